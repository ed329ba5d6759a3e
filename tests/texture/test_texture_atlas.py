"""Charts -> atlas: iso-line clipping, overlap trimming, packing at one texel density."""
from __future__ import annotations

import numpy as np
import pytest
from texture_helpers import cap_chart, sphere_charts

from mnacore.charts import ChartGrids, load_charts
from mnacore.frame import Normalization
from mnacore.grid import grid_faces
from mnacore.triangles import triangle_areas
from texture.atlas import AtlasConfig, build_atlas
from texture.clip import clip_mesh
from texture.harness import measure
from texture.islands import uv_islands
from texture.layouts import merge_pieces
from texture.pack import pack_islands
from texture.raster import coverage_count
from texture.relax import RelaxConfig
from texture.trim import border_points, domain_pieces, trim_charts
from texture.verify import verify_packing


def _uv_area(uv, faces):
    t = uv[faces]
    return 0.5 * ((t[:, 1, 0] - t[:, 0, 0]) * (t[:, 2, 1] - t[:, 0, 1]) - (t[:, 1, 1] - t[:, 0, 1]) * (t[:, 2, 0] - t[:, 0, 0]))


@pytest.mark.parametrize("G", [5, 17])
def test_clip_linear_field_is_exact_at_any_resolution(G):
    lin = np.linspace(0, 1, G)
    x, y = np.meshgrid(lin, lin, indexing="xy")
    P = np.column_stack([x.ravel(), y.ravel()])
    field = 0.62 - P[:, 0] - 0.2 * P[:, 1]  # kept: x + 0.2 y < 0.62, a trapezoid of area 0.52
    c = clip_mesh(P, grid_faces(G), field)
    area = _uv_area(c.attrs, c.faces)
    assert (area > 0).all()  # orientation kept, no inverted pieces
    assert area.sum() == pytest.approx(0.52, abs=1e-9)
    cut = c.attrs[c.field == 0]
    np.testing.assert_allclose(cut[:, 0] + 0.2 * cut[:, 1], 0.62, atol=1e-12)  # cut points on the iso-line
    assert len(uv_islands(c.faces, c.attrs)) == len(c.faces) and uv_islands(c.faces, c.attrs).max() == 0


def test_domain_cut_follows_iso_line_not_staircase():
    theta_max = np.radians(80)
    G = 64
    uv, xyz, occ = cap_chart(G, theta_max, (0, 0, 1))
    charts = ChartGrids(uv[None], xyz[None], occ[None], 0.5, Normalization(np.zeros(3), 1.0))
    piece = domain_pieces(charts)[0]
    cap_area = 2 * np.pi * (1 - np.cos(theta_max))
    rim = 2 * np.pi * np.sin(theta_max)
    assert piece.area().sum() == pytest.approx(cap_area, rel=5e-3)
    b = border_points(piece)
    polar = np.arccos(np.clip(b[:, 2], -1, 1))
    np.testing.assert_allclose(polar, theta_max, atol=2e-3)  # border vertices on the rim
    # border length: iso-line ~ the rim; whole grid cells (the run's kept mesh) are a staircase
    from mnacore.uvmesh import make_uv_mesh

    ours = measure(make_uv_mesh(piece.xyz, piece.faces, piece.uv), reference_is_closed=True, resolution=64)
    tri = grid_faces(G)
    kept = tri[(occ.reshape(-1) > 0.5)[tri].all(1)]
    stair = measure(make_uv_mesh(xyz.reshape(-1, 3), kept, uv.reshape(-1, 2)), reference_is_closed=True, resolution=64)
    # seam length = half the border (its two sides count once) / sqrt(area): scale-free
    assert ours.summary["seam_length"] == pytest.approx(rim / 2 / np.sqrt(cap_area), rel=0.01)
    assert stair.summary["seam_length"] > 1.2 * ours.summary["seam_length"]


def test_trim_two_caps_gives_one_layer(sphere_run):
    charts = load_charts(sphere_run / "charts.npz")
    res = trim_charts(charts)
    total = sum(p.area().sum() for p in res.pieces)
    assert total == pytest.approx(4 * np.pi, rel=0.01)  # every part of the sphere once
    assert res.stats.doubly_covered_percent_before > 20  # the 75..105 degree band
    assert res.stats.doubly_covered_percent <= 1.0
    for p in res.pieces:  # by symmetry the border is the equator
        assert p.area().sum() == pytest.approx(2 * np.pi, rel=0.02)
        assert np.abs(border_points(p)[:, 2]).max() < 0.05
        assert uv_islands(p.faces, p.uv).max() == 0  # one island per cap


