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
    assert s["islands_before_layout"] == 2 and s["charts_used"] == 2  # the two caps, trimmed at the equator
    if max_islands == 0:  # no halvings: one island per cap
        assert s["islands"] == 2 and s["split_islands"] == 0 and s["halvings"] == []
    else:
        # two discs leave a square's corners empty: the packing search halves them while each
        # halving gains the split gain (0.02), and every halving adds one island
        n = s["split_islands"]
        assert n >= 1 and s["islands"] == 2 + n == int(atlas.island.max()) + 1
        chain = [s["utilization_uncut"]] + [h["utilization"] for h in s["halvings"]
                                            if not (h.get("paired") or h.get("after_quarter_turns"))]
        assert all(b >= a + 0.02 for a, b in zip(chain, chain[1:]))
        assert s["utilization"] >= chain[-1]
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


def test_halvings_add_exactly_their_cut_length_of_seam(sphere_run):
    """The packing search's halvings cut along mesh edges and keep every UV: the atlas's seams
    (the harness's, unit frame, before normalising by the root of the area) grow by exactly the
    3D length of the cuts it records, and the faces are those of the uncut atlas."""
    from mnacore.triangles import triangle_areas

    charts = load_charts(sphere_run / "charts.npz")
    seams, atlases = [], []
    for max_islands in (0, 6):
        a = build_atlas(charts, AtlasConfig(resolution=256, padding=2, max_islands=max_islands,
                                            relax=RelaxConfig(iterations=0)))
        m = a.mesh_unit
        seams.append(measure(m).summary["seam_length"] * np.sqrt(triangle_areas(m.vertices, m.faces).sum()))
        atlases.append(a)
    cuts = [h["cut_length"] for h in atlases[1].stats["halvings"]]
    assert cuts and all(c > 0.5 for c in cuts)  # a cut across a unit hemisphere is not short
    assert seams[1] - seams[0] == pytest.approx(sum(cuts), rel=1e-9)
    areas = [np.sort(triangle_areas(a.mesh_unit.vertices, a.mesh_unit.faces)) for a in atlases]
    np.testing.assert_allclose(areas[1], areas[0], rtol=1e-9)


@pytest.mark.parametrize("max_islands", [2, 3])
def test_max_islands_is_the_search_island_target(sphere_run, max_islands):
    """``max_islands`` is the island target of the packing search: a halving from within it
    gains the split gain, one at it (or past it) only the first seam's gain, and without any
    halving the atlas keeps its two caps."""
    from texture.atlas_stages import layout_goal
    from texture.unwrap_layout import FIRST_SEAM_GAIN

    charts = load_charts(sphere_run / "charts.npz")
    cfg = AtlasConfig(resolution=256, padding=2, max_islands=max_islands, relax=RelaxConfig(iterations=0))
    goal = layout_goal(cfg)
    assert (goal.long_max_islands, goal.pack_cut_gain, goal.pack_target) == (max_islands, 0.02, 0.6)
    assert (goal.resolution, goal.padding) == (256, 2)
    s = build_atlas(charts, cfg).stats
    hs, i = s["halvings"], 0
    before, count = s["utilization_uncut"], 2
    while i < len(hs):
        group = hs[i:i + 2] if hs[i].get("paired") else hs[i:i + 1]  # a pair buys both gains together
        need = 0.0
        for h in group:
            assert h["first_seam"] is (count == max_islands)
            need += FIRST_SEAM_GAIN if h["first_seam"] else 0.02
            count += 1
        if not group[-1].get("after_quarter_turns"):  # (that one is judged against the quarter-turned layout)
            assert group[-1]["utilization"] >= before + need
        before, i = group[-1]["utilization"], i + len(group)
    assert s["islands"] == count


def test_layout_goal_without_islands_budget_never_halves():
    from texture.atlas_stages import layout_goal

    assert layout_goal(AtlasConfig(max_islands=0)).pack_max_cuts == 0
    assert layout_goal(AtlasConfig(max_islands=6)).pack_max_cuts > 0


def test_layout_islands_number_faces_and_vertices_over_the_pieces():
    """Each island of each prepared piece becomes one Island: its own faces and vertices, its
    chart as label, and face and vertex numbers running over the pieces in order."""
    from texture.atlas_stages import joined, layout_islands
    from texture.layouts import prepare
    from texture.trim import Piece

    g = grid_faces(5)
    t = np.linspace(0.0, 1.0, 5)
    u, v = np.meshgrid(t, t, indexing="xy")
    sq = np.column_stack([u.ravel(), v.ravel()])
    two = Piece(1, np.column_stack([np.concatenate([sq, sq + 3.0]), np.ones(50)]), np.concatenate([sq, sq + 3.0]),
                np.concatenate([g, g + 25]))  # two squares apart: two islands of chart 1
    one = Piece(0, np.column_stack([sq * 2.0, np.zeros(25)]), sq, g)
    layout = [prepare(one), prepare(two)]
    islands = layout_islands(layout)
    n = 3 * len(g)
    assert len(islands) == 3
    assert [isl.label for isl in islands] == [0, 1, 1]
    np.testing.assert_array_equal(np.sort(np.concatenate([isl.work_faces for isl in islands])), np.arange(n))
    pieces = [pp.piece for pp in layout]
    face_piece = np.repeat([0, 1], [len(p.faces) for p in pieces])
    face_local = np.concatenate([np.arange(len(p.faces)) for p in pieces])
    for isl in islands:  # every corner as in its piece
        for f, wf in zip(isl.faces, isl.work_faces):
            p = pieces[face_piece[wf]]
            np.testing.assert_array_equal(isl.xyz[f], p.xyz[p.faces[face_local[wf]]])
            np.testing.assert_array_equal(isl.uv[f], p.uv[p.faces[face_local[wf]]])
    m = joined(islands)
    assert len(m.faces) == n and m.island.max() == 2 and (np.bincount(m.chart) == [len(g), 2 * len(g)]).all()


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
