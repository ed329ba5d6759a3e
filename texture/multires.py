"""Flatten a large disk in two resolutions: SLIM on a coarse copy, ARAP on the whole.

SLIM (:mod:`texture.relax`) refactors its system every iteration, and the factorisation grows
faster than the face count: 0.26 s an iteration at 46k faces, 17-23 s at 418k, and an
island needs 20-60 of them. So an island above ``RelaxConfig.multires_faces`` is flattened
in four steps, each injective (no flipped face, no border crossing) or the island falls back
to plain SLIM:

1. **Coarse disk.** About ``COARSE_VERTICES`` of its vertices (interior ones drawn by vertex
   area, seeded; border ones one per coarse spacing of arc length, and every ear tip, a
   border vertex of one face) are triangulated (Delaunay) at their positions in the start
   map, a convex embedding (Tutte's, :func:`texture.flatten.tutte`): the coarse faces tile
   the same disk. Coarse faces degenerate in 3D (three border vertices on a straight border)
   lose a vertex. SLIM flattens the coarse disk (:func:`texture.flatten.relax_disk`).
2. **Transfer.** Each vertex takes the coarse map at its barycentric position in the start
   map (the composition of two embeddings); border vertices follow the coarse border's chords
   where they project onto them in the start map, bowed out by ``BULGE`` of a chord so that
   no face is left with three collinear corners.
3. **Unfold.** The few faces the transfer flips (along coarse edges where the map bends,
   near the border) unfold under free ARAP iterations (step 4's solver): the first
   injective iterate is kept. Faults left (a crossing, faces flipping back and forth) are
   repaired in place (:func:`untangle`: Tutte's condition on a growing patch, ear tips
   placed similar to their 3D triangle; then :func:`polish`, guarded SLIM on the patch),
   or held (vertices around them kept where the transfer put them) and the iterations rerun.
4. **Relax.** ARAP (libigl ``arap_precomputation`` / ``arap_solve``: its system is factored
   once, so an iteration costs a back-substitution) with a free border. Where an iteration
   flips a face or crosses the border, the vertices around it are held where they are and the
   iteration is retried (as :func:`texture.relax.relax_island` holds the border for SLIM).
   A result above ``WORSE`` x the coarse map's energy (plus ``WORSE_BY``) is refused.

Measured on the 111k-face bunny's two 47k-face islands: energy excess 0.062 and 0.070 in
1.4 and 1.1 s, where SLIM took 22 s (guarded, 0.054) and 6.8 s (0.115).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import scipy.sparse as sp
from scipy.spatial import Delaunay, QhullError, cKDTree

from mnacore.triangles import isometric_triangle, signed_areas, triangle_areas

from .islands import neighbour_mean, vertex_adjacency
from .relax import boundary_edges, crossing_edges, energy_excess

#: vertices of the coarse disk (SLIM on ~2x as many faces takes 0.2-0.4 s), or one per this
#: many faces where that is more: the transfer degrades with the fine-to-coarse ratio (a
#: 422k-face island from 2000 coarse vertices: 116 flipped faces, and free ARAP then crossed
#: the border where the coarse SLIM had to hold it; 11k coarse vertices: none)
COARSE_VERTICES = 2000
FACES_PER_COARSE_VERTEX = 40
#: border vertices within this many coarse spacings (arc length) of a sharp border turn are all coarse
NEAR_SHARP = 2.0
#: outward bow of a transferred border between two coarse border vertices (fraction of the chord)
BULGE = 0.02
#: a coarse face whose 3D area is below this times its longest edge squared is degenerate
FLAT = 1e-6
#: a coarse face with a 3D edge longer than this many coarse spacings is refined, at most
#: REFINE_ROUNDS times; FIX_ROUNDS bounds the repair rounds of both kinds. A border that runs
#: straight in 3D (a slit's sides, a flat part's edge) lies on the Tutte map's circle, where
#: Delaunay joins consecutive border vertices into faces that are flat in 3D: each round drops
#: those, and the next three along the run become the next flat face, so the rounds grow with
#: the runs' length (a 51k-face flat sheet with eight straight slits: 48 rounds; 16 failed
#: there and on an unwrap region after eight slits, which SLIM then relaxed at 5 s a slit).
#: A round is one Delaunay triangulation of the coarse vertices (milliseconds).
LONG = 3.0
REFINE_ROUNDS = 6
FIX_ROUNDS = 64
#: patch-growing rounds of the untangling
UNTANGLE_ROUNDS = 8
#: rounds of held vertices in the ARAP relaxation (each refactors its system: 3.8 s at 422k
#: faces, where an iteration costs 0.24 s), and the rings held around a fault per round
HOLD_ROUNDS = 2
HOLD_RINGS = 4
#: a result whose energy excess exceeds WORSE x the coarse map's plus WORSE_BY is refused
#: (measured: the fine map is within 0.9-1.1x of the coarse one when the steps go well)
WORSE = 3.0
WORSE_BY = 0.1
#: SLIM iterations on an untangled patch
POLISH_ITERATIONS = 50
#: free ARAP iterations allowed to unfold a transfer
FREE_ITERATIONS = 10
#: most ARAP iterations, and the least gain in energy excess for another
ARAP_ITERATIONS = 12
ARAP_MIN_GAIN = 1e-3


def _grow(mask: np.ndarray, adj: sp.csr_matrix, rings: int) -> np.ndarray:
    for _ in range(rings):
        mask = mask | ((adj @ mask.astype(np.float64)) > 0)
    return mask


def is_convex_border(uv: np.ndarray, border: np.ndarray) -> bool:
    """Whether the ordered border polygon ``uv[border]`` turns left (or goes straight) everywhere."""
    p = uv[border]
    d0, d1 = p - np.roll(p, 1, axis=0), np.roll(p, -1, axis=0) - p
    turn = d0[:, 0] * d1[:, 1] - d0[:, 1] * d1[:, 0]
    scale = np.linalg.norm(d0, axis=1) * np.linalg.norm(d1, axis=1)
    return bool((turn >= -1e-9 * scale).all())


def _coarse_samples(xyz, faces, border, count, rng) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(positions along ``border`` kept, interior vertices drawn, ear tips, coarse spacing)."""
    V = len(xyz)
    area = triangle_areas(xyz, faces)
    spacing = np.sqrt(area.sum() / count)  # about the coarse edge length
    seg = np.linalg.norm(xyz[np.roll(border, -1)] - xyz[border], axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)[:-1]])
    at = np.searchsorted(s, np.arange(0.0, s[-1] + seg[-1], spacing)).clip(0, len(border) - 1)
    use = np.bincount(faces.ravel(), minlength=V)
    ears = np.flatnonzero(use[border] == 1)
    # where the border turns back in 3D (a slit's tip, a sharp corner) it keeps its corner
    d0 = xyz[border] - xyz[np.roll(border, 1)]
    d1 = xyz[np.roll(border, -1)] - xyz[border]
    sharp = np.flatnonzero(np.einsum("ij,ij->i", d0, d1) < 0)
    # ... and every border vertex within two coarse spacings of it (arc length): at a slit's
    # tip the two sides meet at zero angle, and a coarse border cutting across them left
    # folds there that ARAP unfolded only by pushing one side across the other
    total = s[-1] + seg[-1]
    gap = np.abs(s[:, None] - s[sharp][None, :]) if len(sharp) else np.full((len(s), 1), np.inf)
    near_sharp = np.flatnonzero((np.minimum(gap, total - gap) <= NEAR_SHARP * spacing).any(1))
    kept = np.unique(np.concatenate([at, ears, sharp, near_sharp, [0]]))
    interior = np.setdiff1d(np.arange(V), border)
    weight = np.bincount(faces.ravel(), np.repeat(area / 3, 3), V)[interior]
    drawn = rng.choice(interior, size=min(count, len(interior)), replace=False, p=weight / weight.sum())
    return kept, drawn, border[ears], spacing