def test_pack_keeps_one_scale_no_overlap_inside_unit_square():
    rng = np.random.default_rng(0)
    uvs, faces, island, off = [], [], [], 0
    sizes = [1.0, 0.5, 0.3, 0.3, 0.12]
    for i, s in enumerate(sizes):  # islands: jittered grids of different sizes, same local UV origin
        G = 6
        lin = np.linspace(-s, s, G)
        u, v = np.meshgrid(lin, lin, indexing="xy")
        P = np.column_stack([u.ravel(), v.ravel()]) + 0.02 * s * rng.standard_normal((G * G, 2))
        uvs.append(P)
        faces.append(grid_faces(G) + off)
        island.append(np.full(2 * (G - 1) ** 2, i))
        off += G * G
    uv, faces, island = np.concatenate(uvs), np.concatenate(faces), np.concatenate(island)
    pk = pack_islands(uv, faces, island, resolution=256, padding=2)
    assert pk.uv.min() >= 0 and pk.uv.max() <= 1
    # rasterise every island separately: no texel is covered by two islands
    counts = np.stack([coverage_count(pk.uv[faces[island == i]], 256, 256) > 0 for i in range(len(sizes))])
    assert counts.sum(0).max() == 1
    assert verify_packing(pk.uv, faces, island, 256)[0] == 0
    # one scale for every island, and each island is a rigid copy (edge lengths scale by pk.scale)
    ratio = np.abs(_uv_area(pk.uv, faces)) / np.abs(_uv_area(uv, faces))
    np.testing.assert_allclose(ratio, pk.scale**2, rtol=1e-6)
    e_in = np.linalg.norm(uv[faces[:, 1]] - uv[faces[:, 0]], axis=1)
    e_out = np.linalg.norm(pk.uv[faces[:, 1]] - pk.uv[faces[:, 0]], axis=1)
    np.testing.assert_allclose(e_out, pk.scale * e_in, rtol=1e-6)
    assert 0.2 < pk.utilization < 1.0


@pytest.mark.parametrize("max_islands", [0, 6])
def test_build_atlas_on_synthetic_sphere(sphere_run, max_islands):
    charts = load_charts(sphere_run / "charts.npz")
    # the charts' own UVs (no relaxation), so the packed areas have a closed form below
    atlas = build_atlas(charts, AtlasConfig(resolution=256, padding=2, max_islands=max_islands,
                                            relax=RelaxConfig(iterations=0)))
    s = atlas.stats
    if max_islands == 0:  # the two caps, trimmed at the equator, one island each
        assert s["islands"] == 2 and s["charts_used"] == 2 and s["split_islands"] == 0
    else:
        # two discs pack into at most 2 pi / 16 = 0.39 of a square; one cut in half packs tighter
        assert s["islands"] == 3 and s["charts_used"] == 2 and s["split_islands"] == 1
        assert s["utilization_coarse_cut"] >= s["utilization_coarse_uncut"] + 0.02
        assert s["utilization"] > 2 * np.pi / 16
    assert s["doubly_covered_percent"] <= 1.0
    assert s["fscore_drop"] <= 0.5
    assert atlas.mesh.uv.min() >= 0 and atlas.mesh.uv.max() <= 1
    # positions come back in the input frame: on the sphere of radius SCALE around CENTER
    from texture_helpers import CENTER, SCALE

    r = np.linalg.norm(atlas.mesh.vertices - CENTER, axis=1)
    np.testing.assert_allclose(r, SCALE, rtol=2e-3)
    # one scale for both islands: each cap's domain is cut at the equator, theta = 90 deg, i.e. the
    # chart-local disc r < 90/105, so the packed UV area is uv_scale^2 * 2 pi (90/105)^2
    per_face = np.abs(_uv_area(atlas.mesh.uv, atlas.mesh.faces))
    expected = s["uv_scale"] ** 2 * np.pi * (90 / 105) ** 2
    for k in range(2):
        assert per_face[atlas.chart == k].sum() == pytest.approx(expected, rel=0.01)


