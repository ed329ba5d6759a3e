"""The UV-metrics harness: closed forms, a naive per-face loop, invariants, an analytic chart."""
from __future__ import annotations

import numpy as np
import pytest
from texture_helpers import cap_chart

from mnacore import distortion as D
from mnacore.grid import grid_faces
from mnacore.uvmesh import from_corners, make_uv_mesh
from texture.clip import clip_mesh
from texture.harness import measure, per_face_distortions, uv_islands

SQUARE_V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.0]])
SQUARE_F = np.array([[0, 1, 2], [0, 2, 3]])
SQUARE_UV = SQUARE_V[:, :2].copy()


def test_flat_square_identity_uv_has_zero_distortion():
    m = measure(make_uv_mesh(SQUARE_V, SQUARE_F, SQUARE_UV))
    s = m.summary
    # metric: only the SSDE's eps (1e-4) keeps it from exactly 0
    assert s["distortion_metric"] == pytest.approx(0.0, abs=2e-4)
    assert s["distortion_conformal"] == pytest.approx(0.0, abs=1e-9)
    assert s["distortion_area"] == pytest.approx(0.0, abs=1e-9)
    assert s["charts"] == 1 and s["flipped_faces"] == 0 and s["folded_faces"] == 0
    assert s["seam_length"] == 0.0
    assert s["texel_density_cv"] == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("sx, sy, metric, conformal", [(2.0, 1.0, 1.0, 0.5), (1.0, 3.0, 2 * np.sqrt(10 * 10 / 9) - 4, 10 / 3 - 2),
                                                      (5.0, 5.0, 0.0, 0.0)])
def test_affine_stretch_closed_form(sx, sy, metric, conformal):
    # J = diag(sx, sy): tr g = sx^2 + sy^2, tr g^-1 = 1/sx^2 + 1/sy^2, MIPS = (sx^2 + sy^2)/(sx sy) - 2
    V = SQUARE_V * [sx, sy, 1]
    d = per_face_distortions(V, SQUARE_F, SQUARE_UV)
    np.testing.assert_allclose(d["metric"], metric, atol=5e-4)
    np.testing.assert_allclose(d["conformal"], conformal, atol=1e-9)
    np.testing.assert_allclose(d["area"], 0.0, atol=1e-9)
    s = measure(make_uv_mesh(V, SQUARE_F, SQUARE_UV)).summary
    assert s["distortion_metric"] == pytest.approx(metric, abs=5e-4)
    assert s["distortion_conformal_3d"] == pytest.approx(conformal, abs=1e-9)


def _naive(vertices, faces, uv):
    """Per-face loop: J from two edge equations, g, then the DESIGN aggregates by hand."""
    used = vertices[np.unique(faces)]  # unit ball of the vertices the faces use
    center = 0.5 * (used.min(0) + used.max(0))
    V = (vertices - center) / np.linalg.norm(used - center, axis=1).max()
    J, w, a3 = [], [], []
    for f in faces:
        p0, p1, p2 = V[f]
        t0, t1, t2 = uv[f]
        Dm = np.array([t1 - t0, t2 - t0]).T
        P = np.array([p1 - p0, p2 - p0]).T
        J.append(P @ np.linalg.inv(Dm))
        w.append(abs(np.linalg.det(Dm)) / 2)
        a3.append(np.linalg.norm(np.cross(p1 - p0, p2 - p0)) / 2)
    J, w, a3 = np.array(J), np.array(w), np.array(a3)
    s = np.sqrt(a3.sum() / w.sum())  # harness: UVs rescaled to equal total area
    out = {"metric": [], "conformal": [], "area": []}
    tr, tri, A = [], [], []
    for Jf in J:
        g = (Jf * s).T @ (Jf * s)
        gh = g + D.SSDE_EPS * np.eye(2)
        tr.append(np.trace(gh))
        tri.append(np.trace(np.linalg.inv(gh)))
        out["conformal"].append(np.trace(g) / np.sqrt(np.linalg.det(g) + D.AREA_EPS) - 2)
        A.append(np.sqrt(max(np.linalg.det(g), 0)) + D.AREA_EPS)
    tr, tri, A = map(np.array, (tr, tri, A))
    metric = 2 * np.sqrt((tr * w).sum() / w.sum() * (tri * w).sum() / w.sum()) - 4
    area = 2 * np.sqrt((A * w).sum() / w.sum() * (w / A).sum() / w.sum()) - 2
    conformal = (np.array(out["conformal"]) * w).sum() / w.sum()
    return metric, conformal, area, np.array(out["conformal"])


