"""texture.relax: SLIM toward an isometry, one shared scale, no flips, no border crossings."""
from __future__ import annotations

import numpy as np
import pytest

from mnacore.grid import grid_faces
from texture.flatten import euler_characteristic
from texture.raster import coverage_count
from texture.relax import (
    RelaxConfig,
    boundary_edges,
    crossing_edges,
    energy_excess,
    holes_run_clockwise,
    is_injective,
    relax_island,
    relax_islands,
)
from texture.unwrap import UnwrapConfig
from texture.unwrap_islands import HoledRule, Island, _holed, audit_islands, overlaps_itself


def _signed_areas(uv, faces):
    t = uv[faces]
    return 0.5 * ((t[:, 1, 0] - t[:, 0, 0]) * (t[:, 2, 1] - t[:, 0, 1])
                  - (t[:, 1, 1] - t[:, 0, 1]) * (t[:, 2, 0] - t[:, 0, 0]))


def _edge_lengths(x, faces):
    return np.linalg.norm(x[np.roll(faces, -1, 1)] - x[faces], axis=-1).ravel()


def _cylinder(nu=25, nv=9, angle=np.pi, height=1.0):
    """Half cylinder of radius 1 as a grid; UV (theta, z): stretched around, exact along z."""
    th, z = np.meshgrid(np.linspace(0, angle, nu), np.linspace(0, height, nv), indexing="xy")
    xyz = np.column_stack([np.cos(th.ravel()), np.sin(th.ravel()), z.ravel()])
    return xyz, np.column_stack([th.ravel(), z.ravel()]), _grid(nu, nv)


def _grid(nu, nv):
    """Faces of an nu (x) by nv (y) vertex grid, counter-clockwise in (x, y)."""
    i, j = np.meshgrid(np.arange(nu - 1), np.arange(nv - 1), indexing="xy")
    a = (j * nu + i).ravel()
    return np.concatenate([np.column_stack([a, a + 1, a + nu + 1]), np.column_stack([a, a + nu + 1, a + nu])])


def test_stretched_cylinder_energy_matches_closed_form():
    # the flat triangles have chords, not arcs: around, a step dtheta in UV spans the chord
    # 2 sin(dtheta/2); with UV u = 0.3 theta the map UV -> 3D stretches by c = chord / (0.3 dtheta)
    nu = 25
    xyz, uv, faces = _cylinder(nu)
    dth = np.pi / (nu - 1)
    c = 2 * np.sin(dth / 2) / (0.3 * dth)
    uv = uv * [0.3, 1.0]
    # singular values c and 1 on every face: tr g + tr g^-1 - 4 = c^2 + 1/c^2 - 2
    assert energy_excess(xyz, uv, faces) == pytest.approx(c**2 + 1 / c**2 - 2, rel=1e-9)


@pytest.mark.parametrize("height", [1e-9, 2e-8, 1e-5])
@pytest.mark.parametrize("shear", [0.0, 0.3])
def test_energy_of_a_3d_sliver_matches_closed_form(height, shear):
    """A fair UV triangle on a 3D sliver of the given height: J's columns (1, 0, 0) and
    (1 + shear, height, 0) are nearly parallel, ``tr g = 1 + (1 + shear)^2 + height^2`` and
    ``det g = height^2``, so ``tr g^-1 = tr g / height^2``. ``E G - F^2`` cancels here (10 %
    off at 2e-8, infinite at 1e-9); the energy takes ``det g`` from the areas."""
    uv = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    xyz = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0 + shear, height, 0.0]])
    tr = 1.0 + (1.0 + shear) ** 2 + height**2
    closed = tr * (1.0 + 1.0 / height**2) - 4.0
    assert energy_excess(xyz, uv, np.array([[0, 1, 2]])) == pytest.approx(closed, rel=1e-9)