def test_relaxed_sphere_atlas_keeps_one_scale_and_lowers_distortion(sphere_run):
    """Relaxed (the default): each hemisphere is re-flattened toward an isometry at one shared
    scale, so the two mirror-image caps keep equal UV areas and texel densities, no face flips,
    and the distortion drops."""
    charts = load_charts(sphere_run / "charts.npz")
    cfg = dict(resolution=256, padding=2, max_islands=0)
    raw = build_atlas(charts, AtlasConfig(**cfg, relax=RelaxConfig(iterations=0)))
    relaxed = build_atlas(charts, AtlasConfig(**cfg))
    s = relaxed.stats
    assert s["islands"] == 2 and s["relax_stopped_by_crossing"] == 0 and s["relax_iterations_max"] >= 1
    # a hemisphere cannot be flattened isometrically: the azimuthal-equidistant charts are close
    # to the best already, and each iteration kept gained at least min_gain
    assert s["relax_energy_after"] <= s["relax_energy_before"] - RelaxConfig().min_gain
    d_raw = measure(raw.mesh).summary["distortion_metric"]
    d_relaxed = measure(relaxed.mesh).summary["distortion_metric"]
    assert d_relaxed < d_raw - RelaxConfig().min_gain
    per_face = np.abs(_uv_area(relaxed.mesh.uv, relaxed.mesh.faces))
    caps = [per_face[relaxed.chart == k].sum() for k in range(2)]
    assert caps[0] == pytest.approx(caps[1], rel=0.01)
    # one texel density: UV area per 3D area is the same on both caps, and no face flipped
    area3d = triangle_areas(relaxed.mesh.vertices, relaxed.mesh.faces)
    density = [caps[k] / area3d[relaxed.chart == k].sum() for k in range(2)]
    assert density[0] == pytest.approx(density[1], rel=0.01)
    signs = [np.sign(_uv_area(m.mesh.uv, m.mesh.faces)) for m in (raw, relaxed)]
    for k in range(2):  # each island keeps one orientation
        assert len(np.unique(signs[1][relaxed.chart == k])) == 1


def test_sphere_charts_fixture_is_consistent():
    uv, xyz, occ = sphere_charts(G=33)
    assert uv.shape == (2, 33, 33, 2) and xyz.shape == (2, 33, 33, 3) and occ.shape == (2, 33, 33)
    # grid convention: uv[k, i, j] = (u_j, v_i)
    assert uv[0, 0, 32].tolist() == [1.0, -1.0] and uv[0, 32, 0].tolist() == [-1.0, 1.0]


def test_build_atlas_is_deterministic(sphere_run):
    charts = load_charts(sphere_run / "charts.npz")
    a = build_atlas(charts, AtlasConfig(resolution=128, padding=2))
    b = build_atlas(charts, AtlasConfig(resolution=128, padding=2))
    np.testing.assert_array_equal(a.mesh.uv, b.mesh.uv)
    np.testing.assert_array_equal(a.mesh.faces, b.mesh.faces)
    assert a.stats["doubly_covered_percent"] == b.stats["doubly_covered_percent"]


def test_islands_touching_at_a_vertex_get_their_own_copy():
    """Two squares of one chart meeting at a single corner are two islands (no shared edge); packing
    one must not drag the other's corner along, so merging gives each its own vertex there."""
    from texture.trim import Piece

    t = np.linspace(0.0, 1.0, 9)
    u, v = np.meshgrid(t, t, indexing="xy")
    grid_uv = np.column_stack([u.ravel(), v.ravel()])
    f = grid_faces(9)
    uv = np.concatenate([grid_uv - 1.0, grid_uv])  # squares [-1,0]^2 and [0,1]^2 meet at (0, 0)
    faces = np.concatenate([f, f + len(grid_uv)])
    shared = np.flatnonzero(np.all(uv == 0.0, axis=1))
    faces[faces == shared[1]] = shared[0]  # one vertex index for the common corner
    piece = Piece(0, np.column_stack([uv, np.zeros(len(uv))]), uv, faces)
    uv_local, faces_m, island = merge_pieces([piece]).islands
    assert island.max() == 1
    for i in range(2):  # no vertex is used by both islands
        assert not np.isin(faces_m[island == i], faces_m[island != i]).any()
    pk = pack_islands(uv_local, faces_m, island, resolution=128, padding=2)
    assert verify_packing(pk.uv, faces_m, island, 128)[0] == 0
    for i in range(2):  # each island is a rigid copy at the shared scale: its UV area scales by scale^2
        sel = island == i
        assert np.abs(_uv_area(pk.uv, faces_m[sel])).sum() == pytest.approx(pk.scale ** 2 * 1.0, rel=1e-6)