def test_harness_matches_naive_loop(icosphere):
    rng = np.random.default_rng(3)
    V = np.asarray(icosphere.vertices) * [1.0, 0.7, 1.3] + 2.0
    F = np.asarray(icosphere.faces)
    uv = np.column_stack([np.arctan2(V[:, 1] - 2, V[:, 0] - 2), V[:, 2]]) + 0.01 * rng.standard_normal((len(V), 2))
    keep = np.abs(V[F, 2] - 2).max(1) < 1.1  # away from the poles: a valid (non-wrapping) chart
    keep &= np.ptp(uv[F, 0], axis=1) < 1.0
    F = F[keep]
    metric, conformal, area, conformal_f = _naive(V, F, uv)
    m = measure(make_uv_mesh(V, F, uv))
    assert m.summary["distortion_metric"] == pytest.approx(metric, rel=1e-9)
    assert m.summary["distortion_conformal"] == pytest.approx(conformal, rel=1e-9)
    assert m.summary["distortion_area"] == pytest.approx(area, rel=1e-9)
    np.testing.assert_allclose(m.conformal, conformal_f, rtol=1e-9)
    # per-face decomposition averages back to the aggregate (UV-area weights)
    w = m.uv_area
    assert (m.metric * w).sum() / w.sum() == pytest.approx(metric, rel=1e-9)
    assert (m.area * w).sum() / w.sum() == pytest.approx(area, rel=1e-9)


def test_uv_islands_connect_by_uv_edges_not_indices():
    assert uv_islands(SQUARE_F, SQUARE_UV).tolist() == [0, 0]
    # duplicate the shared vertices at the same UV: still one island
    V2 = np.concatenate([SQUARE_V, SQUARE_V[[0, 2]]])
    uv2 = np.concatenate([SQUARE_UV, SQUARE_UV[[0, 2]]])
    F2 = np.array([[0, 1, 2], [4, 5, 3]])
    assert uv_islands(F2, uv2).tolist() == [0, 0]
    # move the copies in UV: a seam along the diagonal, two islands
    uv3 = uv2.copy()
    uv3[4:] += [0.0, 0.5]
    assert uv_islands(F2, uv3).tolist() == [0, 1]
    m = measure(make_uv_mesh(V2, F2, uv3 * 0.5))
    assert m.summary["charts"] == 2
    # seam = the diagonal, sqrt(2), over sqrt(area 1); open borders of the sheet are not seams
    assert m.summary["seam_length"] == pytest.approx(np.sqrt(2), rel=1e-12)


def test_from_corners_splits_seam_vertices():
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.2, 0.2], [0.4, 0.4]])
    uvf = np.array([[0, 1, 2], [4, 5, 3]])
    m = from_corners(SQUARE_V, SQUARE_F, uv, uvf)
    assert len(m.vertices) == 6  # vertices 0 and 2 split on the seam
    np.testing.assert_allclose(m.uv[m.faces], uv[uvf])
    np.testing.assert_allclose(m.vertices[m.faces], SQUARE_V[SQUARE_F])


def _sheet(n=6):
    lin = np.linspace(0, 1, n)
    x, y = np.meshgrid(lin, lin, indexing="xy")
    V = np.column_stack([x.ravel(), y.ravel(), np.zeros(n * n)])
    return V, grid_faces(n)


