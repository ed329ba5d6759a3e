"""Relax each island's UVs toward an isometry with SLIM (libigl), keeping every island injective.

The neural charts are fitted with a distortion loss, but when a shape has more
disconnected parts than there are charts, a chart has to reach several parts and is
left stretched where it does. Once the charts are cut into islands, each island can be re-flattened on
its own: SLIM (Rabinovich et al., "Scalable Locally Injective Mappings", 2017; libigl's
``slim_precompute`` / ``slim_solve``) minimises the symmetric Dirichlet energy

    E = sum_f A_f (tr g_f + tr g_f^-1),     g = J^T J of the map UV -> surface,

from the island's own UVs, with free boundaries. The energy is infinite on a degenerate
triangle and SLIM's line search never crosses it, so no face flips. What SLIM does not
prevent is the island's *border* running over itself (global overlap): after every
iteration each island's boundary edges are tested for crossings; where one appears, the
border vertices near it are held in place (soft constraints) and the step is retried, and
after ``pin_rounds`` such retries the island keeps its last crossing-free UVs.

One texel density for all charts: before relaxing, every island's UVs are scaled by one
global factor (total UV area = total 3D area), so SLIM's target, an
isometry, means the same texel size everywhere; the result is scaled back to chart units.
Topology, 3D positions, borders and seams are unchanged: only UV positions move.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from mnacore.triangles import signed_areas, triangle_areas

from . import parallel
from .distortion_faces import face_geometry, symmetric_dirichlet
from .islands import edge_keys, edge_use_counts, half_edges, uv_islands
from .parallel import parallel_map

#: the unwrap's size above which a disk is flattened by :mod:`texture.multires`
#: (``UnwrapConfig.multires_faces``); relax_disk gives it Tutte's convex embedding for that
MULTIRES_FACES = 20_000
#: the unwrap's size above which a disk whose two-resolution flattening fails is not handed
#: to SLIM (``UnwrapConfig.slim_max_faces``). Only up to it does a disk's start offer the
#: conformal map (:func:`texture.flatten.start_map`; SLIM may start there); above it the
#: start is Tutte's alone, as the two-resolution path needs, and LSCM's solve on a 250k-face
#: island is not spent (it took the 1M-face scan's unwrap 147 -> 186 s)
SLIM_MAX_FACES = 100_000

#: weight of the soft constraints that hold border vertices (libigl's default).
PIN_WEIGHT = 1e5


@dataclass
class RelaxConfig:
    """Options of :func:`relax_islands`."""

    iterations: int = 8
    """Most SLIM iterations per island (0 = no relaxation)."""
    min_gain: float = 0.005
    """Stop an island once an iteration lowers its mean energy excess ``E / A - 4`` (about
    its metric distortion) by less than this; islands already below it are left alone."""
    pin_rounds: int = 4
    """Where the border would cross itself, the border vertices near the crossing are held
    in place (soft constraints) and the iteration is retried, at most this many times per
    island; after that the island keeps its last crossing-free UVs."""
    pin_radius: float = 8.0
    """Border vertices within this many median edge lengths of a crossing are held (the
    radius doubles with every round)."""
    multires_faces: int = 0
    """Disks above this many faces are flattened by :mod:`texture.multires` (coarse SLIM,
    then ARAP on the whole) instead of SLIM on the whole (0 = never); used by
    :func:`texture.flatten.relax_disk`."""
    slim_max_faces: int = 0
    """Where that fails, disks above this many faces keep their start (0 = SLIM at any size)."""
    scaffold_above: float = 0.0
    """Where free SLIM overlaps itself and the guarded run ends above this energy excess (or
    not at all), :func:`texture.flatten.relax_disk` runs SLIM with a scaffold
    (:mod:`texture.scaffold`) too and keeps the lower (0 = never)."""
    coarse_excess_limit: float = 0.0
    """A disk flattened in two resolutions whose coarse map's energy excess is above this is
    not refined (it fails as if a step had: :func:`texture.multires.relax_multires`), for a
    caller that refuses a map past it anyway (a merge trial: :mod:`texture.merge`; 0 = none)."""


def _local_jacobian_energy(xyz: np.ndarray, uv: np.ndarray, faces: np.ndarray) -> tuple[float, float]:
    """(sum over faces of ``A (tr g + tr g^-1)``, sum of ``A``); inf energy if a face is degenerate."""
    geom = face_geometry(xyz, faces, uv)
    v = geom.valid & (geom.area_3d > 0)
    if not v.any():
        return np.inf, 0.0
    e = symmetric_dirichlet(geom)[v]
    a = geom.area_3d[v]
    if (~geom.valid).any() or not np.isfinite(e).all():
        return np.inf, float(a.sum())
    return float((a * e).sum()), float(a.sum())


def energy_excess(xyz: np.ndarray, uv: np.ndarray, faces: np.ndarray) -> float:
    """3D-area weighted mean of ``tr g + tr g^-1`` minus 4 (0 for an isometry; inf if a face is degenerate)."""
    e, a = _local_jacobian_energy(xyz, uv, faces)
    return e / a - 4.0 if a > 0 else np.inf


def boundary_edges(faces: np.ndarray) -> np.ndarray:
    """(B, 2) vertex pairs of the edges used by exactly one face (each in its face's direction)."""
    faces = np.asarray(faces, np.int64)
    if len(faces) == 0:
        return np.zeros((0, 2), np.int64)
    once = edge_use_counts(edge_keys(np.arange(int(faces.max()) + 1), faces)) == 1
    return half_edges(faces)[once]


def boundary_length(xyz: np.ndarray, faces: np.ndarray) -> float:
    """3D length of the boundary edges of ``faces`` (into ``xyz``)."""
    e = boundary_edges(faces)
    return float(np.linalg.norm(xyz[e[:, 0]] - xyz[e[:, 1]], axis=1).sum())


def is_injective(uv: np.ndarray, faces: np.ndarray, slivers: bool = False) -> bool:
    """Whether the map is finite, flips no face, its border does not cross itself
    (:func:`crossing_edges`) and its holes run clockwise (:func:`holes_run_clockwise`):
    then the island does not overlap itself. ``slivers``: a face of zero UV area passes
    (it covers nothing twice); by default every face must have positive area."""
    if not np.isfinite(uv).all():
        return False
    area = signed_areas(uv, faces)
    if not ((area >= 0) if slivers else (area > 0)).all():
        return False
    edges = boundary_edges(faces)
    return bool(not len(crossing_edges(faces, uv, edges)) and holes_run_clockwise(uv, faces, edges))


def holes_run_clockwise(uv: np.ndarray, faces: np.ndarray, edges: np.ndarray | None = None) -> bool:
    """Whether every border loop but the largest (by UV area) runs clockwise in UV, each
    loop directed as its faces run (the largest then runs counter-clockwise on a flip-free map).

    A flip-free map whose border loops are simple and apart covers each point as many times
    as the loops around it wind (each loop directed as its faces run: +1 inside a
    counter-clockwise one, -1 inside a clockwise one). A disk's one loop winds once, so
    flips and crossings are all that can make it overlap itself; with holes, a hole loop
    that runs counter-clockwise covers its inside twice, with no face flipped and no border
    edge crossing (a plate's conformal map, whose region around a hole lapped over it like a
    tongue: 2.5 % of a held-out genus-3 shape's texels). ``edges``: the boundary edges, if known."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    edges = boundary_edges(faces) if edges is None else edges
    if len(edges) == 0:
        return True
    n = int(np.asarray(faces).max()) + 1
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    _, loop = connected_components(graph, directed=False)
    a, b = uv[edges[:, 0]], uv[edges[:, 1]]
    # shoelace per loop: each directed border edge adds its cross product
    area = np.bincount(loop[edges[:, 0]], 0.5 * (a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1]), minlength=n)
    area = area[np.unique(loop[edges[:, 0]])]
    if len(area) < 2:
        return True
    others = np.delete(area, int(np.argmax(np.abs(area))))
    return bool((others < 0).all())


def crossing_edges(faces: np.ndarray, uv: np.ndarray, edges: np.ndarray | None = None) -> np.ndarray:
    """(K, 2, 2) vertex pairs of the boundary edges that cross another boundary edge in UV
    (one row per crossing pair of edges sharing no vertex).

    For a map of a disk that flips no face, the island overlaps itself exactly when its
    border crosses itself (a touching without crossing counts too: collinear overlaps and an
    endpoint lying on another edge are crossings here); with holes, see :func:`is_injective`. ``edges``: the boundary edges, if known.
    """
    edges = boundary_edges(faces) if edges is None else edges
    none = np.zeros((0, 2, 2), np.int64)
    if len(edges) < 2:
        return none
    a, b = uv[edges[:, 0]], uv[edges[:, 1]]
    length = np.linalg.norm(b - a, axis=1)
    # two segments can only meet if their midpoints lie within the sum of their half
    # lengths, so within the longer one's length: each edge looks that far for edges no
    # longer than itself. (One radius for all, the longest edge's, made every pair of a
    # cluster of short edges a candidate: a cap's rim of 1,500 short edges beside cut edges
    # 100 times longer gave a million pairs per SLIM iteration.)
    mid = 0.5 * (a + b)
    near = cKDTree(mid).query_ball_point(mid, length * (1.0 + 1e-9) + 1e-300, return_sorted=False)
    counts = np.fromiter((len(n) for n in near), np.int64, len(near))
    i = np.repeat(np.arange(len(edges)), counts)
    j = np.fromiter((k for n in near for k in n), np.int64, int(counts.sum()))
    own = (length[j] < length[i]) | ((length[j] == length[i]) & (j > i))  # each pair once
    i, j = i[own], j[own]
    if len(i) == 0:
        return none
    share = (edges[i, 0, None] == edges[j]).any(1) | (edges[i, 1, None] == edges[j]).any(1)
    i, j = i[~share], j[~share]
    p, r, q, s = a[i], b[i] - a[i], a[j], b[j] - a[j]

    def cross(u, w):
        return u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0]

    d1, d2 = cross(r, q - p), cross(r, q + s - p)  # sides of q, q+s relative to segment i
    d3, d4 = cross(s, p - q), cross(s, p + r - q)  # sides of p, p+r relative to segment j
    hit = (d1 * d2 <= 0) & (d3 * d4 <= 0)
    # collinear pairs pass the sign test everywhere on the line: keep those whose extents overlap
    collinear = (d1 == 0) & (d2 == 0)
    if collinear.any():
        rr = np.maximum(np.einsum("ij,ij->i", r, r), 1e-300)
        t0 = np.einsum("ij,ij->i", q - p, r) / rr
        t1 = np.einsum("ij,ij->i", q + s - p, r) / rr
        hit &= ~collinear | ((np.maximum(t0, t1) >= 0) & (np.minimum(t0, t1) <= 1))
    return np.stack([edges[i[hit]], edges[j[hit]]], 1)


@dataclass
class IslandRelaxation:
    """What :func:`relax_island` did."""

    uv: np.ndarray
    iterations: int
    excess_before: float
    excess_after: float
    stopped_by_crossing: bool
    valid_uv: np.ndarray | None = None
    """Unguarded runs (``check_crossings=False``): the lowest-energy iterate (the start
    included) with no flipped face and no border crossing, None if there was none."""
    valid_excess: float = np.inf


def relax_island(xyz: np.ndarray, uv: np.ndarray, faces: np.ndarray, cfg: RelaxConfig,
                 check_crossings: bool = True, fixed: np.ndarray | None = None) -> IslandRelaxation:
    """SLIM on one connected island (``uv`` in the isometric scale); see the module docstring.
    ``fixed``: vertices held where they are throughout (soft constraints, as the guard's).

    Returns the input UVs unchanged when a face has zero or turned-over UV area (SLIM's
    Jacobians need every face on one side), when the input border already crosses itself,
    or when SLIM gives non-finite values. A map of infinite energy excess whose faces all
    keep some area (a Tutte map of a long, branching disk squeezes its far faces to 1e-11
    of the mean area: :func:`energy_excess` counts them degenerate) is relaxed: SLIM's
    first iterations spread them out (excess 506 after one on a 21k-face disk); its iterates are
    taken while the excess stays infinite, as long as they stay finite and flip-free.
    """
    import igl

    uv = np.asarray(uv, np.float64)
    before = energy_excess(xyz, uv, faces)
    result = IslandRelaxation(uv, 0, before, before, False)
    if cfg.iterations <= 0 or before < cfg.min_gain or len(faces) < 2:
        return result
    if not np.isfinite(before):
        signed = signed_areas(uv, faces) if np.isfinite(uv).all() else np.zeros(1)
        if not ((signed > 0).all() or (signed < 0).all()):
            return result
    border_edges = boundary_edges(faces)
    if check_crossings and len(crossing_edges(faces, uv, border_edges)):
        return result
    # SLIM's local step fits rotations (det > 0): a clockwise island is mirrored in and out
    mirror = np.array([1.0, -1.0 if face_geometry(xyz, faces, uv).uv_area.sum() < 0 else 1.0])
    xyz_f = np.asfortranarray(xyz, np.float64)
    faces_f = np.asfortranarray(faces, np.int32)
    border = np.unique(border_edges)
    edge_len = np.linalg.norm(uv[faces[:, 1]] - uv[faces[:, 0]], axis=1)
    pins = np.zeros(0, np.int64) if fixed is None else np.unique(np.asarray(fixed, np.int64))

    def start(at):
        return igl.slim_precompute(xyz_f, faces_f, np.asfortranarray(at * mirror), igl.SYMMETRIC_DIRICHLET,
                                   np.ascontiguousarray(pins, np.int32),
                                   np.asfortranarray(at[pins] * mirror), PIN_WEIGHT if len(pins) else 0.0)

    data = start(uv)
    current, excess, it, rounds = uv, before, 0, 0

    def track_valid(u, e):  # unguarded: remember the best iterate a guarded run may start from
        if (not check_crossings and e < result.valid_excess and (signed_areas(u, faces) * mirror[1] > 0).all()
                and not len(crossing_edges(faces, u, border_edges))):
            result.valid_uv, result.valid_excess = u, e

    track_valid(uv, before)
    while it < cfg.iterations:
        nxt = np.array(igl.slim_solve(data, 1)[:, :2], np.float64) * mirror
        new_excess = energy_excess(xyz, nxt, faces) if np.isfinite(nxt).all() else np.inf
        if not np.isfinite(new_excess):
            # still infinite from an infinite start: SLIM's line search lowers its own energy at
            # every step, and its iterates spread the squeezed faces out over a few iterations
            # (a Tutte start of a 17k-face half of an unseen scan: 313, 111, 14, 2, then no faces
            # below DEGENERATE_UV_REL, excess 3.2e6 after four and 357 after twelve); stopping at the
            # first such iterate left that island as it started, for the slits to relax it
            if np.isfinite(excess) or not np.isfinite(nxt).all() or not (signed_areas(nxt, faces) * mirror[1] > 0).all():
                break
        elif new_excess > excess:
            break
        crossing = crossing_edges(faces, nxt, border_edges) if check_crossings else np.zeros((0, 2, 2), np.int64)
        if len(crossing):
            if rounds >= cfg.pin_rounds:
                result.stopped_by_crossing = True
                break
            # hold the border near the crossings where it is now (crossing-free) and try again
            rounds += 1
            radius = cfg.pin_radius * (2 ** (rounds - 1)) * float(np.median(edge_len))
            near = cKDTree(current[border]).query_ball_point(current[np.unique(crossing)], radius)
            hit = np.unique(np.concatenate([np.asarray(n, np.int64) for n in near]))
            pins = np.union1d(pins, border[hit])
            data = start(current)
            continue
        gain = excess - new_excess if np.isfinite(new_excess) else np.inf
        current, excess = nxt, new_excess
        track_valid(current, excess)
        it += 1
        result.iterations = it
        if gain < cfg.min_gain:
            break
    result.uv, result.excess_after = current, excess
    return result


def isometric_scale(xyz: np.ndarray, uv: np.ndarray, faces: np.ndarray) -> float:
    """``s`` with ``sum |uv area| * s^2 = sum 3D area`` (the one global scale of every island)."""
    uv_total = float(triangle_areas(uv, faces).sum())
    return float(np.sqrt(triangle_areas(xyz, faces).sum() / uv_total)) if uv_total > 0 else 1.0


def _relax_job(job, _shared=None):
    xyz, uv, faces, cfg, check_crossings = job
    return relax_island(xyz, uv, faces, cfg, check_crossings)


def _run_jobs(jobs: list, workers: int | None) -> list:
    """``relax_island`` of every job, in parallel processes when there is enough work
    (SLIM runs on one core and holds the GIL), largest first; same result as one by one."""
    order = sorted(range(len(jobs)), key=lambda i: -len(jobs[i][2]))
    done = parallel_map(_relax_job, [jobs[i] for i in order], workers,
                        parallel=sum(len(j[2]) for j in jobs) >= parallel.MIN_FACES)
    out = [None] * len(jobs)
    for i, r in zip(order, done):
        out[i] = r
    return out


def relax_islands(xyz: np.ndarray, uv: np.ndarray, faces: np.ndarray, island: np.ndarray | None = None,
                  cfg: RelaxConfig | None = None, scale: float | None = None,
                  check_crossings: bool = True, workers: int | None = None) -> tuple[np.ndarray, dict]:
    """Relax every island of ``(xyz, uv, faces)``; returns ``(uv, stats)``.

    ``island`` (F,) defaults to the UV islands; islands must not share vertices.
    ``scale`` (UV units -> isometric) defaults to :func:`isometric_scale` of the whole mesh;
    pass one scale for several meshes that share a texel density.
    """
    s = isometric_scale(xyz, uv, faces) if scale is None else float(scale)
    return relax_meshes([(xyz, uv, faces, island)], cfg, s, check_crossings, workers)[0]


def relax_meshes(meshes: list[tuple], cfg: RelaxConfig | None = None, scale: float = 1.0,
                 check_crossings: bool = True, workers: int | None = None) -> list[tuple[np.ndarray, dict]]:
    """:func:`relax_islands` of several meshes ``(xyz, uv, faces, island or None)`` at one
    ``scale``, all their islands relaxed in parallel (the result is the same as one by one)."""
    cfg = cfg or RelaxConfig()
    s = float(scale)
    jobs, where = [], []  # where: (mesh, vertex ids) of each job
    for m, (xyz, uv, faces, island) in enumerate(meshes):
        faces = np.asarray(faces, np.int64)
        if island is None:
            island = uv_islands(faces, uv)
        order = np.argsort(island, kind="stable")
        bounds = np.searchsorted(island[order], np.arange(int(island.max()) + 2)) if len(island) else [0]
        for k in range(len(bounds) - 1):
            fi = order[bounds[k]:bounds[k + 1]]
            if len(fi) == 0:
                continue
            vid, inv = np.unique(faces[fi], return_inverse=True)
            jobs.append((xyz[vid], np.asarray(uv, np.float64)[vid] * s, inv.reshape(-1, 3), cfg, check_crossings))
            where.append((m, vid))
    results = _run_jobs(jobs, workers)
    outs = [np.array(uv, np.float64) for _, uv, _, _ in meshes]
    stats = [{"islands": 0, "iterations": [], "stopped_by_crossing": 0, "energy_before": 0.0,
              "energy_after": 0.0, "area": 0.0} for _ in meshes]
    for (m, vid), job, r in zip(where, jobs, results):
        outs[m][vid] = r.uv / s
        st = stats[m]
        area = float(triangle_areas(job[0], job[2]).sum())
        st["islands"] += 1
        st["iterations"].append(r.iterations)
        st["stopped_by_crossing"] += int(r.stopped_by_crossing)
        if np.isfinite(r.excess_before):
            st["energy_before"] += area * r.excess_before
            st["energy_after"] += area * r.excess_after
            st["area"] += area
    for st in stats:
        if st["area"] > 0:
            st["energy_before"] /= st["area"]
            st["energy_after"] /= st["area"]
    return list(zip(outs, stats))