def _rectangle_island(G=41):
    from texture.trim import Piece

    rows = (G + 1) // 2
    lin = np.linspace(0.0, 2.0, G)  # a 2 x 1 rectangle of square cells: its long (principal) axis is u
    u, v = np.meshgrid(lin, lin[:rows], indexing="xy")
    uv = np.column_stack([u.ravel(), v.ravel()])
    faces = grid_faces(G)[: 2 * (G - 1) * (rows - 1)]  # the cells of the first rows - 1 rows
    return Piece(0, np.column_stack([uv, np.zeros(len(uv))]), uv, faces)


@pytest.mark.parametrize("fraction", [None, 0.25, 0.75])
def test_cut_island_leaves_the_asked_area_fraction(fraction):
    from texture.layouts import cut_island

    p = _rectangle_island()
    area = p.uv_area().sum()
    parts = cut_island([p], 0, 0, long_axis=True, fraction=fraction)
    assert len(parts) == 2
    areas = sorted(q.uv_area().sum() / area for q in parts)
    # the cut loses and adds nothing (up to slivers the clip drops where it runs along grid vertices)
    assert sum(areas) == pytest.approx(1.0, abs=1e-6)
    want = 0.25 if fraction is not None else 0.5  # the centroid halves a rectangle
    # the cut sits at a face-centre quantile: within one grid column (1/40 of the length)
    assert areas[0] == pytest.approx(want, abs=1 / 40)
    for q in parts:  # a straight cut across the long axis: each part spans the full width
        assert np.ptp(q.uv[np.unique(q.faces), 1]) == pytest.approx(np.ptp(p.uv[:, 1]))
    with pytest.raises(ValueError, match="fraction"):
        cut_island([p], 0, 0, fraction=1.0)


def test_search_gives_up_below_min_estimate():
    from texture.policy import DEFAULT_POLICY
    from texture.scale_search import plan_layouts

    p = _rectangle_island()
    island = np.zeros(len(p.faces), np.int64)
    kw = {"candidates": DEFAULT_POLICY.pack_candidates, "resolution": 256, "padding": 2, "workers": 1}
    plain = plan_layouts([(p.uv, p.faces, island)], **kw)[0]
    assert plain is not None and 0.3 < plain.utilization < 1.0
    # one rectangle cannot fill more than the square: an estimate above 1 prunes every search
    assert plan_layouts([(p.uv, p.faces, island)], min_estimate=1.01, **kw) == [None]


@pytest.mark.parametrize("target", [0.0, 1.0])
def test_off_centre_cuts_only_below_the_target(sphere_run, target):
    charts = load_charts(sphere_run / "charts.npz")
    s = build_atlas(charts, AtlasConfig(resolution=256, padding=2, target_utilization=target)).stats
    tried = s.get("utilization_coarse_off_centre_cuts")
    if target == 0.0:
        assert tried is None
    else:  # no packing reaches 1: the two caps x 2 axes x 2 positions are packed too
        assert len(tried) == 8
        assert s["islands"] == 3 and s["split_islands"] == 1
        # the kept cut is the best of both rounds
        found = [u for u in s["utilization_coarse_cuts"] + tried if u is not None]
        assert s["utilization_coarse_cut"] == max(found)
        assert s["cut"]["through_centroid"] == (s["cut"]["area_fraction"] == 0.5)


def test_unique_rows_matches_numpy():
    from texture.islands import unique_rows

    rng = np.random.default_rng(3)
    v = rng.integers(0, 4, (500, 3)).astype(float) * 0.1
    v[::7, 1] = -0.0  # equal to 0.0, as in np.unique
    _, first, ids = np.unique(v, axis=0, return_index=True, return_inverse=True)
    f2, i2 = unique_rows(v)
    np.testing.assert_array_equal(f2, first)
    np.testing.assert_array_equal(i2, ids.reshape(-1))
    empty_first, empty_ids = unique_rows(np.zeros((0, 5)))  # no rows: no ids (uv_islands of an empty piece)
    assert len(empty_first) == 0 and len(empty_ids) == 0


def _plan(u):
    from texture.scale_search import Plan

    return None if u is None else Plan(u, 1.0, {}, 1)


@pytest.mark.parametrize("relaxed_util, raw_util, kept", [(0.55, 0.62, False), (0.55, 0.58, True),
                                                          (0.61, 0.70, True), (None, 0.62, False),
                                                          (0.55, None, True)])