@pytest.mark.parametrize("mirrored", [False, True])
def test_relax_unrolls_a_developable_surface_isometrically(mirrored):
    xyz, uv, faces = _cylinder()
    uv = uv * [0.3, 1.0]  # 3.3x stretched around the cylinder
    if mirrored:  # a clockwise island must come back clockwise, and just as flat
        uv = uv * [-1.0, 1.0]
    r = relax_island(xyz, uv, faces, RelaxConfig(iterations=30, min_gain=1e-6))
    assert r.excess_before > 5.0 and r.excess_after < 1e-4 and not r.stopped_by_crossing
    # an unrolled cylinder: every UV edge as long as its 3D edge, areas equal, orientation kept
    np.testing.assert_allclose(_edge_lengths(r.uv, faces), _edge_lengths(xyz, faces), rtol=5e-3)
    sign = np.sign(_signed_areas(r.uv, faces))
    assert (sign == (-1 if mirrored else 1)).all()


def test_a_start_squeezed_below_the_degenerate_area_is_relaxed():
    """A flip-free start whose far faces are squeezed below ``DEGENERATE_UV_REL`` of the mean
    UV area (as Tutte's map squeezes the far end of a long, branching disk) has infinite
    energy excess; SLIM's iterates spread those faces out before its excess turns finite,
    and the half cylinder still unrolls isometrically (the first such iterate used to end
    the run, leaving the start)."""
    from texture.distortion_faces import DEGENERATE_UV_REL

    xyz, uv, faces = _cylinder(nu=41, nv=21)
    k = 11.0  # around the cylinder u = (1 - exp(-k theta)) / k: the faces at theta = pi shrink by exp(-k pi)
    uv = np.column_stack([(1 - np.exp(-k * uv[:, 0])) / k, uv[:, 1]])
    area = _signed_areas(uv, faces)
    assert (area > 0).all() and area.min() < DEGENERATE_UV_REL * area.mean()
    r = relax_island(xyz, uv, faces, RelaxConfig(iterations=300, min_gain=1e-6))
    assert np.isinf(r.excess_before) and r.excess_after < 1e-3
    np.testing.assert_allclose(_edge_lengths(r.uv, faces), _edge_lengths(xyz, faces), rtol=2e-2)
    assert (_signed_areas(r.uv, faces) > 0).all()


def test_islands_share_one_scale():
    """Two flat unit squares with UVs at scales 1 and 3: relaxed, both map at the *one* global
    isometric scale (UV area / 3D area = 1 / s^2 with s^2 = total 3D / total UV area = 2 / 10)."""
    g = 9
    lin = np.linspace(0, 1, g)
    x, y = np.meshgrid(lin, lin, indexing="xy")
    sq = np.column_stack([x.ravel(), y.ravel(), np.zeros(g * g)])
    xyz = np.concatenate([sq, sq + [2.0, 0, 0]])
    f = grid_faces(g)
    faces = np.concatenate([f, f + g * g])
    uv = np.concatenate([sq[:, :2], 3 * sq[:, :2] + [5.0, 0]])
    island = np.repeat([0, 1], len(f))
    out, stats = relax_islands(xyz, uv, faces, island, RelaxConfig(iterations=20, min_gain=1e-8))
    assert stats["islands"] == 2 and stats["energy_after"] < 1e-6
    ratio = np.abs(_signed_areas(out, faces)) / (0.5 / (g - 1) ** 2)
    np.testing.assert_allclose(ratio, 10 / 2, rtol=1e-4)


def _saddle_cone(nu=72, nv=8, a=0.5, r0=0.1, alpha=0.95):
    """A cone with a 3-fold saddle, z = a r sin(3 phi), cut open along phi = 0: developable, with
    a cone angle of about 1.25 turns, so its isometric flattening overlaps itself. Its UVs: the
    polar map with angles scaled by ``alpha`` (a slit open by 5 %, injective)."""
    ph, r = np.meshgrid(np.linspace(0, 2 * np.pi, nu), np.linspace(r0, 1.0, nv), indexing="xy")
    ph, r = ph.ravel(), r.ravel()
    xyz = np.column_stack([r * np.cos(ph), r * np.sin(ph), a * r * np.sin(3 * ph)])
    uv = np.column_stack([r * np.cos(alpha * ph), r * np.sin(alpha * ph)])
    return xyz, uv, _grid(nu, nv)


def _overlap_texels(uv, faces, res=400):
    t = uv[faces]
    lo, hi = t.reshape(-1, 2).min(0), t.reshape(-1, 2).max(0)
    return int((coverage_count((t - lo) / (hi - lo).max(), res, res) >= 2).sum())


