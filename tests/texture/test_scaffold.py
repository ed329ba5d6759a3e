"""Relaxing disks whose free optimum overlaps itself (texture.scaffold) and starts squeezed
to near nothing (texture.relax)."""
from dataclasses import replace

import igl
import numpy as np
import pytest

from mnacore.triangles import signed_areas, triangle_areas
from texture.flatten import _cut_flags, is_disk, relax_disk, start_map
from texture.relax import RelaxConfig, energy_excess, is_injective, relax_island
from texture.scaffold import relax_scaffold

CFG = RelaxConfig(iterations=200, min_gain=1e-4, scaffold_above=0.1)


def _grid(nx, ny, sx, sy, height=None):
    xs, ys = np.linspace(0, sx, nx + 1), np.linspace(0, sy, ny + 1)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    Z = np.zeros_like(X) if height is None else height(X, Y)
    pts = np.stack([X, Y, Z], -1).reshape(-1, 3)
    idx = np.arange(len(pts)).reshape(nx + 1, ny + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel()
    return pts, np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)]), idx


def _angle_sum(p, faces, v):
    total = 0.0
    for tri in faces[(faces == v).any(1)]:
        j = list(tri).index(v)
        a, b = p[tri[(j + 1) % 3]] - p[v], p[tri[(j + 2) % 3]] - p[v]
        total += np.arccos(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1, 1))
    return total