def test_relaxation_is_dropped_only_when_it_costs_the_utilisation_target(relaxed_util, raw_util, kept):
    """The charts' own UVs replace the relaxed ones only when the relaxed layouts pack below
    the target (0.6) and the unrelaxed reach it."""
    from texture.policy import keep_relaxed

    assert keep_relaxed(_plan(relaxed_util), _plan(raw_util), 0.6) is kept


@pytest.mark.parametrize("target", [0.01, 1.0])
def test_relax_choice_follows_the_recorded_utilisations(sphere_run, target):
    """The atlas's relaxation choice agrees with the coarse utilisations it records: the
    unrelaxed layout is searched only when the relaxed one misses the target, dropped only when
    it reaches it, and the packed UVs are those of the kept variant (distortion)."""
    charts = load_charts(sphere_run / "charts.npz")
    got = build_atlas(charts, AtlasConfig(resolution=128, padding=2, max_islands=0, target_utilization=target))
    raw = build_atlas(charts, AtlasConfig(resolution=128, padding=2, max_islands=0, relax=RelaxConfig(iterations=0)))
    s = got.stats
    compared = "utilization_coarse_unrelaxed" in s
    assert compared is (target == 1.0)  # no packing reaches 1: the charts' own UVs are laid out too
    if compared:
        assert s["utilization_coarse_relaxed"] < target
        assert s["relax_kept"] is not (s["utilization_coarse_unrelaxed"] is not None
                                       and s["utilization_coarse_unrelaxed"] >= target)
    else:
        assert s["relax_kept"] is True
    d_got = measure(got.mesh).summary["distortion_metric"]
    d_raw = measure(raw.mesh).summary["distortion_metric"]
    if s["relax_kept"]:
        assert d_got < d_raw - RelaxConfig().min_gain
    else:
        assert d_got == pytest.approx(d_raw, rel=1e-6)


def _flat_piece(width, height, G=9):
    from texture.trim import Piece

    u, v = np.meshgrid(np.linspace(0.0, width, G), np.linspace(0.0, height, G), indexing="xy")
    uv = np.column_stack([u.ravel(), v.ravel()])
    return Piece(0, np.column_stack([uv, np.zeros(len(uv))]), uv, grid_faces(G))


@pytest.mark.parametrize("target", [0.02, 0.5, 0.99])
def test_layout_stage_drops_the_relaxed_uvs_only_for_the_target(target):
    """The layout stage on real packings: a 16:1 strip (standing in for relaxed islands that
    pack loosely) against a square (the charts' own UVs, packing tightly). Below both
    utilisations the relaxed layout is kept and the other never laid out; between them the
    square's layout is packed instead; above both the relaxed one is kept."""
    from texture.atlas_stages import choose_layout
    from texture.atlas_stats import RelaxStats
    from texture.layouts import prepare

    strip, square = [prepare(_flat_piece(8.0, 0.5))], [prepare(_flat_piece(1.0, 1.0))]
    stats = RelaxStats()
    cfg = AtlasConfig(resolution=256, padding=2, max_islands=0, target_utilization=target)
    choice = choose_layout(strip, square, cfg, stats)
    if target == 0.02:
        assert stats.kept is True and not stats.compared_unrelaxed
        assert choice.plan.utilization >= target
    else:
        assert stats.compared_unrelaxed and stats.coarse_relaxed < 0.5 <= stats.coarse_unrelaxed < 0.99
        assert stats.kept is (target == 0.99)
    want = square if stats.kept is False else strip
    np.testing.assert_array_equal(choice.merged.uv, want[0].piece.uv)
    if stats.compared_unrelaxed:  # the plan packed is the one recorded for the kept layout
        assert choice.plan.utilization == (stats.coarse_unrelaxed if stats.kept is False else stats.coarse_relaxed)


@pytest.mark.parametrize("target, order", [(0.6, [1, 2]), (0.72, [1, 2]), (0.75, [1]), (0.8, [])])
def test_off_centre_order_prunes_far_guesses_and_ranks_the_rest(target, order):
    """Guesses 0.5, 0.7, 0.66, 0.2: those more than the margin (0.07) under the target are never
    searched; the others are searched best guess first."""
    from texture.policy import off_centre_order
    from texture.scale_search import Estimate

    guesses = [Estimate(0.5, 50.0), Estimate(0.7, 70.0), Estimate(0.66, 66.0), None, Estimate(0.2, 20.0)]
    assert off_centre_order(guesses, target, 0.07) == order
    assert all(guesses[i].utilization >= target - 0.07 for i in order)


