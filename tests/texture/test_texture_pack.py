"""Packing at one texel density whatever xatlas does: rotations, mirrors, oversized,
folded, flipped and degenerate islands, and the shelf fallback (regressions of
``packed island N is not a rigid copy of its input``)."""
from __future__ import annotations

import json

import numpy as np
import pytest
from texture_helpers import CENTER, SCALE

import texture.pack as pack
from mna.cli import main
from mnacore.charts import load_charts, save_charts
from mnacore.frame import Normalization
from mnacore.grid import grid_faces
from mnacore.triangles import signed_areas, triangle_areas
from texture.atlas import AtlasConfig, build_atlas
from texture.export import read_back
from texture.islands import uv_islands
from texture.islandset import IslandSet
from texture.layouts import merge_pieces
from texture.mirrors import mirrored_islands
from texture.outlines import island_outlines
from texture.pack import pack_islands
from texture.policy import DEFAULT_POLICY, SearchPolicy
from texture.raster import coverage_count
from texture.relax import RelaxConfig
from texture.scale_search import plan_layouts, search
from texture.similarity import similarity_fit
from texture.trim import trim_charts
from texture.verify import verify_packing


def _rot(a):
    return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])


def _signed_area(uv, faces):
    t = uv[faces]
    return 0.5 * ((t[:, 1, 0] - t[:, 0, 0]) * (t[:, 2, 1] - t[:, 0, 1]) - (t[:, 1, 1] - t[:, 0, 1]) * (t[:, 2, 0] - t[:, 0, 0]))


def assert_valid_packing(pk, uv_in, faces, island):
    """No overlap (each island rasterised alone), inside [0,1]^2, one scale, rigid copies."""
    res = pk.resolution
    assert pk.uv[np.unique(faces)].min() >= 0 and pk.uv[np.unique(faces)].max() <= 1
    covered = np.stack([coverage_count(pk.uv[faces[island == i]], res, res) > 0 for i in np.unique(island)])
    assert covered.sum(0).max() == 1
    assert verify_packing(pk.uv, faces, island, res)[0] == 0 and pk.overlap_texels == 0
    # every edge keeps its length times the one shared scale, every face its signed area up to
    # one sign per island (xatlas's 90-degree "rotation" is a transpose, i.e. a mirror)
    e_in = np.linalg.norm(uv_in[faces[:, 1]] - uv_in[faces[:, 0]], axis=1)
    e_out = np.linalg.norm(pk.uv[faces[:, 1]] - pk.uv[faces[:, 0]], axis=1)
    np.testing.assert_allclose(e_out, pk.scale * e_in, rtol=1e-6, atol=1e-12)
    a_in, a_out = _signed_area(uv_in, faces), _signed_area(pk.uv, faces)
    for i in np.unique(island):
        f = island == i
        sign = np.sign(a_out[f] @ a_in[f]) or 1.0
        np.testing.assert_allclose(a_out[f], sign * pk.scale**2 * a_in[f], rtol=1e-6, atol=1e-15)


@pytest.mark.parametrize("angle", [0.0, 0.3, np.pi / 2, 2.5, -1.2])
@pytest.mark.parametrize("mirror", [False, True])
def test_similarity_fit_recovers_known_transform(angle, mirror):
    rng = np.random.default_rng(0)
    src = rng.standard_normal((40, 2))
    M = _rot(angle) @ (np.diag([1.0, -1.0]) if mirror else np.eye(2))
    dst = 3.5 * src @ M.T + np.array([2.0, -5.0])
    fit = similarity_fit(src, dst, rng.uniform(0.5, 2.0, 40))
    assert fit.scale == pytest.approx(3.5, rel=1e-12)
    np.testing.assert_allclose(fit.rotation, M, atol=1e-12)
    np.testing.assert_allclose(fit.translation, [2.0, -5.0], atol=1e-12)