def _slit_egg_crate(amplitude=0.2, slits=5):
    """A 4 x 2 egg crate (z = A sin 2 pi x sin 2 pi y, 2,304 faces) slit open from its lower
    border up to ``slits`` of its saddle points (x a multiple of 1/2, y = 1): each slit's
    tip is a border vertex whose faces span more than a full turn, so the isometric map
    laps over itself at every tip."""
    nx, ny = 48, 24
    p, f, idx = _grid(nx, ny, 4.0, 2.0, lambda X, Y: amplitude * np.sin(2 * np.pi * X) * np.sin(2 * np.pi * Y))
    cuts = [[int(idx[int(round((0.5 + 0.5 * s) * nx / 4)), j]) for j in range(ny // 2 + 1)] for s in range(slits)]
    tips = [c[-1] for c in cuts]
    _, nf, src = igl.cut_mesh(p, f, _cut_flags(f, cuts))
    src = np.asarray(src, np.int64)
    nf = np.asarray(nf, np.int64)
    return p[src], nf, [int(np.flatnonzero(src == t)[0]) for t in tips]


def test_a_disk_whose_free_optimum_laps_over_relaxes_without_overlap_near_that_optimum():
    xyz, faces, tips = _slit_egg_crate()
    assert is_disk(faces)
    # the property the test rests on: every slit tip spans more than a full turn in 3D
    assert all(_angle_sum(xyz, faces, t) > 2.05 * np.pi for t in tips)
    uv0 = start_map(xyz, faces)
    uv0 *= np.sqrt(triangle_areas(xyz, faces).sum() / signed_areas(uv0, faces).sum())
    free = relax_island(xyz, uv0, faces, CFG, check_crossings=False)
    assert not is_injective(free.uv, faces)  # the unconstrained optimum overlaps itself
    uv, stats = relax_disk(xyz, uv0, faces, CFG)
    assert is_injective(uv, faces) and stats["mode"] == "scaffold"
    # the best map that does not overlap is near the free optimum (it differs only around
    # the five tips); the guarded run from the start stalls at 0.50 against 0.077 here
    assert stats["excess"] == pytest.approx(energy_excess(xyz, uv, faces))
    assert free.excess_after <= stats["excess"] <= 1.15 * free.excess_after
    # with the scaffold off (merge trials), the guarded run alone: injective, far above
    guarded, st = relax_disk(xyz, uv0, faces, replace(CFG, scaffold_above=0.0))
    assert st["mode"] == "guarded" and is_injective(guarded, faces)
    assert st["excess"] > 3 * stats["excess"]


def test_the_guard_is_left_out_where_its_start_is_far_from_relaxed(monkeypatch):
    """The guarded run continues from the free run's best crossing-free iterate; where that
    is more than GUARD_START_RATIO times the free result's excess, the scaffold runs alone."""
    import texture.relax as R
    from texture.flatten import GUARD_START_RATIO

    xyz, faces, _ = _slit_egg_crate()
    uv0 = start_map(xyz, faces)
    uv0 *= np.sqrt(triangle_areas(xyz, faces).sum() / signed_areas(uv0, faces).sum())
    uv0 *= np.array([3.0, 1.0 / 3.0])  # stretched (an affine map: still flip-free), excess ~21
    # a real crossing-free map between it and relaxed: one guarded iteration from it
    early = relax_island(xyz, uv0, faces, replace(CFG, iterations=1), check_crossings=True)
    assert is_injective(early.uv, faces)
    real, guarded_calls = R.relax_island, []

    def spy(x, u, f, cfg, check_crossings=True, fixed=None):
        got = real(x, u, f, cfg, check_crossings=check_crossings, fixed=fixed)
        if check_crossings:
            guarded_calls.append(len(f))
        else:  # as if the free run had passed that map on its way (after its start)
            got.valid_uv, got.valid_excess = early.uv, early.excess_after
        return got

    monkeypatch.setattr(R, "relax_island", spy)
    free = real(xyz, uv0, faces, CFG, check_crossings=False)
    # the case the rule rests on: that iterate is far above the free result, below the start
    assert GUARD_START_RATIO * free.excess_after < early.excess_after < free.excess_before
    uv, stats = relax_disk(xyz, uv0, faces, CFG)
    assert guarded_calls == [] and stats["mode"] == "scaffold" and is_injective(uv, faces)
    assert free.excess_after <= stats["excess"] <= 1.15 * free.excess_after


def test_scaffold_is_scale_free_and_keeps_the_scale_of_its_input():
    xyz, faces, _ = _slit_egg_crate(amplitude=0.3, slits=2)
    uv0 = start_map(xyz, faces)
    results = []
    # SCAF's scaffold mesher works in absolute units (an island of area 0.13 gave NaN, then
    # hung): each island is solved at unit area, so 1e-3 and 1e3 give the same map
    for s in (1e-3, 1.0, 1e3):
        uv, iters, excess = relax_scaffold(xyz * s, uv0 * s, faces, 200, 1e-4)
        assert is_injective(uv, faces)
        assert excess == pytest.approx(energy_excess(xyz * s, uv, faces), rel=1e-9)
        results.append((uv / s, iters, excess))
    e = [r[2] for r in results]
    assert e[0] < 0.5 * energy_excess(xyz, uv0 * np.sqrt(triangle_areas(xyz, faces).sum() / signed_areas(uv0, faces).sum()), faces)
    assert e[0] == pytest.approx(e[1], rel=1e-3) and e[2] == pytest.approx(e[1], rel=1e-3)
    assert np.abs(results[0][0] - results[1][0]).max() < 1e-3 * np.ptp(results[1][0])


def test_scaffold_refuses_a_start_that_overlaps():
    xyz, faces, _ = _slit_egg_crate(slits=1)
    uv0 = start_map(xyz, faces)
    flipped = uv0.copy()
    flipped[faces[0]] = flipped[faces[0][[0, 2, 1]]]  # two corners swapped: that face turns over
    assert not is_injective(flipped, faces)
    assert relax_scaffold(xyz, flipped, faces, 50, 1e-4) is None


def test_a_start_squeezed_to_near_nothing_is_relaxed():
    """A start whose faces all keep some area but one only 1e-12 of the mean (a Tutte map of a
    long, branching disk squeezes its far faces so) has infinite energy excess by
    :func:`texture.relax.energy_excess`; SLIM still runs from it and finds the isometry of a
    flat square (it used to return the start unchanged)."""
    xyz, faces, idx = _grid(10, 10, 3.0, 3.0)
    uv = xyz[:, :2].copy()
    v = int(idx[5, 5])
    f = int(np.flatnonzero((faces == v).any(1))[0])
    a, b = (u for u in faces[f] if u != v)
    # v onto the segment ab, 1e-12 of an edge inside: its face keeps 1e-12 of its area
    foot = 0.5 * (uv[a] + uv[b])
    uv[v] = foot + 1e-12 * (uv[v] - foot) / np.linalg.norm(uv[v] - foot)
    signed = signed_areas(uv, faces)
    assert (signed > 0).all() and signed.min() < 1e-10 * signed.mean()
    assert not np.isfinite(energy_excess(xyz, uv, faces))
    out = relax_island(xyz, uv, faces, CFG, check_crossings=True)
    assert np.isfinite(out.excess_after) and out.excess_after < 1e-3
    assert is_injective(out.uv, faces)
    # the isometry of the square: edge lengths kept
    e = faces[:, [0, 1]]
    assert np.allclose(np.linalg.norm(out.uv[e[:, 0]] - out.uv[e[:, 1]], axis=1),
                       np.linalg.norm(xyz[e[:, 0]] - xyz[e[:, 1]], axis=1), rtol=2e-2)
