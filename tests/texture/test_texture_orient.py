"""Reorienting inside-out parts of charts (texture.orient) on flat sheets with closed forms."""
from __future__ import annotations

import numpy as np
import pytest

from mnacore.grid import grid_faces
from texture.islands import uv_islands
from texture.orient import Reference, face_normals, folded_area, orient_pieces, split_orientation
from texture.trim import Piece

G = 41  # grid vertices per side over [-1, 1]^2


def _grid_uv() -> np.ndarray:
    t = np.linspace(-1.0, 1.0, G)
    u, v = np.meshgrid(t, t, indexing="xy")  # u along columns j, v along rows i (grid_faces)
    return np.column_stack([u.ravel(), v.ravel()])


def _piece(xyz_of_uv) -> Piece:
    uv = _grid_uv()
    return Piece(0, xyz_of_uv(uv), uv, grid_faces(G))


def _plane_reference(normal_sign=lambda xy: np.ones(len(xy)), n: int = 81) -> Reference:
    """The plane z = 0 over [-2, 2]^2 with vertex normals sign * +z."""
    t = np.linspace(-2.0, 2.0, n)
    x, y = np.meshgrid(t, t, indexing="ij")
    xy = np.column_stack([x.ravel(), y.ravel()])
    normals = np.zeros((len(xy), 3))
    normals[:, 2] = normal_sign(xy)
    return Reference(np.column_stack([xy, np.zeros(len(xy))]), grid_faces(n), normals)


def _flat(uv):
    return np.column_stack([uv, np.zeros(len(uv))])


def _uv_signs(p: Piece) -> np.ndarray:
    t = p.uv[p.faces]
    return np.sign((t[:, 1, 0] - t[:, 0, 0]) * (t[:, 2, 1] - t[:, 0, 1]) - (t[:, 1, 1] - t[:, 0, 1]) * (t[:, 2, 0] - t[:, 0, 0]))


def _up(p: Piece) -> np.ndarray:
    return np.sign(face_normals(p.xyz, p.faces)[:, 2])


def test_consistent_piece_is_untouched():
    p = _piece(_flat)
    assert (_up(p) > 0).all()  # grid_faces are counter-clockwise in UV: +z on the identity sheet
    ref = _plane_reference()
    out, back, dropped = split_orientation(p, ref, min_area=0.1)
    assert out is p and len(back.faces) == 0 and dropped == 0.0
    assert folded_area(p, ref) == 0.0


def test_whole_inward_piece_is_reversed_and_mirrored():
    p = _piece(_flat)
    ref = _plane_reference(lambda xy: -np.ones(len(xy)))  # the surface faces -z
    assert folded_area(p, ref) == pytest.approx(4.0, rel=1e-12)
    out, back, _ = split_orientation(p, ref, min_area=0.1)
    assert len(out.faces) == 0
    assert (_up(back) < 0).all() and folded_area(back, ref) == 0.0
    # mirrored UVs: one UV orientation for every face, same UV and 3D areas as before
    assert len(np.unique(_uv_signs(back))) == 1
    np.testing.assert_allclose(np.sort(back.area()), np.sort(p.area()), rtol=1e-12)
    np.testing.assert_allclose(back.uv, p.uv * [-1, 1])


def _folded_sheet(uv):
    """The sheet runs along +x up to u = 0.3, then folds back over itself (slightly lower)."""
    u, v = uv[:, 0], uv[:, 1]
    back = u > 0.3
    x = np.where(back, 0.6 - u, u)
    z = np.where(back, -0.004 * (u - 0.3), 0.0)
    return np.column_stack([x, v, z])


