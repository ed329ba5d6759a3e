"""One region of faces -> topological disks -> a flip-free flattening (Tutte, then SLIM).

- :func:`split_pinched` splits vertices where two fans of a region touch (a pinch), so
  the region is a manifold surface with boundary.
- :func:`cut_to_disks` makes it a disk: libigl's ``cut_to_disk`` (a cut graph through
  every handle and between every pair of boundary loops) and ``cut_mesh``; a closed
  genus-0 region (no cut needed by that definition, but no boundary either) is cut along
  the graph-shortest path from its first vertex to the vertex farthest from it.
- :func:`tutte` embeds a disk in the unit circle with uniform weights (Tutte's theorem:
  for a disk whose boundary is mapped to a convex polygon, every interior vertex at the
  mean of its neighbours gives an embedding without flipped faces), boundary vertices at
  arc-length positions (``igl.map_vertices_to_circle``).
- SLIM (:mod:`texture.relax`) then relaxes it toward an isometry; see :mod:`texture.unwrap`.

Face order and corner order are kept by every step (``cut_mesh`` duplicates vertices
only), so face ``i`` of a cut disk is face ``i`` of the region.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components, dijkstra

from mnacore.triangles import signed_areas, triangle_areas

from .islands import neighbour_mean, vertex_adjacency
from .meshprep import corner_groups


@dataclass
class Disk:
    """A region cut to a disk: ``faces (F, 3)`` into its ``source (V,)`` region vertices."""

    faces: np.ndarray
    source: np.ndarray
    cut_edges: int


def split_pinched(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(faces (F,3) with pinched vertices split, source (V',) original vertex of each new one)."""
    new, _ = corner_groups(faces)
    src = np.zeros(int(new.max()) + 1, np.int64)
    src[new.ravel()] = faces.ravel()
    return new, src


def boundary_loop_count(faces: np.ndarray) -> int:
    """Connected components of the boundary edges (edges used once) of a manifold mesh."""
    he = np.stack([faces, np.roll(faces, -1, axis=1)], -1).reshape(-1, 2)
    n = int(faces.max()) + 1
    key = he.min(1) * n + he.max(1)
    _, inv, counts = np.unique(key, return_inverse=True, return_counts=True)
    b = he[counts[inv.reshape(-1)] == 1]
    if len(b) == 0:
        return 0
    used, idx = np.unique(b, return_inverse=True)
    idx = idx.reshape(-1, 2)
    g = sp.coo_matrix((np.ones(len(b)), (idx[:, 0], idx[:, 1])), shape=(len(used), len(used)))
    return int(connected_components(g, directed=False)[0])


def euler_characteristic(faces: np.ndarray) -> int:
    """``V - E + F`` over the vertices used by ``faces``."""
    he = np.sort(np.stack([faces, np.roll(faces, -1, axis=1)], -1).reshape(-1, 2), axis=1)
    E = len(np.unique(he, axis=0))
    return int(len(np.unique(faces)) - E + len(faces))


def is_disk(faces: np.ndarray) -> bool:
    return euler_characteristic(faces) == 1 and boundary_loop_count(faces) == 1


def _edge_graph(vertices: np.ndarray, faces: np.ndarray) -> sp.csr_matrix:
    he = np.stack([faces, np.roll(faces, -1, axis=1)], -1).reshape(-1, 2)
    w = np.linalg.norm(vertices[he[:, 0]] - vertices[he[:, 1]], axis=1) + 1e-12
    n = len(vertices)
    g = sp.coo_matrix((w, (he[:, 0], he[:, 1])), shape=(n, n)).tocsr()
    return g.maximum(g.T)


def _farthest_path(vertices: np.ndarray, faces: np.ndarray) -> list[list[int]]:
    """Shortest edge path from the first face's first vertex to the vertex farthest from it."""
    start = int(faces[0, 0])
    dist, pred = dijkstra(_edge_graph(vertices, faces), indices=start, return_predecessors=True)
    dist[~np.isfinite(dist)] = -1
    v = int(np.argmax(dist))
    path = [v]
    while v != start:
        v = int(pred[v])
        path.append(v)
    return [path[::-1]]