def coarse_disk(xyz, uv, faces, border, count, seed=0):
    """(coarse vertices (into the disk's), their Delaunay triangulation in ``uv``, its faces
    counter-clockwise, positions along ``border`` of the coarse border vertices); see step 1.

    Two repairs, a round each until none is needed: a coarse face degenerate in 3D loses a
    vertex (not an ear tip); a coarse face with a 3D edge longer than ``LONG`` coarse spacings
    gains the vertex nearest its centre in ``uv``. The second is what a big disk needs: its
    Tutte map squeezes the band along the border into a thin ring that area-drawn vertices
    seldom hit, so coarse faces there reach from the border far inside, and the carried map
    folded along the border (a 422k-face island)."""
    kept, drawn, ears, spacing = _coarse_samples(xyz, faces, border, count, np.random.default_rng(seed))
    interior = np.setdiff1d(np.arange(len(xyz)), border)
    refined = 0
    for _ in range(FIX_ROUNDS):
        sel = np.concatenate([border[kept], drawn])
        tri = Delaunay(uv[sel])
        cf = tri.simplices
        p = xyz[sel]
        longest = np.max([np.sum((p[cf[:, i]] - p[cf[:, (i + 1) % 3]]) ** 2, 1) for i in range(3)], 0)
        flat = triangle_areas(p, cf) <= FLAT * longest
        if flat.any():
            drop = np.unique(cf[flat].ravel())
            drop = drop[~np.isin(sel[drop], ears)]  # ear tips stay corners of the coarse border
            n_kept = len(kept)
            kept = np.delete(kept, drop[drop < n_kept])
            drawn = np.delete(drawn, drop[drop >= n_kept] - n_kept)
            continue
        long = longest > (LONG * spacing) ** 2
        if not long.any() or refined >= REFINE_ROUNDS:
            break
        refined += 1
        where = tri.find_simplex(uv[interior])
        cand = np.flatnonzero((where >= 0) & long[np.maximum(where, 0)])
        cand = cand[~np.isin(interior[cand], sel)]
        if not len(cand):
            break
        centre = uv[sel][cf[where[cand]]].mean(1)
        d = np.linalg.norm(uv[interior[cand]] - centre, axis=1)
        order = np.lexsort((d, where[cand]))
        first = order[np.r_[True, where[cand][order][1:] != where[cand][order][:-1]]]
        drawn = np.concatenate([drawn, interior[cand[first]]])
    else:
        return None
    cf = tri.simplices.copy()
    s = signed_areas(uv[sel], cf)
    cf[s < 0] = cf[s < 0][:, [0, 2, 1]]
    return sel, tri, cf, kept