def test_border_crossings_are_prevented():
    xyz, uv, faces = _saddle_cone()
    assert len(crossing_edges(faces, uv)) == 0 and _overlap_texels(uv, faces) == 0
    cfg = RelaxConfig(iterations=10, min_gain=1e-7)
    free = relax_island(xyz, uv, faces, cfg, check_crossings=False)
    # SLIM alone closes the slit and runs on: the flattened cone overlaps itself (rasterised too)
    assert len(crossing_edges(faces, free.uv)) > 0 and _overlap_texels(free.uv, faces) > 0
    kept = relax_island(xyz, uv, faces, cfg)
    assert len(crossing_edges(faces, kept.uv)) == 0 and _overlap_texels(kept.uv, faces) == 0
    assert kept.excess_after < 0.1 * kept.excess_before  # pinning the slit still lets the rest relax
    assert (np.sign(_signed_areas(kept.uv, faces)) == np.sign(_signed_areas(uv, faces))).all()


def _brute_force_crossings(edges, uv):
    count = 0
    for i in range(len(edges)):
        for j in range(i + 1, len(edges)):
            if set(edges[i]) & set(edges[j]):
                continue
            p, p2 = uv[edges[i, 0]], uv[edges[i, 1]]
            q, q2 = uv[edges[j, 0]], uv[edges[j, 1]]

            def side(a, b, c):
                return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])

            if side(p, p2, q) * side(p, p2, q2) <= 0 and side(q, q2, p) * side(q, q2, p2) <= 0:
                count += 1
    return count


def test_crossing_edges_match_brute_force():
    rng = np.random.default_rng(3)
    faces = np.arange(3 * 40).reshape(-1, 3)  # 40 separate triangles: every edge is a border edge
    centres = rng.uniform(0, 4, (40, 1, 2))
    uv = (centres + rng.uniform(-0.4, 0.4, (40, 3, 2))).reshape(-1, 2)
    got = len(crossing_edges(faces, uv))
    assert got == _brute_force_crossings(boundary_edges(faces), uv)
    assert got > 10  # the random soup does overlap


def test_crossing_edges_match_brute_force_across_edge_lengths():
    """Edges of lengths 0.01-3 (a soup of triangles of log-uniform sizes): every crossing of
    a long edge with a short one is found, though each edge looks only as far as its own
    length for edges no longer than itself."""
    rng = np.random.default_rng(5)
    n = 80
    faces = np.arange(3 * n).reshape(-1, 3)
    size = np.exp(rng.uniform(np.log(0.01), np.log(3.0), (n, 1, 1)))
    uv = (rng.uniform(0, 4, (n, 1, 2)) + size * rng.uniform(-1, 1, (n, 3, 2))).reshape(-1, 2)
    got = len(crossing_edges(faces, uv))
    assert got == _brute_force_crossings(boundary_edges(faces), uv)
    assert got > 10


def test_boundary_edges_of_a_grid():
    g = 6
    edges = boundary_edges(grid_faces(g))
    assert len(edges) == 4 * (g - 1)
    assert len(np.unique(edges)) == 4 * (g - 1)  # the border is one loop through 4 (g - 1) vertices


def test_meshes_relaxed_in_processes_match_one_by_one(monkeypatch):
    """relax_meshes runs all islands of several meshes in worker processes, largest first: the
    result is identical to relaxing them in this process, and each mesh keeps its own stats."""
    import texture.relax as R

    xyz_c, uv_c, f_c = _cylinder()
    xyz_s, uv_s, f_s = _saddle_cone(nu=36, nv=6)
    meshes = [(xyz_c, uv_c, f_c, None), (xyz_s, uv_s, f_s, np.zeros(len(f_s), np.int64))]
    cfg = RelaxConfig(iterations=5, min_gain=1e-8)
    serial = R.relax_meshes(meshes, cfg, scale=1.3, workers=1)
    import texture.parallel as P

    monkeypatch.setattr(P, "MIN_FACES", 0)
    parallel = R.relax_meshes(meshes, cfg, scale=1.3, workers=2)
    for (u1, s1), (u2, s2) in zip(serial, parallel):
        np.testing.assert_array_equal(u1, u2)
        assert s1 == s2 and s1["islands"] == 1
    assert serial[0][1]["energy_after"] < serial[0][1]["energy_before"]
    # one mesh through relax_islands at the same scale gives the same UVs as in the batch
    alone, _ = relax_islands(xyz_c, uv_c, f_c, None, cfg, scale=1.3)
    np.testing.assert_array_equal(alone, serial[0][0])