def test_flipped_faces_count_reversed_uv_triangles():
    V, F = _sheet()
    F = F.copy()
    F[[3, 10]] = F[[3, 10]][:, ::-1]  # reversed winding: UV and 3D orientation both flip
    m = measure(make_uv_mesh(V, F, V[:, :2]))
    assert m.summary["flipped_faces"] == 2
    assert sorted(np.flatnonzero(m.flipped)) == [3, 10]
    assert m.summary["flipped_area_percent"] == pytest.approx(100 * 2 / len(F), rel=1e-9)


def test_folded_faces_against_reference_normals():
    import trimesh

    V, F = _sheet(7)
    Vf = V.copy()
    c = 3 * 7 + 3  # an interior vertex pushed across its right neighbours: the surface folds over
    Vf[c, 0] += 0.25
    n = np.cross(Vf[F[:, 1]] - Vf[F[:, 0]], Vf[F[:, 2]] - Vf[F[:, 0]])[:, 2]
    expected = int((n < 0).sum())
    assert expected > 0
    ref = trimesh.Trimesh(V, F, process=False)
    m = measure(make_uv_mesh(Vf, F, V[:, :2]), reference=ref)
    assert m.summary["folded_faces"] == expected
    assert m.summary["flipped_faces"] == 0  # the UVs do not flip, only the surface folds
    assert m.summary["uv_overlap_percent"] == 0.0


def test_overlap_and_utilization():
    F = np.concatenate([SQUARE_F, SQUARE_F + 4])
    V = np.concatenate([SQUARE_V, SQUARE_V + [2, 0, 0]])
    uv = np.concatenate([SQUARE_UV, SQUARE_UV]) * 0.5  # two islands on the same UV square
    s = measure(make_uv_mesh(V, F, uv), resolution=256).summary
    assert s["charts"] == 2
    assert s["uv_overlap_percent"] == pytest.approx(100.0, abs=1.0)
    assert s["utilization"] == pytest.approx(0.25, abs=2 / 256)
    uv2 = uv.copy()
    uv2[4:] += [0.5, 0.5]
    s2 = measure(make_uv_mesh(V, F, uv2), resolution=256).summary
    assert s2["uv_overlap_percent"] == 0.0
    assert s2["utilization"] == pytest.approx(0.5, abs=4 / 256)


def _analytic_cap(theta_max):
    """DESIGN distortions of the azimuthal-equidistant cap over its disc domain (quadrature)."""
    r = (np.arange(200000) + 0.5) / 200000
    w = 2 * r  # uniform on the unit disc
    th = r * theta_max
    a = np.full_like(r, theta_max)  # radial stretch
    b = theta_max * np.sin(th) / th  # tangential stretch
    E = lambda f: (f * w).mean() / w.mean()  # noqa: E731
    metric = 2 * np.sqrt(E(a**2 + b**2) * E(1 / a**2 + 1 / b**2)) - 4
    conformal = E(a / b + b / a) - 2
    area = 2 * np.sqrt(E(a * b) * E(1 / (a * b))) - 2
    return metric, conformal, area


def test_discrete_harness_matches_analytic_chart_within_5_percent():
    theta_max = np.radians(100)
    G = 161
    uv, xyz, occ = cap_chart(G, theta_max, (0, 0, 1))
    c = clip_mesh(np.column_stack([xyz.reshape(-1, 3), uv.reshape(-1, 2)]), grid_faces(G), occ.reshape(-1) - 0.5)
    mesh = make_uv_mesh(c.attrs[:, :3], c.faces, c.attrs[:, 3:])
    s = measure(mesh, resolution=64).summary
    metric, conformal, area = _analytic_cap(theta_max)
    assert s["distortion_metric"] == pytest.approx(metric, rel=0.05)
    assert s["distortion_conformal"] == pytest.approx(conformal, rel=0.05)
    assert s["distortion_area"] == pytest.approx(area, rel=0.05)
    assert s["charts"] == 1 and s["flipped_faces"] == 0


