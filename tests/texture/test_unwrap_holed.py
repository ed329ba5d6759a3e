"""Disks with holes kept uncut (texture.flatten.holed_map, the unwrap's ``holed_islands``).

A flat plate with windows is developable as it is: its conformal map is the plate itself,
so it needs no cut from each window to its border. The plate below is 3 x 2 (a grid of
cells of side 0.1) with three square windows, rotated and moved in 3D: genus 0 with four
border loops.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import trimesh
from test_unwrap import FAST, chart_from_function, check_faithful, island_topology

from mnacore.frame import unit_ball_normalization
from mnacore.triangles import signed_areas, triangle_areas
from texture.flatten import boundary_loop_count, euler_characteristic, holed_map
from texture.harness import measure
from texture.unwrap import unwrap_mesh

W, H, CELL = 3.0, 2.0, 0.1
WINDOWS = [(4, 4), (14, 10), (22, 4)]  # lower-left cell of each 4 x 4-cell window
ROT = trimesh.transformations.rotation_matrix(0.7, [1.0, 2.0, 0.5])[:3, :3]
SHIFT = np.array([0.3, -1.2, 2.0])


def window_plate() -> trimesh.Trimesh:
    nx, ny = int(round(W / CELL)), int(round(H / CELL))
    i, j = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), indexing="ij")
    xy = np.c_[i.ravel(), j.ravel()] * CELL
    vid = lambda a, b: a * (ny + 1) + b  # noqa: E731
    faces = []
    for a in range(nx):
        for b in range(ny):
            if any(x <= a < x + 4 and y <= b < y + 4 for x, y in WINDOWS):
                continue
            faces += [[vid(a, b), vid(a + 1, b), vid(a + 1, b + 1)], [vid(a, b), vid(a + 1, b + 1), vid(a, b + 1)]]
    xyz = np.c_[xy, np.zeros(len(xy))] @ ROT.T + SHIFT
    mesh = trimesh.Trimesh(xyz, np.array(faces), process=False)
    mesh.remove_unreferenced_vertices()  # the windows' inner grid points
    return mesh


def plate_chart(mesh):
    norm = unit_ball_normalization(mesh.vertices)
    return chart_from_function(lambda u, v: norm.apply(
        (np.stack([(u + 1) / 2 * W, (v + 1) / 2 * H, 0 * u], -1).reshape(-1, 3)) @ ROT.T + SHIFT).reshape(*u.shape, 3),
        norm)


def test_holed_map_of_a_plate_is_the_plate():
    mesh = window_plate()
    xyz, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    assert boundary_loop_count(f) == 4 and euler_characteristic(f) == -2
    uv = holed_map(xyz, f)
    assert uv is not None
    uv *= np.sqrt(triangle_areas(xyz, f).sum() / signed_areas(uv, f).sum())
    e = np.r_[f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]
    np.testing.assert_allclose(np.linalg.norm(uv[e[:, 0]] - uv[e[:, 1]], axis=1),
                               np.linalg.norm(xyz[e[:, 0]] - xyz[e[:, 1]], axis=1), rtol=1e-6)
    # not a disk with holes: a disk (one loop) and a closed surface are left to the disk cut
    disk = f[(mesh.triangles_center - SHIFT) @ ROT[:, 0] < 0.35]  # the strip left of every window
    assert boundary_loop_count(disk) == 1 and holed_map(xyz, disk) is None
    sphere = trimesh.creation.icosphere(2)
    assert holed_map(np.asarray(sphere.vertices), np.asarray(sphere.faces)) is None


@pytest.mark.parametrize("holed", [True, False])
def test_plate_with_windows_unwraps_uncut(holed):
    mesh = window_plate()
    cfg = replace(FAST, long_max_splits=0, pack_max_cuts=0, holed_islands=holed)
    res = unwrap_mesh(mesh.vertices, mesh.faces, plate_chart(mesh), cfg)
    check_faithful(mesh, res)
    m = measure(res.mesh, reference=mesh).summary
    assert m["flipped_faces"] == 0 and m["uv_overlap_percent"] == 0.0
    if holed:
        # one island, its windows kept as holes: no seam at all, and the plate's own shape
        assert res.stats["islands"] == 1 and island_topology(res) == [(-2, 4)]
        assert m["seam_length"] == 0.0
        assert m["distortion_metric"] < 1e-4
        assert res.stats["flatten"]["holed"] == 1
    else:
        # cut to a disk: a cut runs from every window to the border
        assert all(t == (1, 1) for t in island_topology(res))
        assert m["seam_length"] > 3 * 0.4 / np.sqrt(W * H - 3 * 0.16)