def test_similarity_fit_prefers_rotation_unless_clearly_mirrored():
    # a symmetric target (a segment) is fitted as well by a rotation as by a mirror: rotation
    src = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    assert np.linalg.det(similarity_fit(src, src[::-1] * 2).rotation) == pytest.approx(1.0)
    # zero spread or zero weight: identity, centroid to centroid
    fit = similarity_fit(np.ones((3, 2)), np.full((3, 2), 4.0))
    np.testing.assert_array_equal(fit.rotation, np.eye(2))
    np.testing.assert_allclose(fit.translation, [3.0, 3.0])


def _centred_grid(G, half, offset=(0.0, 0.0)):
    """A G x G vertex grid over [-half, half]^2 (+ offset)."""
    lin = np.linspace(-half, half, G)
    u, v = np.meshgrid(lin, lin, indexing="xy")
    return np.column_stack([u.ravel(), v.ravel()]) + offset, grid_faces(G)


def _awkward_islands():
    """A dominant island with a UV fold (flipped triangles), a rotated one, a degenerate
    (collinear) one and small ones, all over the same chart-local UV range."""
    parts = []
    uv, f = _centred_grid(12, 1.0)
    fold = uv[:, 0] > 0.6  # fold the right strip back over itself: flipped triangles
    uv[fold, 0] = 1.2 - uv[fold, 0]
    parts.append((uv, f))
    uv, f = _centred_grid(6, 0.4)
    parts.append((uv @ _rot(0.7).T, f))
    parts.append((np.array([[0.0, 0.0], [0.5, 0.5], [1.0, 1.0]]), np.array([[0, 1, 2]])))  # zero area
    for s in (0.15, 0.1):
        parts.append(_centred_grid(4, s))
    uvs, faces, island, off = [], [], [], 0
    for i, (u, f) in enumerate(parts):
        uvs.append(u)
        faces.append(f + off)
        island.append(np.full(len(f), i))
        off += len(u)
    return np.concatenate(uvs), np.concatenate(faces), np.concatenate(island)


def test_pack_folded_dominant_and_degenerate_islands():
    uv, faces, island = _awkward_islands()
    assert (_signed_area(uv, faces) < 0).any() and (_signed_area(uv, faces)[island == 2] == 0).all()
    pk = pack_islands(uv, faces, island, resolution=128, padding=2)
    assert pk.packer == "xatlas"
    assert_valid_packing(pk, uv, faces, island)
    assert pk.utilization > 0.3


@pytest.mark.parametrize("resolution, padding", [(2048, 8), (1024, 4)])
def test_pack_grows_a_square_island_to_the_atlas_side(resolution, padding):
    """One 3 x 3 square island (a UV scale that is not 1): the largest placement fills the
    atlas, side ``resolution`` texels at most. The packing reaches it within the finest grow
    step (a 1 % search bracket alone left it 0.5 % short: 2037 of 2048 texels)."""
    uv = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 3.0], [0.0, 3.0]])
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    pk = pack_islands(uv, faces, np.zeros(2, int), resolution=resolution, padding=padding)
    side = 3.0 * pk.texels_per_unit
    assert resolution / min(pack.GROW_STEPS) - 1.0 <= side <= resolution
    # texel centres covered by a square of that side: at least (side - 2)^2 wherever it lies
    assert (side - 2.0) ** 2 <= pk.utilization * resolution**2 <= side**2
    assert_valid_packing(pk, uv, faces, np.zeros(2, int))


def test_pack_falls_back_to_shelf_when_xatlas_never_fits():
    uv, faces, island = _awkward_islands()
    # a policy with no xatlas option set to try stands for an input xatlas never packs validly
    # (e.g. an island it always splits)
    pk = pack_islands(uv, faces, island, resolution=128, padding=2, policy=SearchPolicy(pack_candidates=()))
    assert pk.packer == "shelf" and pk.attempts == 0
    assert_valid_packing(pk, uv, faces, island)
    assert mirrored_islands(IslandSet.of(uv, faces, island), pk.uv) == []
    assert pk.utilization > 0.1