def transfer(uv, border, tri, sel, kept, coarse_uv) -> np.ndarray:
    """(V, 2): the coarse map carried to every vertex (step 2)."""
    simp = tri.find_simplex(uv)
    out = simp < 0
    if out.any():  # off the coarse hull by rounding: the nearest hull face's affine map, extended
        hull = np.flatnonzero((tri.neighbors < 0).any(1))
        _, j = cKDTree(uv[sel][tri.simplices[hull]].mean(1)).query(uv[out])
        simp[out] = hull[j]
    T = tri.transform[simp]
    b = np.einsum("nij,nj->ni", T[:, :2], uv - T[:, 2])
    bary = np.column_stack([b, 1.0 - b.sum(1)])
    new = np.einsum("ni,nij->nj", bary, coarse_uv[tri.simplices[simp]])
    # the border: along the coarse border polygon, each vertex where it projects onto its
    # coarse chord in the start map (as the coarse faces along the chord carry the vertices
    # inside: a 3D arc-length fraction disagreed with them and folded the band), bowed outward
    pos = np.arange(len(border))
    k = np.searchsorted(np.append(kept, len(border)), pos, side="right") - 1
    ends = np.append(kept, kept[0])
    a, b = uv[border[ends[k]]], uv[border[ends[k + 1]]]
    f = (np.einsum("ij,ij->i", uv[border] - a, b - a) / np.maximum(np.einsum("ij,ij->i", b - a, b - a), 1e-300))
    f = np.clip(f, 0.0, 1.0)[:, None]
    corner = np.vstack([coarse_uv[:len(kept)], coarse_uv[:1]])
    d = corner[k + 1] - corner[k]
    outward = np.column_stack([d[:, 1], -d[:, 0]])  # right of a counter-clockwise border
    new[border] = corner[k] * (1 - f) + corner[k + 1] * f + BULGE * 4 * f * (1 - f) * outward
    return new


