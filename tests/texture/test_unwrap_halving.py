"""Halving an island: the cut is the shortest anywhere between the positions tried."""
from __future__ import annotations

import numpy as np
import pytest

from mnacore.triangles import signed_areas, triangle_areas
from texture.halving import LONG_CUTS, halve_across
from texture.unwrap_islands import Island

#: grid step of the planar strip below, and its neck: columns [NECK_X0, NECK_X1), rows [NECK_Y0, NECK_Y1)
H = 0.05
NECK_X0, NECK_X1, NECK_Y0, NECK_Y1 = 1.70, 1.85, 0.40, 0.65
#: the strip's 3D coordinates and UVs are its plane's times this (an unwrap's islands are at
#: the 3D scale: ``ZIGZAG`` compares a cut's 3D length with the island's UV width)
XYZ_SCALE = 3.0


def _cells(width: float, height: float, keep) -> Island:
    """A planar island of the grid cells (two triangles each, step ``H``) of a ``width`` x
    ``height`` rectangle whose lower-left corners (x, y) pass ``keep(x, y)``, at ``XYZ_SCALE``."""
    nx, ny = round(width / H), round(height / H)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    v = (i.ravel() * (ny + 1) + j.ravel())[keep(i.ravel() * H, j.ravel() * H)]
    faces = np.concatenate([np.column_stack([v, v + ny + 1, v + ny + 2]),
                            np.column_stack([v, v + ny + 2, v + 1])])
    gi, gj = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), indexing="ij")
    plane = np.column_stack([gi.ravel() * H, gj.ravel() * H])
    used, inv = np.unique(faces, return_inverse=True)
    plane = plane[used]
    xyz = np.column_stack([plane * XYZ_SCALE, np.zeros(len(plane))])
    faces = inv.reshape(-1, 3)
    return Island(faces, plane * XYZ_SCALE, xyz, np.arange(len(faces)), np.arange(len(plane)), 0)


def _necked_strip() -> Island:
    """A 4 x 1 planar strip of grid cells whose cells over ``[NECK_X0, NECK_X1)`` are kept
    only between ``NECK_Y0`` and ``NECK_Y1``: a neck 0.25 wide. Its area before the neck is
    1.70 of 3.8875 (0.437), after it 2.15: between the straight cuts at 0.40 and 0.45 of the
    area."""
    def keep(x0, y0):
        in_neck_cols = (x0 >= NECK_X0 - 1e-9) & (x0 < NECK_X1 - 1e-9)
        return ~in_neck_cols | ((y0 >= NECK_Y0 - 1e-9) & (y0 < NECK_Y1 - 1e-9))
    return _cells(4.0, 1.0, keep)


def test_a_halving_cuts_through_a_neck_that_no_straight_cut_meets():
    """The cut positions tried (0.30-0.70 of the area) step over the neck (0.437-0.447 of the
    area): every straight cut crosses the strip's full width, 3.0 in 3D. The shortest cut between
    the first and last position is across the neck: 0.25 x 3 = 0.75, with the neck's area on
    either side of it, and the halves keep their UVs."""
    strip = _necked_strip()
    total = triangle_areas(strip.xyz, strip.faces).sum()
    assert total == pytest.approx((4 - (NECK_X1 - NECK_X0) * (1 - (NECK_Y1 - NECK_Y0))) * XYZ_SCALE**2)
    straight = [halve_across(strip, cuts=[q]) for q in LONG_CUTS]  # one position: a straight cut
    straight = [got[1] for got in straight if got is not None]
    assert straight and min(straight) >= XYZ_SCALE * (1 - 1e-9)  # the full width, or a staircase
    halves, cut = halve_across(strip)
    assert cut == pytest.approx((NECK_Y1 - NECK_Y0) * XYZ_SCALE, rel=1e-9)
    smaller = min(triangle_areas(h.xyz, h.faces).sum() for h in halves) / XYZ_SCALE**2  # either end first
    assert NECK_X0 - 1e-9 <= smaller <= NECK_X0 + (NECK_X1 - NECK_X0) * (NECK_Y1 - NECK_Y0) + 1e-9
    assert sum(len(h.faces) for h in halves) == len(strip.faces)
    for h in halves:  # each half's corners keep the island's UVs
        assert np.allclose(h.uv, strip.uv[h.work_vertex])