#: policies that search less (or differently) than the default: the packing's guarantees
#: must not depend on the policy, only its utilisation may
POLICIES = {
    "default": SearchPolicy(),
    "no_turns": SearchPolicy(pack_candidates=({"rotate_charts": False},)),
    "turns_only": SearchPolicy(pack_candidates=({},)),
    "hasty": SearchPolicy(max_attempts=3, mirror_tries=1, unmirror_steps=0),
    "shelf": SearchPolicy(pack_candidates=()),
}


def _long_thin_islands(n=14, seed=0):
    rng = np.random.default_rng(seed)
    uvs, faces, island, off = [], [], [], 0
    for k in range(n):
        u, f = _centred_grid(5, 1.0)
        u = u * [rng.uniform(1.5, 3.0), rng.uniform(0.3, 0.6)]  # long and thin: turning helps packing
        uvs.append(u @ _rot(rng.uniform(0, np.pi)).T)
        faces.append(f + off)
        island.append(np.full(len(f), k))
        off += len(u)
    return np.concatenate(uvs), np.concatenate(faces), np.concatenate(island)


@pytest.mark.parametrize("name", sorted(POLICIES))
@pytest.mark.parametrize("islands", ["awkward", "long_thin"])
def test_any_policy_packs_validly_and_deterministically(name, islands):
    """Every policy's packing: no texel covered twice, no island mirrored, every island inside
    the unit square as a rigid copy at one scale, utilisation above a bound (0.3 for xatlas,
    0.1 for the shelf), and the same bytes when packed again."""
    uv, faces, island = _awkward_islands() if islands == "awkward" else _long_thin_islands()
    policy = POLICIES[name]
    pk = pack_islands(uv, faces, island, resolution=128, padding=2, policy=policy)
    assert_valid_packing(pk, uv, faces, island)
    assert mirrored_islands(IslandSet.of(uv, faces, island), pk.uv) == []
    assert pk.packer == ("shelf" if not policy.pack_candidates else "xatlas")
    assert pk.utilization > (0.1 if pk.packer == "shelf" else 0.3)
    again = pack_islands(uv, faces, island, resolution=128, padding=2, policy=policy)
    assert again.uv.tobytes() == pk.uv.tobytes() and again.utilization == pk.utilization


@pytest.mark.parametrize("field, value", [("mirror_tries", 0), ("max_attempts", 0), ("unmirror_steps", -1),
                                          ("mirror_tries", True)])
def test_policy_refuses_settings_that_would_void_the_guarantees(field, value):
    with pytest.raises(ValueError, match=f"SearchPolicy.{field}"):
        SearchPolicy(**{field: value})


def test_default_policy_packs_at_least_as_tight_as_the_shelf():
    uv, faces, island = _long_thin_islands()
    best = pack_islands(uv, faces, island, resolution=128, padding=2)
    shelf = pack_islands(uv, faces, island, resolution=128, padding=2, policy=POLICIES["shelf"])
    assert best.utilization >= shelf.utilization


def _write_folded_run(run):
    """One chart whose domain fills the whole UV square and whose surface folds over twice
    (a Z in 3D): the single island is larger than the atlas at xatlas's first guesses."""
    G = 48
    lin = np.linspace(-1.0, 1.0, G)
    u, v = np.meshgrid(lin, lin, indexing="xy")
    x = np.where(u < -0.3, u, np.where(u < 0.3, -0.6 - u, u - 1.2))  # goes right, back, right again
    z = 0.05 * np.clip(u + 0.3, 0, 0.6) + 0.05 * np.clip(u - 0.3, 0, None)
    xyz = np.stack([x, v, z], -1)[None] * 0.5 * SCALE + CENTER
    occ = (1.49 - 0.4 * np.maximum(np.abs(u), np.abs(v)) ** 8)[None]  # in domain everywhere
    save_charts(run / "charts.npz", np.stack([u, v], -1)[None], xyz, occ, 0.5, Normalization(CENTER, SCALE))
    return run