def _ear_faces(faces: np.ndarray, V: int) -> tuple[np.ndarray, np.ndarray]:
    """(ear tips, their faces rolled so the tip is corner 1): a border vertex of one face."""
    use = np.bincount(faces.ravel(), minlength=V)
    tip_corner = use[faces] == 1
    rows = np.flatnonzero(tip_corner.any(1))
    corner = tip_corner[rows].argmax(1)
    rolled = np.stack([np.roll(faces[r], 1 - c) for r, c in zip(rows, corner)]) if len(rows) else faces[:0]
    return rolled[:, 1], rolled


def _place_ears(xyz, uv, ears: np.ndarray) -> None:
    """Each ear tip where its face is similar to its 3D triangle, counter-clockwise, on its two
    neighbours as they are (in place): Tutte's mean would put it on their chord."""
    for a, e, b in ears:
        t = isometric_triangle(xyz[[a, e, b]])  # (0,0), (|ae|, 0), b: counter-clockwise
        za, zb = complex(*uv[a]), complex(*uv[b])
        m = (zb - za) / complex(*t[2])
        ze = za + m * complex(*t[1])
        uv[e] = (ze.real, ze.imag)


def untangle(uv: np.ndarray, faces: np.ndarray, border: np.ndarray, adj: sp.csr_matrix,
             edges: np.ndarray, xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Step 3's repair: the vertices around flipped faces, or around border crossings once no
    face is flipped, at the mean of their neighbours (Tutte's condition, solved on the patch),
    the patch growing each round. Border vertices join from the third round around flips and
    at once around a crossing (it is on the border: a small flap of the island that folded
    over its neck pulls back inside). An ear tip (a border vertex of one face; the mean would
    put it on its neighbours' chord) is placed instead so that its face is similar to its 3D
    triangle (two ears hanging off one corner crossed each other on a 217k-face island).
    ``(uv, the vertices moved)``, or None if a flip or a crossing remains."""
    V = len(uv)
    uv = uv.copy()
    movable = np.ones(V, bool)
    movable[border] = False
    tips, ears = _ear_faces(faces, V)
    not_ear = np.ones(V, bool)
    not_ear[tips] = False
    free = np.zeros(V, bool)
    for r in range(UNTANGLE_ROUNDS + 1):
        bad, cross = _faults(uv, faces, edges)
        if not bad.any() and not len(cross):
            return uv, free
        if r == UNTANGLE_ROUNDS:
            return None
        around = np.zeros(V, bool)
        around[faces[bad].ravel()] = True
        around[cross.ravel()] = True
        free |= _grow(around, adj, 2 + r) & (movable if r < 2 and not len(cross) else np.ones(V, bool))
        uv = neighbour_mean(adj, uv, free & not_ear)
        _place_ears(xyz, uv, ears[free[tips]])
    return None


def polish(xyz, uv, moved, faces, adj, edges) -> np.ndarray:
    """An untangled patch relaxed by SLIM (guarded against border crossings) with the ring
    around it held: Tutte's condition leaves its border vertices squashed onto their
    neighbours (a 422k-face island's energy excess 0.13 -> 0.78 from a flap of a few dozen
    faces, and ARAP with the patch held could not undo it). ``uv`` unchanged if SLIM's
    result flips a face or crosses the whole island's border."""
    from .relax import RelaxConfig, relax_island

    inner = _grow(moved, adj, 1)
    patch = np.flatnonzero(inner[faces].any(1))
    if not len(patch):
        return uv
    vid, inv = np.unique(faces[patch], return_inverse=True)
    sub = inv.reshape(-1, 3)
    ring = np.flatnonzero(~inner[vid])
    got = relax_island(xyz[vid], uv[vid], sub, RelaxConfig(iterations=POLISH_ITERATIONS, min_gain=1e-4), True, ring)
    new = uv.copy()
    new[vid] = got.uv
    bad, cross = _faults(new, faces, edges)
    return uv if bad.any() or len(cross) else new


class _Arap:
    """libigl's ARAP (2D parameterisation, one iteration per solve) with a set of held vertices."""

    def __init__(self, xyz, faces):
        self.xyz = np.ascontiguousarray(xyz, np.float64)
        self.faces = np.ascontiguousarray(faces, np.int64)
        self.held = np.zeros(len(xyz), bool)
        self.held[0] = True  # ARAP's translation
        self.factor()

    def factor(self):
        import igl

        self.data = igl.ARAPData()
        self.data.max_iter = 1
        igl.arap_precomputation(self.xyz, self.faces, 2, np.flatnonzero(self.held).astype(np.int32), self.data)

    def step(self, uv: np.ndarray) -> np.ndarray:
        import igl

        b = np.flatnonzero(self.held)
        return np.asarray(igl.arap_solve(np.ascontiguousarray(uv[b]), self.data, np.ascontiguousarray(uv)))


def _faults(uv, faces, edges) -> tuple[np.ndarray, np.ndarray]:
    """(flipped or non-finite faces (F,) bool, border crossings (K, 2, 2))."""
    bad = ~np.isfinite(uv).all(1)[faces].all(1) | (signed_areas(uv, faces) <= 0)
    return bad, (crossing_edges(faces, uv, edges) if not bad.any() else np.zeros((0, 2, 2), np.int64))


def injective_start(arap: _Arap, uv, faces, border, adj, edges, limit: float) -> tuple[np.ndarray | None, int]:
    """(an injective map near the transferred ``uv``, ARAP iterations spent). ARAP unfolds the
    few flipped faces of a transfer (its local step fits proper rotations; the count falls
    116, 13, 6, 3, 1, 0 on a 422k-face island), but a free border may then cross itself
    where it nearly touched: up to ``FREE_ITERATIONS`` iterations run from ``uv`` until no face
    is flipped. If the border then crosses, or a few faces stay flipped, :func:`untangle`
    repairs the last iterate in place (on a 422k-face island a flap of a few faces folded over
    its neck; on a 432k-face one six faces along the border flipped back and forth); failing
    that, the vertices around those faults are held where ``uv`` has them and the iterations
    rerun (at most ``HOLD_ROUNDS`` times; each hold refactors ARAP's system). A repair is
    kept only if its energy excess is within ``limit`` (what :func:`relax_multires` accepts).
    Failing that, :func:`untangle` of ``uv``; None if that fails too."""
    spent = 0
    folded = np.zeros(len(uv), bool)  # never held: a vertex held on a flipped face keeps it flipped
    folded[faces[_faults(uv, faces, edges)[0]].ravel()] = True
    folded = _grow(folded, adj, 1)
    for rounds in range(HOLD_ROUNDS + 1):
        current = uv
        for it in range(FREE_ITERATIONS + 1):
            bad = _faults(current, faces, edges)[0]
            if not bad.any():
                cross = crossing_edges(faces, current, edges)
                if not len(cross):
                    return current, spent
                break
            if it < FREE_ITERATIONS:
                current = arap.step(current)
                spent += 1
        else:
            cross = np.zeros((0, 2, 2), np.int64)
        # a few faults left (a flap folded over its neck; faces along the border that ARAP
        # flips back and forth): repaired in place
        fixed = untangle(current, faces, border, adj, edges, arap.xyz)
        if fixed is not None:
            fixed = polish(arap.xyz, *fixed, faces, adj, edges)
            if energy_excess(arap.xyz, fixed, faces) <= limit:  # else holding does better
                return fixed, spent
        if rounds == HOLD_ROUNDS:
            break
        around = np.zeros(len(uv), bool)
        around[faces[bad].ravel()] = True
        around[cross.ravel()] = True
        arap.held |= _grow(around, adj, HOLD_RINGS * (rounds + 1)) & ~folded
        arap.factor()
    fixed = untangle(uv, faces, border, adj, edges, arap.xyz)
    return (None if fixed is None else polish(arap.xyz, *fixed, faces, adj, edges)), spent


def held_arap(arap: _Arap, uv, faces, adj, edges) -> tuple[np.ndarray, int, int]:
    """Step 4: (uv, iterations, hold rounds). ``uv`` must be injective; so is the result."""
    current, excess = uv, energy_excess(arap.xyz, uv, faces)
    it = rounds = 0
    while it < ARAP_ITERATIONS:
        nxt = arap.step(current)
        bad, cross = _faults(nxt, faces, edges)
        if bad.any() or len(cross):
            if rounds >= HOLD_ROUNDS:
                break
            rounds += 1
            around = np.zeros(len(uv), bool)
            around[faces[bad].ravel()] = True
            around[cross.ravel()] = True
            arap.held |= _grow(around, adj, HOLD_RINGS * rounds)
            arap.factor()
            continue
        new_excess = energy_excess(arap.xyz, nxt, faces)
        if not new_excess < excess:
            break
        gain = excess - new_excess
        current, excess = nxt, new_excess
        it += 1
        if gain < ARAP_MIN_GAIN:
            break
    return current, it, rounds


def relax_multires(xyz, uv, faces, cfg, border: np.ndarray, relax_coarse) -> tuple[np.ndarray, dict] | None:
    """Steps 1-4 on a disk whose start ``uv`` is a convex embedding (ordered ``border``);
    ``(uv, stats)`` at the isometric scale, or None where a step failed (SLIM then runs).
    ``relax_coarse``: SLIM for the coarse disk (:func:`texture.flatten.relax_disk`, handed in
    by it: the two modules do not import each other)."""
    faces = np.asarray(faces, np.int64)
    if not is_convex_border(uv, border):
        return None
    try:
        coarse = coarse_disk(xyz, uv, faces, border, max(COARSE_VERTICES, len(faces) // FACES_PER_COARSE_VERTEX))
    except (QhullError, ValueError):
        return None
    if coarse is None:
        return None
    sel, tri, cf, kept = coarse
    p = xyz[sel]
    start = uv[sel] * np.sqrt(triangle_areas(p, cf).sum() / triangle_areas(uv[sel], cf).sum())
    # SLIM itself on the coarse disk: a Delaunay triangulation of scattered vertices is no
    # mesh to flatten in two resolutions again (its irregular faces folded every transfer)
    coarse_uv, coarse_stats = relax_coarse(p, start, cf, replace(cfg, multires_faces=0))
    if 0 < cfg.coarse_excess_limit < coarse_stats["excess"]:  # a finer map seldom flattens better
        return None
    adj = vertex_adjacency(faces, len(xyz))
    edges = boundary_edges(faces)
    arap = _Arap(xyz, faces)
    limit = WORSE * coarse_stats["excess"] + WORSE_BY
    new, unfold = injective_start(arap, transfer(uv, border, tri, sel, kept, coarse_uv), faces, border, adj, edges,
                                  limit)
    if new is None:
        return None
    new, iterations, rounds = held_arap(arap, new, faces, adj, edges)
    excess = energy_excess(xyz, new, faces)
    if not excess <= limit:  # held vertices stuck a fold nearly flat
        return None
    return new, {"mode": "multires", "iterations": coarse_stats["iterations"] + unfold + iterations,
                 "excess": excess, "coarse_faces": len(cf), "arap_iterations": unfold + iterations,
                 "hold_rounds": rounds}