@pytest.mark.parametrize("above_best_guess", [None, 0.05])
def test_off_centre_search_stops_at_the_target_and_skips_far_guesses(sphere_run, above_best_guess):
    """On the sphere's real off-centre cut layouts, one search at a time: only layouts whose
    first guess is within the policy's margin of the target are searched, best guess first,
    and the search stops at the first layout that reaches the target (a low target: the first
    one; a target above every guess: possibly none)."""
    from texture.layout_search import cut_candidates, off_centre_plans, ranked_islands
    from texture.layouts import prepare
    from texture.policy import DEFAULT_POLICY, off_centre_order
    from texture.scale_search import estimate_layouts

    charts = load_charts(sphere_run / "charts.npz")
    layout = [prepare(p) for p in trim_charts(charts, AtlasConfig().trim).pieces]
    wider = cut_candidates(layout, ranked_islands(layout), DEFAULT_POLICY.off_centre_cuts, 6)
    arrays = [c.islands for c in wider]
    assert len(arrays) == 8  # two caps x two axes x two positions
    guesses = estimate_layouts(arrays, resolution=256, padding=2, options=DEFAULT_POLICY.pack_candidates[0])
    best_guess = max(g.utilization for g in guesses if g is not None)
    target = 0.01 if above_best_guess is None else best_guess + above_best_guess
    order = off_centre_order(guesses, target, DEFAULT_POLICY.prune_margin)
    assert order and order[0] == int(np.argmax([-1 if g is None else g.utilization for g in guesses]))
    goal = AtlasConfig(resolution=256, padding=2, max_islands=6, target_utilization=target)
    plans = off_centre_plans(arrays, goal, workers=1)
    searched = [i for i, p in enumerate(plans) if p is not None]
    # a prefix of the order (a search may find nothing: then it is None like an unsearched one)
    k = max(order.index(i) for i in searched) + 1 if searched else 0
    assert set(searched) <= set(order[:k])
    reached = [i for i in order[:k] if plans[i] is not None and plans[i].utilization >= target]
    assert reached == ([order[k - 1]] if reached else [])  # it stopped at the first to reach the target
    if not reached:
        assert k == len(order) or not searched
    if above_best_guess is None:
        assert searched == [order[0]] and reached == [order[0]]


@pytest.mark.parametrize("target", [0.01, 1.0])
def test_other_options_for_every_layout_until_the_target(target):
    """Round one packs every layout with xatlas's default options, then the other option sets:
    for the uncut islands and the best cut once a layout reached the target, else for all."""
    from texture.policy import best_cut, other_options_for

    plans = [_plan(u) for u in (0.50, 0.55, None, 0.52)]
    assert best_cut(plans) == 1
    assert other_options_for(plans, target) == ([0, 1] if target <= 0.55 else [0, 1, 2, 3])
    assert other_options_for(plans, 0.0) == [0, 1, 2, 3]  # target 0: "no target", never reached


@pytest.mark.parametrize("target", [0.0, 0.6, 1.0])
def test_layout_search_keeps_the_best_layout_only_with_the_split_gain(sphere_run, target):
    """Whatever the rounds searched, the layout kept is the uncut islands unless the best cut
    found gains ``split_gain`` over them, and then it is that best cut; its plan packs as recorded."""
    from texture.layout_search import search_layouts
    from texture.layouts import island_count, prepare

    charts = load_charts(sphere_run / "charts.npz")
    cfg = AtlasConfig(resolution=256, padding=2, target_utilization=target, relax=RelaxConfig(iterations=0))
    layout = [prepare(p) for p in trim_charts(charts, cfg.trim).pieces]
    assert island_count(layout) == 2  # two caps
    choice = search_layouts(layout, cfg)
    s = choice.stats.to_json()
    cuts = [u for u in s["utilization_coarse_cuts"] + s.get("utilization_coarse_off_centre_cuts", []) if u is not None]
    split = max(cuts) >= s["utilization_coarse_uncut"] + cfg.split_gain
    assert s["split_islands"] == int(split)
    assert int(choice.merged.island.max()) + 1 == 2 + int(split)
    assert choice.plan.utilization == (max(cuts) if split else s["utilization_coarse_uncut"])
    if split:
        assert s["utilization_coarse_cut"] == max(cuts)