def test_folded_single_chart_atlas_keeps_invariants(tmp_path):
    run = _write_folded_run(tmp_path)
    charts = load_charts(run / "charts.npz")
    # the packer's invariants hold against the UVs it was given: the charts' own (no relaxation)
    atlas = build_atlas(charts, AtlasConfig(resolution=256, padding=2, relax=RelaxConfig(iterations=0)))
    uv_local, faces, island = merge_pieces(trim_charts(charts, AtlasConfig().trim).pieces).islands
    np.testing.assert_array_equal(atlas.mesh.faces, faces)
    assert_valid_packing(atlas.packing, uv_local, faces, island)
    assert atlas.stats["utilization"] > 0.5


def test_export_folded_single_chart_run(tmp_path, capsys):
    run = _write_folded_run(tmp_path)
    assert main(["export", str(run), "--size", "256", "--padding", "8"]) == 0
    info = json.loads((run / "atlas.json").read_text())
    assert info["uv_metrics"]["uv_overlap_percent"] == 0.0 and info["uv_metrics"]["uv_inside_unit_square"]
    back = read_back(run / "mesh.obj")
    assert back.uv.min() >= 0 and back.uv.max() <= 1
    isl = uv_islands(back.faces, back.uv)
    assert verify_packing(back.uv, back.faces, isl, 256)[0] == 0


def _grid_island(n=12, hole=False, shift=(0.0, 0.0)):
    """An n x n grid of unit-spaced squares (two triangles each), optionally without its
    central 2 x 2 squares: a rectangle (4 corners) or a rectangle with a square hole."""
    faces = grid_faces(n + 1)
    if hole:
        c = np.arange(n * n * 2) // 2
        i, j = c // n, c % n
        mid = n // 2
        faces = faces[~((abs(i - mid + 0.5) < 1.1) & (abs(j - mid + 0.5) < 1.1))]
    t = np.arange(n + 1, dtype=float)
    u, v = np.meshgrid(t, t, indexing="xy")
    return np.column_stack([u.ravel(), v.ravel()]) + shift, faces


@pytest.mark.parametrize("hole", [False, True])
def test_island_outline_is_the_border_ear_clipped(hole):
    uv, faces = _grid_island(hole=hole)
    island = np.zeros(len(faces), np.int64)
    out = island_outlines(uv, faces, island)
    # straight runs along the grid's sides are dropped: a rectangle is 4 corners, 2 triangles;
    # with a square hole 8 corners, ear-clipped into n + 2h - 2 = 8 triangles
    assert len(out) == (8 if hole else 2)
    assert len(np.unique(out)) == (8 if hole else 4)
    assert triangle_areas(uv, out).sum() == pytest.approx(144.0 - (4.0 if hole else 0.0), rel=1e-12)
    # the same texels: rasterised (centres on an edge count) the two triangulations cover the same centres
    from texture.raster import face_id_image

    scaled = uv / 13.0
    np.testing.assert_array_equal(face_id_image(scaled[out], 52, 52)[0] >= 0, face_id_image(scaled[faces], 52, 52)[0] >= 0)


def _annulus(n=720, r=(0.25, 3.0), rings=6):
    """A ring of ``rings`` x ``n`` quads between radii ``r``: two border circles of n vertices each."""
    rad = np.linspace(r[0], r[1], rings + 1)
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    uv = (rad[:, None, None] * np.stack([np.cos(t), np.sin(t)], -1)[None]).reshape(-1, 2)
    i, j = np.meshgrid(np.arange(rings), np.arange(n), indexing="ij")
    a, b = i * n + j, i * n + (j + 1) % n
    c, d = a + n, b + n
    faces = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    return uv, faces


@pytest.mark.parametrize("tol", [1e-3, 1e-2, 5e-2])
def test_simplified_outline_stays_within_its_tolerance(tol):
    uv, faces = _annulus()
    island = np.zeros(len(faces), np.int64)
    exact = island_outlines(uv, faces, island)
    coarse = island_outlines(uv, faces, island, tolerance=tol)
    assert len(np.unique(exact)) == 2 * 720  # both circles, every vertex
    # Douglas-Peucker on a circle of radius R keeps one vertex per chord of sagitta <= tol:
    # about pi / sqrt(2 tol / R) per circle (and at least 3 on the small one)
    def kept(radius):
        return max(3.0, np.pi / np.sqrt(2.0 * tol / radius))
    n = len(np.unique(coarse))
    assert kept(3.0) + 3 <= n <= 2.0 * (kept(3.0) + kept(0.25)) + 8
    # the region moves by at most tol across each border: area within tol x perimeter
    perimeter = 2 * np.pi * (3.0 + 0.25)
    exact_area = triangle_areas(uv, exact).sum()
    assert abs(triangle_areas(uv, coarse).sum() - exact_area) <= tol * perimeter
    # every kept vertex is a border vertex of the island (the outline never invents points)
    assert set(np.unique(coarse)) <= set(np.unique(exact))