def test_xatlas_on_sphere_has_no_flips_or_overlap(icosphere):
    from texture.xatlas_uv import XatlasOptions, unwrap

    res = unwrap(icosphere.vertices, icosphere.faces, XatlasOptions(resolution=512, padding=2))
    s = measure(res.mesh, reference=icosphere, resolution=512).summary
    assert s["flipped_faces"] == 0 and s["folded_faces"] == 0
    assert s["uv_overlap_percent"] < 0.1  # texel centres on shared padding-free borders only
    assert s["uv_inside_unit_square"] and s["charts"] == res.charts
    assert 0.0 < s["distortion_metric"] < 0.5
    # the welded mesh is closed: every UV border is a seam, none is a surface boundary
    assert s["seam_length"] > 0
    np.testing.assert_allclose(res.mesh.vertices, np.asarray(icosphere.vertices)[res.vmapping])


def _stacked_boxes():
    """Two unit cubes, the second on top of the first: the lower one's top face and the
    upper one's bottom face lie on each other, with opposite normals (touching parts)."""
    import trimesh

    box = trimesh.creation.box((1.0, 1.0, 1.0))
    V = np.concatenate([box.vertices, box.vertices + [0.0, 0.0, 1.0]])
    F = np.concatenate([box.faces, box.faces + len(box.vertices)])
    return V, F, trimesh.Trimesh(V, F, process=False)


def test_touching_parts_measured_against_themselves_have_no_folds():
    V, F, ref = _stacked_boxes()
    # UVs: each face its own right triangle (one island per face pair is not needed here)
    m = measure(make_uv_mesh(V, F, V[:, :2] + 0.1 * V[:, 2:]), reference=ref)
    assert m.summary["folded_faces"] == 0
    # the touching faces (4 of 24, area 2 of 12) are the only ones that can be undecided
    assert m.summary["orientation_undecided_area_percent"] <= 100 * 2 / 12 + 1e-9
    # a really inverted face is still folded: the upper cube's top, one triangle reversed
    top = np.flatnonzero(np.isclose(V[F][:, :, 2], 1.5).all(1))
    assert len(top) == 2
    F2 = F.copy()
    F2[top[0]] = F2[top[0], ::-1]
    m2 = measure(make_uv_mesh(V, F2, V[:, :2] + 0.1 * V[:, 2:]), reference=ref)
    assert np.flatnonzero(m2.folded).tolist() == [top[0]]
    assert m2.summary["folded_area_percent"] == pytest.approx(100 * 0.5 / 12, rel=1e-9)


def test_thin_plate_sheet_between_its_sides_is_undecided_not_folded():
    import trimesh

    V, F = _sheet(9)
    V = V - [0.5, 0.5, 0.0]
    centre = np.linalg.norm(V[F].mean(1)[:, :2], axis=1) < 0.2
    F = np.where(centre[:, None], F[:, ::-1], F)  # a patch facing down in a sheet facing up
    area = 0.5 / 64 * centre.sum()
    # over a plate 0.01 thick (its two sides well within FOLD_TOL of each other), a hair above
    # its mid-plane: the closest side is the top, but the bottom faces the patch's way
    plate = trimesh.creation.box((1.0, 1.0, 0.01))
    m = measure(make_uv_mesh(V + [0, 0, 0.001], F, V[:, :2]), reference=plate)
    assert m.summary["folded_faces"] == 0
    assert m.summary["orientation_undecided_area_percent"] == pytest.approx(100 * area, rel=1e-9)
    # on a block 0.4 thick nothing near faces the patch's way: folded
    block = trimesh.creation.box((1.0, 1.0, 0.4))
    m = measure(make_uv_mesh(V + [0, 0, 0.201], F, V[:, :2]), reference=block)
    assert np.array_equal(m.folded, centre)
    assert m.summary["folded_area_percent"] == pytest.approx(100 * area, rel=1e-9)
    assert m.summary["orientation_undecided_area_percent"] == 0.0