def _cut_flags(faces: np.ndarray, cuts: list[list[int]]) -> np.ndarray:
    """(F, 3) bool: edge ``(faces[f, j], faces[f, (j+1) % 3])`` lies on a cut path."""
    n = int(faces.max()) + 1
    keys = set()
    for c in cuts:
        c = np.asarray(c, np.int64)
        keys.update((np.minimum(c[:-1], c[1:]) * n + np.maximum(c[:-1], c[1:])).tolist())
    keys = np.fromiter(keys, np.int64, len(keys))
    flags = np.zeros(faces.shape, bool)
    for j in range(3):
        a, b = faces[:, j], faces[:, (j + 1) % 3]
        flags[:, j] = np.isin(np.minimum(a, b) * n + np.maximum(a, b), keys)
    return flags


def cut_to_disk(vertices: np.ndarray, faces: np.ndarray) -> Disk:
    """Cut the region ``(vertices (V,3), faces (F,3))`` (manifold, connected) into one disk.

    Raises ``RuntimeError`` if the result is not a disk (the caller splits the region).
    """
    import igl

    faces = np.asarray(faces, np.int64)
    if is_disk(faces):
        return Disk(faces, np.arange(len(vertices)), 0)
    if boundary_loop_count(faces) == 0 and euler_characteristic(faces) == 2:
        cuts = _farthest_path(vertices, faces)
    else:
        cuts = [list(c) for c in igl.cut_to_disk(faces)]
    flags = _cut_flags(faces, cuts)
    _, new_faces, source = igl.cut_mesh(np.asarray(vertices, np.float64), faces, flags)
    new_faces = np.asarray(new_faces, np.int64)
    if not is_disk(new_faces):
        raise RuntimeError("cut_to_disk: the cut region is not a disk")
    return Disk(new_faces, np.asarray(source, np.int64), int(flags.sum()))


def ordered_boundary(faces: np.ndarray) -> np.ndarray:
    """Boundary vertices of a disk in the order of its boundary half-edges."""
    he = np.stack([faces, np.roll(faces, -1, axis=1)], -1).reshape(-1, 2)
    n = int(faces.max()) + 1
    key = he.min(1) * n + he.max(1)
    _, inv, counts = np.unique(key, return_inverse=True, return_counts=True)
    b = he[counts[inv.reshape(-1)] == 1]
    nxt = dict(zip(b[:, 0].tolist(), b[:, 1].tolist()))
    loop = [int(b[0, 0])]
    while len(loop) <= len(b):
        v = nxt[loop[-1]]
        if v == loop[0]:
            break
        loop.append(v)
    return np.asarray(loop, np.int64)