def test_island_outline_keeps_faces_where_uvs_overlap():
    uv, faces = _grid_island(n=4)
    folded = uv.copy()
    folded[6] += [2.5, 0.0]  # an interior vertex dragged over the border: the UVs overlap themselves
    island = np.zeros(len(faces), np.int64)
    np.testing.assert_array_equal(island_outlines(folded, faces, island), faces)


@pytest.mark.parametrize("tol", [0.0, 0.3])
def test_island_outline_follows_a_border_that_passes_a_vertex_twice(tol):
    """A 12 x 12 grid with a 2 x 2 hole, and pieces joined to it at single border points: a
    square at its far corner and a triangle at a side (the border passes each joint twice).
    Each piece is ear-clipped on its own, the hole stays in the grid; the same region in a
    few faces (before, such an island was handed to xatlas whole: every face)."""
    uv, faces = _grid_island(hole=True)
    n = len(uv)
    extra = np.array([[13, 12], [13, 13], [12, 13], [5.5, -1.0], [6.5, -1.0]])
    corner, side = 12 * 13 + 12, 6  # grid vertices (12, 12) and (6, 0)
    more = np.array([[corner, n, n + 1], [corner, n + 1, n + 2], [side, n + 3, n + 4]])
    uv, faces = np.vstack([uv, extra]), np.vstack([faces, more])
    assert (signed_areas(uv, faces) > 0).all()
    out = island_outlines(uv, faces, np.zeros(len(faces), np.int64), tolerance=tol)
    # grid with hole: 8 corners, 8 triangles; the square 2; the triangle 1
    assert len(out) == 8 + 2 + 1
    assert triangle_areas(uv, out).sum() == pytest.approx(144.0 - 4.0 + 1.0 + 0.5, rel=1e-12)
    assert (signed_areas(uv, out) > 0).all()
    # the same texels, rasterised, as the island's own faces
    from texture.raster import face_id_image

    scaled = (uv + [0.0, 1.5]) / 16.0
    np.testing.assert_array_equal(face_id_image(scaled[out], 64, 64)[0] >= 0, face_id_image(scaled[faces], 64, 64)[0] >= 0)


def test_packing_through_outlines_matches_packing_faces():
    a_uv, a_f = _grid_island(n=16)
    b_uv, b_f = _grid_island(n=10, hole=True)
    c_uv, c_f = _grid_island(n=6)
    uv = np.concatenate([a_uv, b_uv @ _rot(0.3).T, 0.5 * c_uv])
    faces = np.concatenate([a_f, b_f + len(a_uv), c_f + len(a_uv) + len(b_uv)])
    island = np.repeat([0, 1, 2], [len(a_f), len(b_f), len(c_f)])
    got = {}
    for outlines in (True, False):
        isl = IslandSet.of(uv, faces, island, outlines=outlines)
        assert len(isl.outline.faces) == (2 + 8 + 2 if outlines else len(faces))
        found = search(isl, 256, 2, {}, 16)
        assert found is not None
        tpu, px = found.tpu, found.px
        pk = pack.Packing(px / 256, tpu / 256, tpu, 256, 2, 0.0, 0, 0.0, 0)
        assert_valid_packing(pk, uv, faces, island)
        got[outlines] = verify_packing(px / 256, faces, island, 256)[1]
    # xatlas sees the same regions either way: the same layout, up to the bisection's tolerance
    assert got[True] == pytest.approx(got[False], rel=0.02)