def test_a_face_parked_on_one_uv_point_is_not_a_chart():
    """Two charts (the square's halves moved apart) plus a face whose three corners share one
    UV point: it covers no texel and carries no texture, so 2 charts and 1 point chart."""
    V = np.concatenate([SQUARE_V, SQUARE_V[[0, 2]], SQUARE_V[[0, 1, 3]]])
    uv = np.concatenate([SQUARE_UV, SQUARE_UV[[0, 2]] + [0.0, 0.5], np.full((3, 2), 0.25)]) * 0.5
    F = np.array([[0, 1, 2], [4, 5, 3], [6, 7, 8]])
    s = measure(make_uv_mesh(V, F, uv)).summary
    assert s["charts"] == 2 and s["point_charts"] == 1
    s2 = measure(make_uv_mesh(V[:6], F[:2], uv[:6])).summary
    assert s2["charts"] == 2 and s2["point_charts"] == 0


def _cards(n: int, seed: int = 0):
    """``n`` separate small squares (two triangles each) at random places and turns: many
    small charts, where xatlas's own scale overshoots the resolution asked for."""
    import trimesh

    rng = np.random.default_rng(seed)
    quads = []
    for _ in range(n):
        q = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]], process=False)
        q.apply_scale(rng.uniform(0.05, 0.15))
        q.apply_transform(trimesh.transformations.random_rotation_matrix(rng.random(3)))
        q.apply_translation(rng.normal(size=3))
        quads.append(q)
    m = trimesh.util.concatenate(quads)
    return np.asarray(m.vertices), np.asarray(m.faces)


def _gap(res, size: int) -> float:
    """Smallest distance (texels of a ``size`` texture) between vertices of two islands."""
    from scipy.spatial import cKDTree

    from texture.harness import uv_islands

    px = res.mesh.uv * size
    island = uv_islands(res.mesh.faces, res.mesh.uv)
    of_vertex = np.zeros(len(px), np.int64)
    of_vertex[res.mesh.faces.ravel()] = np.repeat(island, 3)
    pairs = cKDTree(px).query_pairs(r=32.0, output_type="ndarray")
    apart = of_vertex[pairs[:, 0]] != of_vertex[pairs[:, 1]]
    return float(np.linalg.norm(px[pairs[apart, 0]] - px[pairs[apart, 1]], axis=1).min())


def test_xatlas_is_held_to_the_resolution_asked_for(monkeypatch):
    """xatlas's own scale leaves its gutters out of its estimate: asked for 1024 texels and
    8-texel gutters on 1,000 small charts its atlas is about 1,520 wide, so in the 1024-texel
    texture its gutters would be 2/3 as wide as asked; on 300 charts asked for 2048 it is
    about 1,280 wide, a third of the texture's width unused. Held: exactly the resolution,
    the same charts and seams, charts at least 2 x 8 texels apart in that texture (8 around
    each), and the texture used as far as one atlas allows."""
    import texture.xatlas_uv as X

    for n, size, grows in ((1000, 1024, False), (300, 2048, True)):
        V, F = _cards(n)
        opts = X.XatlasOptions(resolution=size, padding=8)
        held = X.unwrap(V, F, opts)
        with monkeypatch.context() as m:
            m.setattr(X, "HOLD_TRIES", 0)
            own = X.unwrap(V, F, opts)
        assert (max(own.atlas_size) < 0.75 * size) if grows else (max(own.atlas_size) > 1.3 * size)  # the case
        assert held.atlas_size == (size, size) and held.calls >= 3 and held.seconds_total > held.seconds
        assert held.charts == own.charts == n
        s_held, s_own = measure(held.mesh).summary, measure(own.mesh).summary
        assert s_held["charts"] == n and s_held["seam_length"] == pytest.approx(s_own["seam_length"], abs=1e-9)
        assert s_held["uv_overlap_percent"] == 0.0 and s_held["uv_inside_unit_square"]
        assert _gap(held, size) >= 2 * 8
        if grows:
            assert s_held["utilization"] > 1.1 * s_own["utilization"]
        else:
            assert _gap(own, size) < 2 * 8