def tutte(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(V, 2) uniform-weight Tutte embedding of a disk; boundary on the unit circle by arc length.

    Interior vertex ``i``: ``deg(i) x_i - sum_{j ~ i} x_j = 0``. Counter-clockwise boundary
    order follows the faces' winding, so faces keep their orientation (positive UV area).
    """
    import igl

    V = len(vertices)
    bnd = ordered_boundary(faces)
    bnd_uv = np.asarray(igl.map_vertices_to_circle(np.asfortranarray(vertices, np.float64),
                                                   np.ascontiguousarray(bnd, np.int32)), np.float64)
    uv = np.zeros((V, 2))
    uv[bnd] = bnd_uv
    interior = np.ones(V, bool)
    interior[bnd] = False
    return neighbour_mean(vertex_adjacency(faces, V), uv, interior)


def lscm(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray | None:
    """(V, 2) least-squares conformal map of a disk (libigl; two border vertices pinned, the
    second the farthest from the first), counter-clockwise like the faces; None unless it
    is an embedding: every face turned the same way, the border crossing nowhere."""
    import igl

    from .relax import is_injective

    bnd = ordered_boundary(faces)
    if len(bnd) < 3:
        return None
    far = bnd[int(np.argmax(np.linalg.norm(vertices[bnd] - vertices[bnd[0]], axis=1)))]
    pins = np.array([bnd[0], far], np.int64)
    try:
        uv, _ = igl.lscm(np.asarray(vertices, np.float64), np.asarray(faces, np.int64), pins,
                         np.array([[0.0, 0.0], [1.0, 0.0]]))
    except (RuntimeError, ValueError):
        return None
    uv = np.asarray(uv, np.float64)
    if not np.isfinite(uv).all():
        return None
    if signed_areas(uv, faces).sum() < 0:  # LSCM keeps angles, not necessarily the turning
        uv[:, 0] = -uv[:, 0]
    return uv if is_injective(uv, faces) else None


def holed_map(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray | None:
    """(V, 2) conformal map (:func:`lscm`) of a region that is a disk with holes (genus 0,
    two or more border loops), uncut; None for any other region or where the map is not an
    embedding (a face flipped, the borders crossing). A flat region with holes (a plate's
    face, a panel with windows) maps onto itself: no cut to a disk is needed, and the cuts
    from each hole to the border (seam and ragged islands that pack poorly) are saved."""
    faces = np.asarray(faces, np.int64)
    loops = boundary_loop_count(faces)
    if loops < 2 or euler_characteristic(faces) != 2 - loops:
        return None
    return lscm(vertices, faces)


def start_map(vertices: np.ndarray, faces: np.ndarray, slim_max_faces: int | None = None) -> np.ndarray:
    """A flip-free start for SLIM on a disk: of the conformal map (:func:`lscm`, where it is
    an embedding) and :func:`tutte`, the one of lower energy excess at the isometric scale
    (SLIM descends from it). A conformal map only scales, so on a developable piece it *is*
    the isometry: a cut cylinder wall (16:1) starts at excess 0 instead of Tutte's 68, whose
    circle border squeezes the strip; on the benchmark fits SLIM then stops after 6
    iterations instead of 19 (the t-shirt's islands). A disk above ``slim_max_faces`` faces
    (default :data:`texture.relax.SLIM_MAX_FACES`; 0 = no limit), where SLIM never runs,
    gets Tutte's map alone: the two-resolution flattening needs its convex border."""
    from .relax import SLIM_MAX_FACES, energy_excess

    cap = SLIM_MAX_FACES if slim_max_faces is None else slim_max_faces
    t = tutte(vertices, faces)
    c = None if 0 < cap < len(faces) or len(faces) < 2 else lscm(vertices, faces)
    if c is None:
        return t
    area = triangle_areas(vertices, faces).sum()

    def excess(uv):
        return energy_excess(vertices, uv * np.sqrt(area / signed_areas(uv, faces).sum()), faces)
    return c if excess(c) < excess(t) else t


#: border-pinning retries of the guarded SLIM run (texture.relax's default is 4).
GUARD_PIN_ROUNDS = 16
#: the guarded run is left out (the scaffold runs instead) where the free run's best
#: crossing-free iterate has more than this times the free result's energy excess. Measured
#: where both ran: at ratios 1.0-7.2 (11 disks of the 19 benchmark unwraps) the guard ended
#: within 1.5x of the scaffold and below it on 4; at 44-5e5 (4 disks there, 20 large disks of
#: a marching-cubes lattice cut through many handles) it stalled at 1.7-4e4 times the
#: scaffold's result.
GUARD_START_RATIO = 10.0


def relax_disk(xyz: np.ndarray, uv: np.ndarray, faces: np.ndarray, cfg) -> tuple[np.ndarray, dict]:
    """SLIM on one disk (``uv`` at the isometric scale, flip-free): ``(uv, stats)``.

    First free SLIM (``texture.relax.relax_island`` without the border-crossing guard): its
    iterations may cross the border on the way and still end injective, and the guard's
    pinning can stall far from the optimum on a region whose free optimum needs its border
    vertices to move far (one such 683-face region: excess 4.17 guarded, 0.02 free). If the
    free result flips a face or crosses its border, the guarded run (crossing-free after
    every iteration) continues from the free run's best iterate that was flip-free and
    crossing-free: pinning then acts only once the map is nearly relaxed, where restarting
    from the Tutte map left a large island stalled (a 46k-face island: 0.068 at the free
    run's first crossing, 4.67 guarded from Tutte); if that fails too, that iterate (or the
    start). With ``cfg.scaffold_above`` set, SLIM with a scaffold (:mod:`texture.scaffold`)
    runs after a guarded run that ends above it (the lower map is kept), and instead of the
    guarded run where that would start far from relaxed (:data:`GUARD_START_RATIO`). A disk
    above ``cfg.multires_faces`` faces is first flattened by
    :func:`texture.multires.relax_multires` (SLIM's cost per iteration grows faster than the
    face count); the above runs only where that fails, and not above ``cfg.slim_max_faces``
    faces: there the start is kept (mode ``start``), and the unwrap's split stage halves the disk.
    """
    from .relax import energy_excess, is_injective, relax_island

    if 0 < cfg.multires_faces < len(faces):
        from .multires import is_convex_border, relax_multires

        border = ordered_boundary(faces)
        convex = uv
        if not is_convex_border(uv, border):  # a conformal start: the coarse copy needs a convex one
            t = tutte(xyz, faces)
            convex = t * np.sqrt(signed_areas(uv, faces).sum() / signed_areas(t, faces).sum())

        got = relax_multires(xyz, convex, faces, cfg, border, relax_disk)
        if got is not None:
            return got
        # SLIM below starts from the caller's map, not the Tutte map made for the coarse copy:
        # on a cap whose pole is a fan of slivers (a 27k-face half of a 1,500-segment sphere)
        # the conformal start had excess 0.24 and the Tutte map 2,865, and SLIM from the
        # latter stalled at 3.45 after 178 iterations
        if 0 < cfg.slim_max_faces < len(faces):  # SLIM would take minutes: the split stage halves it
            return uv, {"mode": "start", "iterations": 0, "excess": energy_excess(xyz, uv, faces)}

    free = relax_island(xyz, uv, faces, cfg, check_crossings=False)
    if is_injective(free.uv, faces):
        return free.uv, {"mode": "free", "iterations": free.iterations, "excess": free.excess_after}
    from dataclasses import replace

    from .scaffold import relax_scaffold

    def scaffold():
        got = relax_scaffold(xyz, uv, faces, cfg.iterations, cfg.min_gain)
        return [] if got is None else [(got[0], "scaffold", free.iterations + got[1], got[2])]

    done = []
    # the guarded run continues from the free run's best crossing-free iterate; where that is
    # the start itself (no later iterate was crossing-free) or still far from relaxed, its
    # first steps cross and every retry crosses elsewhere, so it stalls far above the free
    # optimum (docs/unwrap.md, step 6): the scaffold runs instead, the guard only if it fails
    first = cfg.scaffold_above > 0 and (free.valid_excess >= free.excess_before
                                        or free.valid_excess > GUARD_START_RATIO * free.excess_after)
    if first:
        done = scaffold()
    if not done:
        best_free = uv if free.valid_uv is None else free.valid_uv
        guarded = relax_island(xyz, best_free, faces, replace(cfg, pin_rounds=GUARD_PIN_ROUNDS), check_crossings=True)
        if is_injective(guarded.uv, faces):
            done = [(guarded.uv, "guarded", free.iterations + guarded.iterations, guarded.excess_after)]
        if cfg.scaffold_above > 0 and not first and (not done or guarded.excess_after > cfg.scaffold_above):
            done += scaffold()  # the guard stalled later on: the lower of the two is kept
    if done:
        best = min(done, key=lambda d: d[3])
        return best[0], {"mode": best[1], "iterations": best[2], "excess": best[3]}
    return best_free, {"mode": "start", "iterations": free.iterations + guarded.iterations,
                       "excess": energy_excess(xyz, best_free, faces)}