def test_whole_island_beside_outlines_keeps_its_fit_weights():
    """An island handed over whole (its UVs overlap themselves) among outlined ones: its small
    faces are solid against its own median, not against the outlines' big triangles (which
    are most of the faces here), so the fit still holds it."""
    parts, faces, island, off = [], [], [], 0
    for k in range(5):  # five holed rectangles: 8 outline triangles each
        u, f = _grid_island(n=10, hole=True, shift=(12.0 * k, 0.0))
        parts.append(u), faces.append(f + off), island.append(np.full(len(f), k))
        off += len(u)
    b_uv, b_f = _grid_island(n=2)  # 8 faces, dragged over themselves: kept whole
    b_uv = 0.05 * b_uv + [0.0, 15.0]
    b_uv[4] += [0.12, 0.0]
    parts.append(b_uv), faces.append(b_f + off), island.append(np.full(len(b_f), 5))
    uv, faces, island = np.concatenate(parts), np.concatenate(faces), np.concatenate(island)
    isl = IslandSet.of(uv, faces, island)
    assert (isl.outline.island < 5).sum() == 40 and (isl.outline.island == 5).sum() == len(b_f)
    assert isl.outline.weight[np.unique(b_f + off)].sum() > 0
    pk = pack_islands(uv, faces, island, resolution=256, padding=2)
    assert pk.packer == "xatlas"
    assert_valid_packing(pk, uv, faces, island)


def test_packed_islands_are_never_mirrored():
    """xatlas's 90-degree turn is a transpose (a mirror): among many long islands it turns some.
    The packing must keep every island's orientation (signed UV area keeps its sign)."""
    rng = np.random.default_rng(3)
    uvs, faces, island, off = [], [], [], 0
    for k in range(14):
        u, f = _centred_grid(5, 1.0)
        u = u * [rng.uniform(1.5, 3.0), rng.uniform(0.3, 0.6)]  # long and thin: turning helps packing
        u = u @ _rot(rng.uniform(0, np.pi)).T
        uvs.append(u)
        faces.append(f + off)
        island.append(np.full(len(f), k))
        off += len(u)
    uv, faces, island = np.concatenate(uvs), np.concatenate(faces), np.concatenate(island)
    isl = IslandSet.of(uv, faces, island)
    raw = plan_layouts([(uv, faces, island)], candidates=DEFAULT_POLICY.pack_candidates, resolution=256,
                       padding=2)[0]
    assert mirrored_islands(isl, raw.uv), "the plan (turns allowed) mirrors some island"
    packed = pack.pack_islands(uv, faces, island, resolution=256, padding=2)
    assert mirrored_islands(isl, packed.uv) == []
    assert verify_packing(packed.uv, faces, island, 256)[0] == 0
    assert packed.utilization > 0.3


@pytest.mark.parametrize("strict", [True, False])
def test_row_spans_hit_exactly_the_texels_of_boxes(strict):
    """``iter_hits(spans=True)`` (for the long fans of ear-clipped outlines) yields the same
    (texel, face) hits as the bounding-box scan: random triangles, long thin ones, and
    corners on texel centres (where the strict/inclusive rule decides)."""
    from texture.raster import iter_hits

    rng = np.random.default_rng(3)
    tris = [rng.uniform(-0.1, 1.1, (300, 1, 2)) + rng.normal(0, 0.2, (300, 3, 2))]
    thin = rng.uniform(0, 1, (200, 3, 2))
    thin[:, 2] = thin[:, 0] + 1e-3 * (thin[:, 1] - thin[:, 0]) + [2e-3, 0]
    tris += [thin, (np.round(rng.uniform(0, 1, (300, 3, 2)) * 32) + 0.5) / 64]
    for tri in tris:
        for h, w in ((128, 128), (61, 90)):
            box = {(int(r), int(c), int(f)) for x in iter_hits(tri, h, w, strict) for r, c, f in zip(x.row, x.col, x.face)}
            span = {(int(r), int(c), int(f)) for x in iter_hits(tri, h, w, strict, spans=True)
                    for r, c, f in zip(x.row, x.col, x.face)}
            assert box == span and len(box) > 100
    # the closed form of the module docstring: (0,0) (1,0) (0,1) on 4 x 4 hits the 6 texels
    # strictly below the anti-diagonal, 10 with the 4 centres on it
    unit = np.array([[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]])
    assert sum(len(x.row) for x in iter_hits(unit, 4, 4, strict, spans=True)) == (6 if strict else 10)