def test_unguarded_run_keeps_its_best_valid_iterate_and_relax_disk_continues_from_it():
    """The saddle cone's free SLIM ends overlapping itself; the run still reports its best
    iterate without flips or border crossings, and relax_disk's guarded run continues from it
    to a crossing-free, flip-free map at a twentieth of the start's energy."""
    from texture.flatten import relax_disk

    xyz, uv, faces = _saddle_cone()
    uv = uv * [1.0, -1.0]  # counter-clockwise, as relax_disk's Tutte starts are
    assert (_signed_areas(uv, faces) > 0).all()
    cfg = RelaxConfig(iterations=40, min_gain=1e-7)
    free = relax_island(xyz, uv, faces, cfg, check_crossings=False)
    assert len(crossing_edges(faces, free.uv)) > 0
    assert free.valid_uv is not None
    assert len(crossing_edges(faces, free.valid_uv)) == 0 and (_signed_areas(free.valid_uv, faces) > 0).all()
    assert free.valid_excess == pytest.approx(energy_excess(xyz, free.valid_uv, faces), rel=1e-12)
    assert free.valid_excess < 0.1 * free.excess_before
    out, st = relax_disk(xyz, uv, faces, cfg)
    assert st["mode"] == "guarded"
    assert len(crossing_edges(faces, out)) == 0 and _overlap_texels(out, faces) == 0
    assert (_signed_areas(out, faces) > 0).all()
    assert energy_excess(xyz, out, faces) <= free.valid_excess < free.excess_before / 18


def _flap_annulus(h=0.5):
    """A 4 x 4 square (grid step ``h``) slit along y = 2 from x = 1 to 3, with a 2 x 1 flap
    glued to the slit's lower lip and lying over the square (tilted up in 3D): an annulus
    (one hole: the upper lip and the flap's free sides) whose identity map (x, y) flips no
    face and whose border crosses nowhere, yet covers the flap's rectangle twice: its hole
    loop runs counter-clockwise."""
    n = int(round(4 / h)) + 1
    x, y = np.meshgrid(np.arange(n) * h, np.arange(n) * h, indexing="xy")
    pts = [np.column_stack([x.ravel(), y.ravel(), np.zeros(n * n)])]
    faces = _grid(n, n)
    idx = lambda i, j: j * n + i  # noqa: E731
    j0, i0, i1 = int(round(2 / h)), int(round(1 / h)), int(round(3 / h))
    # the upper lip: faces above the slit take copies of the slit's inner vertices
    inner = [idx(i, j0) for i in range(i0 + 1, i1)]
    copy = {v: n * n + k for k, v in enumerate(inner)}
    pts.append(pts[0][inner])
    cy = pts[0][faces][:, :, 1].mean(1)
    cx = pts[0][faces][:, :, 0].mean(1)
    above = (cy > 2) & (cy < 2 + h) & (cx > 1) & (cx < 3)
    faces[above] = np.vectorize(lambda v: copy.get(v, v))(faces[above])
    # the flap: a grid over [1, 3] x [2, 3], its bottom row the slit's (lower lip) vertices
    fu, fv = i1 - i0 + 1, int(round(1 / h)) + 1
    base = sum(len(p) for p in pts)
    fx, fy = np.meshgrid(1 + np.arange(fu) * h, 2 + np.arange(fv) * h, indexing="xy")
    pts.append(np.column_stack([fx.ravel(), fy.ravel(), 0.3 * (fy.ravel() - 2)]))
    flap = _grid(fu, fv) + base
    ids = np.arange(base, base + fu * fv)
    ids[:fu] = [idx(i, j0) for i in range(i0, i1 + 1)]
    flap = ids[flap - base]
    xyz = np.concatenate(pts)
    keep = np.unique(np.concatenate([faces.ravel(), flap.ravel()]))
    remap = np.full(len(xyz), -1)
    remap[keep] = np.arange(len(keep))
    f = remap[np.concatenate([faces, flap])]
    return xyz[keep], f


