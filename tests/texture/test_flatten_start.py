"""texture.flatten.start_map: the conformal start where it embeds, Tutte where it does not."""
from __future__ import annotations

import numpy as np
import trimesh

from mnacore.triangles import signed_areas, triangle_areas
from texture.flatten import is_disk, lscm, start_map, tutte
from texture.relax import crossing_edges, energy_excess


def _isometric(xyz, uv, faces):
    return uv * np.sqrt(triangle_areas(xyz, faces).sum() / signed_areas(uv, faces).sum())


def cut_cylinder_wall(radius=1.0, height=0.4, around=200, up=10):
    """The side wall of a cylinder cut open along one line: a developable 2 pi r x h strip."""
    t = np.linspace(0.0, 2 * np.pi, around, endpoint=False)
    z = np.linspace(0.0, height, up + 1)
    T, Z = np.meshgrid(np.r_[t, 2 * np.pi], z, indexing="ij")  # the cut: first column repeated
    xyz = np.c_[radius * np.cos(T).ravel(), radius * np.sin(T).ravel(), Z.ravel()]
    idx = np.arange(len(xyz)).reshape(around + 1, up + 1)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    faces = np.r_[np.c_[a.ravel(), b.ravel(), c.ravel()], np.c_[a.ravel(), c.ravel(), d.ravel()]]
    return xyz, faces


def saddle_fan(spokes=10, levels=3):
    """One interior vertex whose faces' angles sum to 3 pi (each apex 54 degrees, unit spokes,
    the rim zigzagging up and down), every face then split in four ``levels`` times (each stays
    flat): a cone of 3 pi, which laid flat with its angles winds 1.5 times around its apex."""
    apex = 3 * np.pi / spokes
    step = 2 * np.pi / spokes
    # |p_i - p_i+1| = 2 sin(apex / 2) with |p_i| = 1 and z = +-h alternating
    chord2 = (2 * np.sin(apex / 2)) ** 2
    s2 = (2 * np.sin(step / 2)) ** 2
    h = np.sqrt((chord2 - s2) / (4 - s2))
    r = np.sqrt(1 - h * h)
    ang = step * np.arange(spokes)
    rim = np.c_[r * np.cos(ang), r * np.sin(ang), h * (-1.0) ** np.arange(spokes)]
    xyz = np.r_[np.zeros((1, 3)), rim]
    faces = np.c_[np.zeros(spokes, int), 1 + np.arange(spokes), 1 + (np.arange(spokes) + 1) % spokes]
    for _ in range(levels):
        xyz, faces = trimesh.remesh.subdivide(xyz, faces)
    return xyz, faces


def test_a_developable_strip_starts_at_its_isometry_not_at_tuttes_squeezed_circle():
    xyz, faces = cut_cylinder_wall()
    assert is_disk(faces)
    start = start_map(xyz, faces)
    assert (signed_areas(start, faces) > 0).all() and len(crossing_edges(faces, start)) == 0
    assert energy_excess(xyz, _isometric(xyz, start, faces), faces) < 1e-6
    # an isometry up to one scale: every edge keeps its 3D length (the chords are 0.0314 and 0.04)
    uv = _isometric(xyz, start, faces)
    e = np.r_[faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]
    ratio = np.linalg.norm(uv[e[:, 0]] - uv[e[:, 1]], axis=1) / np.linalg.norm(xyz[e[:, 0]] - xyz[e[:, 1]], axis=1)
    assert np.abs(ratio - 1).max() < 1e-3
    assert energy_excess(xyz, _isometric(xyz, tutte(xyz, faces), faces), faces) > 10


def test_a_fan_whose_angles_sum_to_three_pi_falls_back_to_tutte():
    xyz, faces = saddle_fan()
    at_apex = [f for f in faces if 0 in f]
    angles = []
    for f in at_apex:
        i = list(f).index(0)
        u, v = xyz[f[(i + 1) % 3]] - xyz[0], xyz[f[(i + 2) % 3]] - xyz[0]
        angles.append(np.arccos(u @ v / np.linalg.norm(u) / np.linalg.norm(v)))
    assert abs(sum(angles) - 3 * np.pi) < 1e-9
    assert lscm(xyz, faces) is None  # its conformal map overlaps itself
    start = start_map(xyz, faces)
    np.testing.assert_allclose(start, tutte(xyz, faces))
    assert (signed_areas(start, faces) > 0).all()