def test_verify_packing_counts_shared_texels_exactly():
    """The run-based check (:func:`texture.verify.verify_packing`) against a texel-by-texel
    count from the bounding-box scan: random overlapping triangles of 5 islands at two
    resolutions. A texel under k islands adds k - 1; a fold inside one island adds nothing."""
    from texture.raster import iter_hits

    rng = np.random.default_rng(11)
    for res in (97, 256):
        uv = rng.uniform(0, 1, (60, 1, 2)) + rng.normal(0, 0.15, (60, 3, 2))
        faces = np.arange(180).reshape(60, 3)
        island = rng.integers(0, 5, 60)
        owners: dict[int, set] = {}
        for h in iter_hits(uv.reshape(-1, 2)[faces], res, res, strict=True):
            for t, k in zip((h.row * res + h.col).tolist(), island[h.face].tolist()):
                owners.setdefault(t, set()).add(k)
        want = sum(len(s) - 1 for s in owners.values())
        got = verify_packing(uv.reshape(-1, 2), faces, island, res)
        assert want > 100 and got[0] == want
        assert got[1] == pytest.approx(len(owners) / res**2, abs=1e-12)
        # one island: overlapping faces are a fold, not a clash; the covered fraction is the same
        one = verify_packing(uv.reshape(-1, 2), faces, np.zeros(60, np.int64), res)
        assert one == (0, got[1])


def test_exhaustive_placement_runs_at_the_coarse_resolution_only(monkeypatch):
    """xatlas's ``bruteForce`` costs about 250x more per call at full resolution than at the
    coarse one (80 s for one layout's full-resolution search): a plan made with it is used as
    is, and every full-resolution search (here: keeping islands unmirrored once the coarse
    tries are spent, ``unmirror_steps=0``) runs without it, and the packing stays valid."""
    import texture.placement as placement
    import texture.scale_search as scale_search

    calls = []
    real = placement.xatlas_pack

    def recorded(uv, faces, island, resolution, padding, tpu, options=None):
        calls.append((int(padding), bool((options or {}).get("bruteForce"))))  # padding 1: coarse
        return real(uv, faces, island, resolution, padding, tpu, options)

    monkeypatch.setattr(placement, "xatlas_pack", recorded)
    monkeypatch.setattr(scale_search, "xatlas_pack", recorded)
    uv, faces, island = _long_thin_islands()
    isl = IslandSet.of(uv, faces, island)
    brute = {"bruteForce": True}
    plan = plan_layouts([(uv, faces, island)], candidates=(brute,), resolution=1024, padding=4)[0]
    assert plan.options == brute and mirrored_islands(isl, plan.uv), "the plan (turns allowed) mirrors some island"
    assert calls and all(pad == 1 and b for pad, b in calls)  # the plan: coarse, exhaustive
    calls.clear()
    pk = pack_islands(uv, faces, island, resolution=1024, padding=4, plan=plan,
                      policy=SearchPolicy(unmirror_steps=0))
    full = [b for pad, b in calls if pad != 1]
    assert full and not any(full), calls
    assert pk.packer == "xatlas" and mirrored_islands(isl, pk.uv) == []
    assert_valid_packing(pk, uv, faces, island)
    calls.clear()
    pack_islands(uv, faces, island, resolution=1024, padding=4, options=brute)  # asked for at full resolution
    full = [b for pad, b in calls if pad != 1]
    assert full and not any(full)
    assert pack.full_options(brute) == {} and pack.full_options({**brute, "rotate_charts": False}) == {"rotate_charts": False}


