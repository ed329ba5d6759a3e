"""Outlines re-triangulated for xatlas's rasteriser: the same region, and inner vertices that
follow their island through every turn, move and mirror."""
from __future__ import annotations

import numpy as np
import pytest
from test_texture_pack import assert_valid_packing

from mnacore.triangles import signed_areas, triangle_areas
from texture.islands import edge_keys, edge_use_counts, half_edges
from texture.islandset import IslandSet
from texture.outlines import SLIVER_BBOX_RATIO, bbox_ratios, island_outlines
from texture.pack import pack_islands

#: the disk's radius and rim vertices: a cap of a finely sectioned cylinder or cone
RADIUS, RIM = 3.0, 1500


def _fan_disk(shift=(0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """A regular ``RIM``-gon of radius ``RADIUS``, fanned from its centre (vertex 0)."""
    t = 2.0 * np.pi * np.arange(RIM) / RIM
    uv = np.vstack([[0.0, 0.0], RADIUS * np.column_stack([np.cos(t), np.sin(t)])]) + shift
    k = np.arange(RIM)
    return uv, np.column_stack([np.zeros(RIM, np.int64), k + 1, (k + 1) % RIM + 1])


def _border(faces: np.ndarray, n: int) -> np.ndarray:
    return half_edges(faces)[edge_use_counts(edge_keys(np.arange(n), faces)) == 1]


def test_a_fanned_round_outline_is_refined_to_the_same_region():
    uv, faces = _fan_disk()
    island = np.zeros(len(faces), np.int64)
    # ear clipping the rim fans slivers across the disk: what the rule is for
    clipped = island_outlines(uv, faces, island)
    assert bbox_ratios(uv, clipped, np.zeros(len(clipped), np.int64)) > SLIVER_BBOX_RATIO
    o = IslandSet.of(uv, faces, island).outline
    assert len(o.uv) > len(o.src) and len(o.frame) == len(o.uv) - len(o.src)
    assert bbox_ratios(o.uv, o.faces, o.island) < 10.0  # fat triangles (angles of 25 degrees or more)
    polygon = 0.5 * RIM * RADIUS**2 * np.sin(2.0 * np.pi / RIM)
    assert triangle_areas(o.uv, o.faces).sum() == pytest.approx(polygon, rel=1e-9)
    assert (signed_areas(o.uv, o.faces) > 0).all()  # wound as the island is
    # the border is the rim's RIM edges, over mesh vertices only (no vertex added on it)
    rim = _border(o.faces, len(o.uv))
    assert len(rim) == RIM and rim.max() < len(o.src)
    assert sorted(o.src[rim[:, 0]].tolist()) == list(range(1, RIM + 1))


@pytest.mark.parametrize("mirror", [False, True])
def test_inner_outline_vertices_follow_their_island(mirror):
    uv, faces = _fan_disk()
    o = IslandSet.of(uv, faces, np.zeros(len(faces), np.int64)).outline
    c, s = np.cos(1.1), np.sin(1.1)
    m = np.array([[c, -s], [s, c]]) @ (np.diag([-1.0, 1.0]) if mirror else np.eye(2))
    moved = 2.5 * uv @ m.T + [40.0, -7.0]  # turned, scaled, moved (and mirrored)
    np.testing.assert_allclose(o.at(moved), 2.5 * o.uv @ m.T + [40.0, -7.0], atol=1e-9)


def test_refined_outlines_pack_validly():
    """Two fanned disks and a square: every island placed rigidly at one scale, no overlap,
    checked on the islands' own faces."""
    a_uv, a_f = _fan_disk()
    b_uv, b_f = _fan_disk(shift=(10.0, 0.0))
    b_uv = 0.5 * b_uv
    sq = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]]) + [0.0, 9.0]
    uv = np.vstack([a_uv, b_uv, sq])
    faces = np.vstack([a_f, b_f + len(a_uv), np.array([[0, 1, 2], [0, 2, 3]]) + len(a_uv) + len(b_uv)])
    island = np.repeat([0, 1, 2], [len(a_f), len(b_f), 2])
    assert len(IslandSet.of(uv, faces, island).outline.frame) > 0
    pk = pack_islands(uv, faces, island, resolution=512, padding=4)
    assert pk.packer == "xatlas"
    assert_valid_packing(pk, uv, faces, island)