def test_fold_is_cut_at_the_crease_and_reoriented():
    p = _piece(_folded_sheet)
    ref = _plane_reference()
    # the part beyond the crease (u in (0.3, 1]) points down: 0.7 x 2 of area
    assert folded_area(p, ref) == pytest.approx(1.4, rel=1e-3)
    out, back, dropped = split_orientation(p, ref, min_area=0.01)
    assert dropped == 0.0
    # the cut follows the crease to within a grid cell (0.05 in u): areas 2 x 1.3 and 2 x 0.7
    cell = 2.0 / (G - 1)
    assert out.area().sum() == pytest.approx(2.6, abs=2 * cell)
    assert back.area().sum() == pytest.approx(1.4, abs=2 * cell)
    # nothing lost or doubled: the halves tile the piece. Exactly (1e-9) before vertices near
    # the cut snapped onto it (texture.clip); a vertex sliding along an edge across the crease
    # bends its other faces, which changes their area at second order (2e-7 here)
    assert out.area().sum() + back.area().sum() == pytest.approx(p.area().sum(), rel=1e-6)
    assert out.uv[:, 0].max() <= 0.3 + cell and back.uv[:, 0].max() <= -0.3 + cell  # mirrored: u -> -u
    # sub-triangles on the cut move to the side their normal agrees with: what is left folded
    # is rounding-size slivers (< 1e-6 of the area), not the half-cell strip along the crease
    assert folded_area(out, ref) < 4e-6 and folded_area(back, ref) < 4e-6
    for part in (out, back):  # each part is one island with one UV orientation
        assert uv_islands(part.faces, part.uv).max() == 0
        assert len(np.unique(_uv_signs(part))) == 1
    pieces, stats = orient_pieces([p], ref, min_area=0.01)
    assert len(pieces) == 2
    assert stats["folded_percent_before_orient"] == pytest.approx(100 * 1.4 / 4.0, rel=1e-3)
    assert stats["folded_percent"] < 1e-4  # percent: the rounding slivers above
    assert stats["reoriented_percent"] == pytest.approx(100 * 1.4 / 4.0, abs=100 * 2 * cell / 4.0)


def _speck_reference(radius: float = 0.25):
    """Plane whose normals point down in a disc around (0.5, 0.5): a small 'fold'.

    The disc is 5 reference cells wide: its rim, where the reference's normals point both
    ways within FOLD_TOL, is undecided, and most of the disc is not.
    """
    return _plane_reference(lambda xy: np.where(np.hypot(xy[:, 0] - 0.5, xy[:, 1] - 0.5) < radius, -1.0, 1.0))


def test_small_fragment_is_dropped_within_budget():
    p = _piece(_flat)
    ref = _speck_reference()
    disc = np.pi * 0.25 ** 2
    assert folded_area(p, ref) == pytest.approx(disc, rel=0.35)
    out, back, dropped = split_orientation(p, ref, min_area=0.25, drop_budget=0.4)
    assert len(back.faces) == 0  # never an island of its own
    assert dropped == pytest.approx(disc, rel=0.35)
    assert out.area().sum() == pytest.approx(4.0 - dropped, rel=1e-9)
    assert folded_area(out, ref) == pytest.approx(0.0, abs=1e-9)
    assert uv_islands(out.faces, out.uv).max() == 0  # a hole, not a new island


def test_small_fragment_over_budget_stays_with_its_island():
    p = _piece(_flat)
    ref = _speck_reference()
    out, back, dropped = split_orientation(p, ref, min_area=0.25, drop_budget=0.0)
    assert dropped == 0.0 and len(back.faces) == 0
    assert out.area().sum() == pytest.approx(4.0, rel=1e-9)
    assert uv_islands(out.faces, out.uv).max() == 0
    assert folded_area(out, ref) == pytest.approx(np.pi * 0.25 ** 2, rel=0.35)  # reported, not hidden


@pytest.mark.parametrize("min_island", [0.1, 0.3])
def test_fragment_over_budget_becomes_its_own_island_if_large_enough(min_island):
    p = _piece(_flat)
    ref = _speck_reference()
    disc = np.pi * 0.25 ** 2  # ~0.196: an island of its own at min_island 0.1, not at 0.3
    out, back, dropped = split_orientation(p, ref, min_area=0.25, drop_budget=0.0, min_island=min_island)
    assert dropped == 0.0
    assert out.area().sum() + back.area().sum() == pytest.approx(4.0, rel=1e-9)  # nothing lost
    if min_island < disc:
        assert back.area().sum() == pytest.approx(disc, rel=0.35)
        assert uv_islands(back.faces, back.uv).max() == 0  # one island, reoriented outward
        assert folded_area(back, ref) + folded_area(out, ref) == pytest.approx(0.0, abs=0.02 * disc)
    else:  # as without the option: kept with its island, and still folded
        assert len(back.faces) == 0 and uv_islands(out.faces, out.uv).max() == 0
        assert folded_area(out, ref) == pytest.approx(disc, rel=0.35)