def test_unmirroring_skips_what_cannot_pass_the_caller_floor(monkeypatch):
    """A caller keeps a packing only above a floor (its best so far): keeping the islands
    unmirrored tries only the scale steps whose utilisation, grown, can pass it (the texels
    grow with the scale squared), and the full-resolution search without turns only where
    its coarse plan packs above it. Without a floor every step and the search run."""
    uv, faces, island = _long_thin_islands()
    isl = IslandSet.of(uv, faces, island)
    plan = plan_layouts([(uv, faces, island)], candidates=({},), resolution=1024, padding=4)[0]
    assert mirrored_islands(isl, plan.uv), "the plan (turns allowed) mirrors some island"
    best = pack.Candidate(plan.utilization, plan.texels_per_unit, plan.uv * 1024, plan.options)
    tried, searched = [], []
    monkeypatch.setattr(pack, "attempt", lambda *a, **k: tried.append(a[3]) or None)  # every try fails
    monkeypatch.setattr(pack, "search", lambda *a, **k: searched.append(a) or None)
    steps = DEFAULT_POLICY.unmirror_steps
    assert pack._without_mirrors(isl, 1024, 4, best, DEFAULT_POLICY) is None
    assert len(tried) == steps and len(searched) == 1
    # steps 0-2 reach utilisation * 0.985^(2k) * 1.0075^2 above this floor, step 3 does not
    floor = best.utilization * (pack.FINE_SHRINK ** 2.5 * pack.GROW_STEPS[0]) ** 2
    plain = plan_layouts([(uv, faces, island)], candidates=({"rotate_charts": False},), resolution=1024,
                         padding=4)[0]
    assert 0 < plain.utilization < floor
    tried.clear(), searched.clear()
    assert pack._without_mirrors(isl, 1024, 4, best, DEFAULT_POLICY, floor) is None
    np.testing.assert_allclose(tried, best.tpu * pack.FINE_SHRINK ** np.arange(3) * 256 / 1024)
    assert searched == []
    tried.clear()
    pack._without_mirrors(isl, 1024, 4, best, DEFAULT_POLICY, 0.99 * plain.utilization)
    assert len(tried) == steps and len(searched) == 1


def test_rotations_of_many_sets_at_once_equal_one_fit_each():
    """similarity_rotations is similarity_fit batched: on 60 point sets (rotated or mirrored,
    scaled by 1.7, some noisy, some of zero total weight or zero spread) it gives each set's
    rotation, weighted means and total weight, and mirrored sets come back mirrored."""
    from texture.similarity import similarity_rotations

    rng = np.random.default_rng(0)
    src, dst, w, g, mirrored = [], [], [], [], []
    for k in range(60):
        m = int(rng.integers(3, 12))
        s = rng.normal(size=(m, 2)) * rng.uniform(0.1, 5)
        R = _rot(rng.uniform(0, 2 * np.pi)) @ (np.diag([1.0, -1.0]) if k % 3 == 0 else np.eye(2))
        d = 1.7 * s @ R.T + rng.normal(size=2) + rng.normal(size=(m, 2)) * (0.3 if k % 5 == 0 else 0.0)
        ww = rng.random(m) * (k % 7 != 0)
        if k % 11 == 0:
            s[:] = s[0]
        src.append(s), dst.append(d), w.append(ww), g.append(np.full(m, k))
        mirrored.append(k % 3 == 0 and k % 7 != 0 and k % 11 != 0 and k % 5 != 0)
    src, dst, w, g = map(np.concatenate, (src, dst, w, g))
    got = similarity_rotations(src, dst, w, g, 60)
    for k in range(60):
        sel = g == k
        fit = similarity_fit(src[sel], dst[sel], w[sel])
        np.testing.assert_allclose(got.rotation[k], fit.rotation, atol=1e-9)
        assert got.weight[k] == pytest.approx(w[sel].sum())
        if w[sel].sum() > 0:
            np.testing.assert_allclose(got.mean_src[k], w[sel] @ src[sel] / w[sel].sum())
            np.testing.assert_allclose(got.mean_dst[k], w[sel] @ dst[sel] / w[sel].sum())
        if mirrored[k]:
            assert np.linalg.det(got.rotation[k]) < 0
    assert sum(mirrored) >= 5
