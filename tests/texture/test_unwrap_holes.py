"""Small holes kept as holes (texture.holes): the fill, the flattening, the seam it saves."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

from mna import shapes
from mnacore.triangles import signed_areas, triangle_areas


def _grid_with_holes(n: int = 20, holes=((5, 5), (12, 7), (15, 15)), big: tuple | None = None):
    """A flat n x n grid of unit squares (2 faces each) with the faces of some cells removed:
    one-cell holes, and optionally a big square hole (x0, y0, size)."""
    sheet = shapes.sheet(size=float(n), resolution=n + 1)
    xyz, faces = np.asarray(sheet.vertices, float), np.asarray(sheet.faces)
    c = xyz[faces].mean(1)[:, :2] + n / 2.0  # cell coordinates in [0, n)
    cell = np.floor(c).astype(int)
    drop = np.zeros(len(faces), bool)
    for i, j in holes:
        drop |= (cell[:, 0] == i) & (cell[:, 1] == j)
    if big is not None:
        x0, y0, s = big
        drop |= (cell[:, 0] >= x0) & (cell[:, 0] < x0 + s) & (cell[:, 1] >= y0) & (cell[:, 1] < y0 + s)
    return xyz, faces[~drop]


def _holed_cap():
    """A sphere cap (z > -0.2) with six one-face holes near its top (curved: it needs slits)."""
    s = trimesh.creation.icosphere(subdivisions=4)
    c = s.vertices[s.faces].mean(1)
    keep = c[:, 2] > -0.2
    rng = np.random.default_rng(3)
    inner = np.flatnonzero(keep & (c[:, 2] > 0.2))
    keep[rng.choice(inner, 6, replace=False)] = False
    vid, inv = np.unique(s.faces[keep], return_inverse=True)
    return np.asarray(s.vertices)[vid], inv.reshape(-1, 3)


def _edge_uses(faces):
    he = np.stack([faces, np.roll(faces, -1, axis=1)], -1).reshape(-1, 2)
    return he


def test_small_holes_get_fans_that_close_them_with_a_consistent_orientation():
    """Three one-cell holes in a 20 x 20 grid (each 0.25 % of the area) are filled, a 6 x 6
    hole (9 %) is not: the filled grid has one border loop fewer per filled hole, every
    interior edge is used once each way, and the fans cover exactly the cells removed."""
    from texture.flatten import boundary_loop_count
    from texture.holes import FILL_AREA, hole_fans

    xyz, faces = _grid_with_holes(big=(2, 12, 6))
    assert 36 / 400 > FILL_AREA > 1 / 400
    p, f = hole_fans(xyz, faces)
    assert len(p) == len(xyz) + 3 and (f[:len(faces)] == faces).all()
    assert boundary_loop_count(f) == boundary_loop_count(faces) - 3 == 2  # outer border and the big hole
    fan_area = triangle_areas(p, f[len(faces):]).sum()
    assert fan_area == pytest.approx(3.0)
    he = _edge_uses(f)
    directed = set(map(tuple, he.tolist()))
    assert len(directed) == len(he)  # no edge twice the same way: orientation consistent
    assert hole_fans(*_grid_with_holes(holes=())) is None  # nothing to fill


def test_a_flat_region_with_small_holes_flattens_isometrically_without_cuts():
    """A flat grid with one-cell holes is already a plane: flattened with its holes filled, it
    keeps every face in order, adds no seam, maps isometrically (energy excess ~0), and each
    hole is still a unit square inside the island (its 4 border edges of length 1)."""
    from texture.holes import flatten_filled
    from texture.relax import RelaxConfig, crossing_edges, energy_excess

    xyz, faces = _grid_with_holes()
    got = flatten_filled(xyz, faces, RelaxConfig(iterations=50, min_gain=1e-4), 0.1, 8)
    assert got is not None and got.added == pytest.approx(0.0, abs=1e-9) and got.cut_edges == 0
    np.testing.assert_array_equal(got.source[got.faces], faces)  # same faces, same order, same corners
    assert (signed_areas(got.uv, got.faces) > 0).all() and not len(crossing_edges(got.faces, got.uv))
    assert energy_excess(xyz[got.source], got.uv, got.faces) < 1e-6
    # pairwise distances in UV equal those in 3D (an isometry of a flat, connected grid)
    i, j = np.random.default_rng(0).integers(0, len(got.uv), (2, 200))
    d3 = np.linalg.norm(xyz[got.source[i]] - xyz[got.source[j]], axis=1)
    np.testing.assert_allclose(np.linalg.norm(got.uv[i] - got.uv[j], axis=1), d3, atol=1e-6)


def test_a_curved_region_with_small_holes_takes_less_seam_filled_than_cut_to_a_disk():
    """A sphere cap (z > -0.2) with six one-face holes: cut to a disk, every hole is joined to
    the border by a cut; filled, the island keeps its holes, is injective and its slits add
    less seam than those cuts. ``flatten_region`` then keeps the filled island (``holed``)."""
    from texture.flatten import cut_to_disk
    from texture.holes import cut_seam, flatten_filled
    from texture.relax import RelaxConfig, crossing_edges, energy_excess
    from texture.unwrap import UnwrapConfig
    from texture.unwrap_islands import flatten_region, holed_rule

    xyz, faces = _holed_cap()
    cfg = UnwrapConfig()
    got = flatten_filled(xyz, faces, RelaxConfig(iterations=200, min_gain=1e-4), cfg.slit_target, cfg.max_slits)
    assert got is not None
    np.testing.assert_array_equal(got.source[got.faces], faces)
    assert (signed_areas(got.uv, got.faces) > 0).all() and not len(crossing_edges(got.faces, got.uv))
    assert energy_excess(xyz[got.source], got.uv, got.faces) <= cfg.slit_target
    cut = cut_seam(xyz, faces, cut_to_disk(xyz, faces))
    assert 0 <= got.added < cut
    stats = {"region_splits": 0, "cut_edges": 0}
    out = flatten_region(xyz, faces, np.arange(len(faces)), 0, 0, stats, holed_rule(cfg))
    assert len(out) == 1 and out[0].holed and stats["filled"] == 1 and len(out[0].faces) == len(faces)


def test_a_filled_flattening_stops_where_its_seam_would_pass_what_it_may_add():
    """``max_added`` (the seam a caller can use the filled flattening under: the cuts to a disk
    it saves, or what a merge trial's union saves): the sphere cap above needs slits; allowed
    at least the seam they take, the flattening is the unbounded one, array for array; allowed
    less, no slit is relaxed past that and it is dropped (None), and ``flatten_region`` cuts
    the region to a disk instead of keeping a filled island with more seam than that."""
    import texture.slits as slits_module
    from texture.holes import flatten_filled
    from texture.relax import RelaxConfig
    from texture.unwrap import UnwrapConfig
    from texture.unwrap_islands import flatten_region, holed_rule

    xyz, faces = _holed_cap()
    cfg, relax = UnwrapConfig(), RelaxConfig(iterations=200, min_gain=1e-4)
    free = flatten_filled(xyz, faces, relax, cfg.slit_target, cfg.max_slits)
    assert free is not None and free.added > 0.1  # slits were cut (no handles: all of it is slits)
    same = flatten_filled(xyz, faces, relax, cfg.slit_target, cfg.max_slits, free.added * (1 + 1e-9))
    np.testing.assert_array_equal(same.uv, free.uv)
    np.testing.assert_array_equal(same.faces, free.faces)

    relaxed = []
    original = slits_module._relaxed_cut

    def counted(*a, **k):
        relaxed.append(1)
        return original(*a, **k)

    slits_module._relaxed_cut = counted
    try:
        assert flatten_filled(xyz, faces, relax, cfg.slit_target, cfg.max_slits, 0.999 * free.added) is None
        short = len(relaxed)
        relaxed.clear()
        flatten_filled(xyz, faces, relax, cfg.slit_target, cfg.max_slits)
        assert short < len(relaxed)  # the last slit (at least) was never relaxed
    finally:
        slits_module._relaxed_cut = original
    stats = {"region_splits": 0, "cut_edges": 0}
    out = flatten_region(xyz, faces, np.arange(len(faces)), 0, 0, stats, holed_rule(cfg), 0.999 * free.added)
    assert "filled" not in stats and not any(i.holed for i in out)
    assert sum(len(i.faces) for i in out) == len(faces)


def test_a_unions_border_seam_is_half_its_border_inside_the_mesh():
    """``merge._border_seam`` (the seam a union has before any cut, as ``island_seam`` counts
    it: half of each border edge that is a seam, the mesh's own border none): a 4 x 3 block of
    a 10 x 10 grid of 0.5-unit cells, inside it (perimeter 14 cells) and at its corner (two
    sides on the mesh's border)."""
    from texture.merge import _border_seam, interior_edges

    sheet = shapes.sheet(size=5.0, resolution=11)  # 10 x 10 cells of 0.5
    xyz, faces = np.asarray(sheet.vertices, float), np.asarray(sheet.faces)
    cell = np.floor((xyz[faces].mean(1)[:, :2] + 2.5) / 0.5).astype(int)
    interior = interior_edges(faces)

    def block(x0, y0):
        sel = (cell[:, 0] >= x0) & (cell[:, 0] < x0 + 4) & (cell[:, 1] >= y0) & (cell[:, 1] < y0 + 3)
        return faces[sel]

    assert _border_seam(block(3, 3), xyz, interior) == pytest.approx(0.5 * 14 * 0.5)
    assert _border_seam(block(0, 0), xyz, interior) == pytest.approx(0.5 * 7 * 0.5)  # two sides are the mesh's border


def test_a_filled_flattening_that_stays_above_the_bound_is_refused():
    """The sphere cap above is curved: without slits its filled map cannot reach
    ``slit_target`` (its excess stays above it), and the flattening is refused (None), so
    ``flatten_region`` cuts the region to a disk (an island the later stages relax and slit
    to the bound) instead of keeping a filled island above the bound, which no later stage
    touches; with slits allowed it reaches the bound and is kept."""
    from texture.holes import flatten_filled
    from texture.relax import RelaxConfig, energy_excess
    from texture.unwrap import UnwrapConfig
    from texture.unwrap_islands import HoledRule, flatten_region

    xyz, faces = _holed_cap()
    cfg, relax = UnwrapConfig(), RelaxConfig(iterations=200, min_gain=1e-4)
    assert flatten_filled(xyz, faces, relax, cfg.slit_target, 0) is None
    slit = flatten_filled(xyz, faces, relax, cfg.slit_target, cfg.max_slits)
    assert slit is not None and energy_excess(xyz[slit.source], slit.uv, slit.faces) <= cfg.slit_target
    stats = {"region_splits": 0, "cut_edges": 0}
    out = flatten_region(xyz, faces, np.arange(len(faces)), 0, 0, stats,
                         HoledRule(cfg.slit_target, relax, cfg.slim_max_faces, 0))
    assert "filled" not in stats and out and not any(i.holed for i in out)
    assert sum(len(i.faces) for i in out) == len(faces)