def test_the_shortest_cut_is_no_longer_than_any_straight_one_on_a_curved_island():
    """On a curved island (a quarter of a sphere's surface, 3D lengths on radius 2.5) the
    cut between the positions is at most the shortest straight cut among them, and both
    halves are one piece that together hold every face."""
    import trimesh

    from texture.flatten import start_map

    sphere = trimesh.creation.icosphere(subdivisions=4, radius=2.5)
    c = sphere.triangles_center
    sel = np.flatnonzero((c[:, 0] > 0) & (c[:, 1] > 0))
    used, inv = np.unique(sphere.faces[sel], return_inverse=True)
    faces, xyz = inv.reshape(-1, 3), sphere.vertices[used]
    uv = start_map(xyz, faces)
    uv *= np.sqrt(triangle_areas(xyz, faces).sum() / np.abs(signed_areas(uv, faces)).sum())  # the 3D scale
    isl = Island(faces, uv, xyz, np.arange(len(faces)), np.arange(len(xyz)), 0)
    straight = [halve_across(isl, cuts=[q]) for q in LONG_CUTS]
    straight = min(got[1] for got in straight if got is not None)
    halves, cut = halve_across(isl)
    assert cut <= straight * (1 + 1e-9)
    assert sorted(np.concatenate([h.work_faces for h in halves]).tolist()) == list(range(len(faces)))


def test_a_halving_of_a_fork_cuts_one_prong_where_its_end_is_two_lobes():
    """A fork (3 x 6: a base 1.5 high, two prongs 1 wide and 4.5 long) has its principal axis
    along the prongs, and past the cut positions (0.30-0.70 of its area, the base holding
    0.33) lie the two prongs' ends: two lobes. Holding both to one half leaves the shortest cut
    between them (across both prongs, 2.0) with that half in two pieces, and of the straight
    cuts only the one across the base (3.0) keeps both halves whole. Only the larger lobe
    held, the cut runs across one prong: 1.0 x 3, one prong's part cut off, the rest whole."""
    from texture.halving import _one_piece
    from texture.regions import face_adjacency

    fork = _cells(3.0, 6.0, lambda x0, y0: (y0 < 1.5 - 1e-9) | (x0 < 1.0 - 1e-9) | (x0 >= 2.0 - 1e-9))
    straight = [halve_across(fork, cuts=[q]) for q in LONG_CUTS]
    straight = [got[1] for got in straight if got is not None]
    assert straight and min(straight) >= 3.0 * XYZ_SCALE * (1 - 1e-9)
    halves, cut = halve_across(fork)
    assert cut == pytest.approx(1.0 * XYZ_SCALE, rel=1e-9)
    x = [h.uv[h.faces].mean(1)[:, 0] / XYZ_SCALE for h in halves]
    prong = min(range(2), key=lambda k: len(halves[k].faces))
    assert (x[prong] < 1.0).all() or (x[prong] > 2.0).all()  # within one prong
    for h in halves:
        assert _one_piece(face_adjacency(h.xyz, h.faces), np.ones(len(h.faces), bool))
        assert np.allclose(h.uv, fork.uv[h.work_vertex])
    assert sorted(np.concatenate([h.work_faces for h in halves]).tolist()) == list(range(len(fork.faces)))


def test_a_rounds_halvings_in_the_pool_are_the_serial_ones(monkeypatch):
    """The packing round's halvings (:func:`texture.unwrap_layout._halvings`) run in the process
    pool where the islands are large: the same halvings, cut lengths and halves (UVs, faces) as
    one after the other here. The strip and a plain rectangle, each halved across and along at
    the three positions: 12 halvings."""
    from texture import parallel, unwrap_layout
    from texture.unwrap import UnwrapConfig

    islands = [_necked_strip(), _cells(2.0, 1.5, lambda x, y: np.ones(len(x), bool))]
    comp = np.zeros(max(int(i.work_faces.max()) for i in islands) + 1, np.int64)
    cfg = UnwrapConfig()
    runs = []
    for min_faces in (10**9, 0):  # never the pool, always the pool
        monkeypatch.setattr(unwrap_layout, "MIN_FACES", min_faces)
        runs.append(unwrap_layout._halvings(islands, comp, cfg, first_seam=False, cache={}))  # cut anew in each
    serial, pooled = runs
    assert parallel.peak_worker_rss_mb() > 0  # a worker ran them
    assert len(serial) == len(pooled) >= 6
    for (a, da), (b, db) in zip(serial, pooled):
        assert da == db
        for x, y in zip(a, b):
            np.testing.assert_array_equal(x.faces, y.faces)
            np.testing.assert_array_equal(x.uv, y.uv)
            np.testing.assert_array_equal(x.work_faces, y.work_faces)