def test_undecided_fragment_is_kept_not_dropped():
    # the same speck, with a second layer 0.01 below facing up (a touching part): inside the
    # disc the reference faces both ways within FOLD_TOL, so the speck is folded by no
    # measure: it stays with its island and spends none of the drop budget
    top = _speck_reference()
    n = 81
    t = np.linspace(-2.0, 2.0, n)
    x, y = np.meshgrid(t, t, indexing="ij")
    xy = np.column_stack([x.ravel(), y.ravel()])
    V = np.concatenate([top.projector.vertices, np.column_stack([xy, np.full(len(xy), -0.01)])])
    F = np.concatenate([top.projector.faces, grid_faces(n) + len(xy)])
    N = np.concatenate([top.normals, np.tile([0.0, 0.0, 1.0], (len(xy), 1))])
    ref = Reference(V, F, N)
    p = _piece(_flat)
    out, back, dropped = split_orientation(p, ref, min_area=0.25, drop_budget=0.4)
    assert dropped == 0.0 and len(back.faces) == 0
    assert out.area().sum() == pytest.approx(4.0, rel=1e-9)
    assert uv_islands(out.faces, out.uv).max() == 0


def test_off_surface_piece_is_never_cut():
    p = _piece(lambda uv: _folded_sheet(uv) + [0.0, 0.0, 0.5])  # 0.5 above the plane: off the surface
    out, back, dropped = split_orientation(p, _plane_reference(), min_area=0.01)
    assert out is p and len(back.faces) == 0 and dropped == 0.0


@pytest.mark.parametrize("max_islands, islands", [(0, 2), (2, 2), (1, 1)])
def test_fragment_islands_only_within_the_island_budget(max_islands, islands):
    # the speck is a fragment (under min_island_fraction of the area) that the drop budget
    # cannot take and that is large enough to be an island: with it, the atlas has 2 islands.
    # A budget of 1 island takes the plain orientation instead (speck left folded), unless
    # the atlas exceeds the budget without fragment islands too (next test)
    from texture.atlas import AtlasConfig
    from texture.atlas_stages import orient_stage
    from texture.layouts import island_count
    from texture.trim import TrimConfig

    cfg = AtlasConfig(trim=TrimConfig(min_island_fraction=0.25 / 4.0), orient_fragment_island=0.1 / 4.0,
                      max_islands=max_islands)
    oriented = orient_stage([_piece(_flat)], _speck_reference(), cfg)
    out = [pp.source for pp in oriented.layout]
    assert island_count(oriented.layout) == islands
    assert oriented.stats.orient_fragment_islands is (islands == 2)
    disc = np.pi * 0.25 ** 2
    folded = sum(folded_area(p, _speck_reference()) for p in out)
    assert folded == (pytest.approx(0.0, abs=0.02 * disc) if islands == 2 else pytest.approx(disc, rel=0.35))


def test_fragment_islands_kept_when_over_the_budget_anyway():
    from texture.atlas import AtlasConfig
    from texture.atlas_stages import orient_stage
    from texture.layouts import island_count
    from texture.trim import TrimConfig

    far = _piece(lambda uv: _flat(uv) + [10.0, 0.0, 0.0])  # a second part, away from the speck
    cfg = AtlasConfig(trim=TrimConfig(min_island_fraction=0.25 / 8.0), orient_fragment_island=0.1 / 8.0,
                      max_islands=1)
    oriented = orient_stage([_piece(_flat), far], _speck_reference(), cfg)
    assert island_count(oriented.layout) == 3 and oriented.stats.orient_fragment_islands is True


def test_pieces_split_in_processes_match_one_by_one(monkeypatch):
    import texture.orient as O

    pieces = [_piece(_flat), _piece(_folded_sheet), _piece(lambda uv: _flat(uv) + [0.0, 0.0, 0.001])]
    ref = _speck_reference()
    serial = O.orient_pieces(pieces, ref, min_area=0.25, min_fragment_island=0.1)
    import texture.parallel as P

    monkeypatch.setattr(P, "MIN_FACES", 0)
    parallel = O.orient_pieces(pieces, ref, min_area=0.25, min_fragment_island=0.1)
    assert serial[1] == parallel[1] and len(serial[0]) == len(parallel[0]) >= 4
    for a, b in zip(serial[0], parallel[0]):
        np.testing.assert_array_equal(a.uv, b.uv)
        np.testing.assert_array_equal(a.faces, b.faces)
        assert a.chart == b.chart