def test_hole_running_counter_clockwise_is_an_overlap_flips_and_crossings_miss():

    xyz, faces = _flap_annulus()
    uv = xyz[:, :2]
    assert euler_characteristic(faces) == 0 and len(np.unique(boundary_edges(faces)[:, 0])) == len(boundary_edges(faces))
    assert (_signed_areas(uv, faces) > 0).all() and len(crossing_edges(faces, uv)) == 0
    # rasterised: the flap's 2 x 1 rectangle is covered twice, 1/8 of the 4 x 4 square
    assert _overlap_texels(uv / 4.0, faces, 256) == pytest.approx(256 * 256 / 8, rel=0.05)
    assert not holes_run_clockwise(uv, faces) and not is_injective(uv, faces)
    # the same square with a real hole (the flap's rectangle cut out): injective
    keep = ~((uv[faces].mean(1)[:, 0] > 1) & (uv[faces].mean(1)[:, 0] < 3)
             & (uv[faces].mean(1)[:, 1] > 2) & (uv[faces].mean(1)[:, 1] < 3))
    holed = faces[keep]
    assert holes_run_clockwise(uv, holed) and is_injective(uv, holed) and _overlap_texels(uv / 4.0, holed, 256) == 0


def test_a_holed_region_whose_conformal_map_laps_over_a_hole_is_cut_instead():

    xyz, faces = _flap_annulus()
    rule = HoledRule(within=10.0, relax=RelaxConfig(iterations=0), max_faces=10**6)
    uv = _holed(xyz, faces, rule)
    assert uv is None or _overlap_texels((uv - uv.min(0)) / np.ptp(uv, 0).max(), faces, 256) == 0
    # a plain holed plate keeps its uncut map
    keep = ~((xyz[faces].mean(1)[:, 0] > 1) & (xyz[faces].mean(1)[:, 0] < 3)
             & (xyz[faces].mean(1)[:, 1] > 2) & (xyz[faces].mean(1)[:, 1] < 3))
    plate = faces[keep]
    used = np.unique(plate)
    remap = np.full(len(xyz), -1)
    remap[used] = np.arange(len(used))
    assert _holed(xyz[used], remap[plate], rule) is not None


def test_the_audit_flattens_again_an_island_that_overlaps_itself():

    xyz, faces = _flap_annulus()
    lapped = Island(faces, xyz[:, :2].copy(), xyz, np.arange(len(faces)), np.arange(len(xyz)), 0)
    keep = ~((xyz[faces].mean(1)[:, 0] > 1) & (xyz[faces].mean(1)[:, 0] < 3)
             & (xyz[faces].mean(1)[:, 1] > 2) & (xyz[faces].mean(1)[:, 1] < 3))
    fine = Island(faces[keep], xyz[:, :2].copy(), xyz, np.flatnonzero(keep), np.arange(len(xyz)), 1)
    assert overlaps_itself(lapped) and not overlaps_itself(fine)
    out, stats = audit_islands([fine, lapped], xyz, faces, UnwrapConfig())
    assert stats == {"reflattened": 1, "reflatten_failed": 0}
    assert out[0] is fine  # left as it was
    new = out[1:]
    # the lapped island's faces, each once, now flattened without overlap (rasterised too)
    assert sorted(np.concatenate([i.work_faces for i in new]).tolist()) == list(range(len(faces)))
    for isl in new:
        assert not overlaps_itself(isl) and _overlap_texels(isl.uv, isl.faces, 256) == 0
        # at the isometric scale, as every island: UV area = 3D area (within SLIM's tolerance)
        assert _signed_areas(isl.uv, isl.faces).sum() == pytest.approx(
            0.5 * np.linalg.norm(np.cross(isl.xyz[isl.faces[:, 1]] - isl.xyz[isl.faces[:, 0]],
                                          isl.xyz[isl.faces[:, 2]] - isl.xyz[isl.faces[:, 0]]), axis=1).sum(), rel=0.05)
