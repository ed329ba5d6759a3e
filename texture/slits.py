"""Slits: lower an island's distortion by cutting into it, not by adding islands.

A disk that is far from developable (a cap, a bag-like chart region) keeps a high
symmetric Dirichlet energy under SLIM however long it runs: area has to go somewhere.
A *slit* is a shortest edge path from the island's border to the vertex where the
relaxed map is most distorted; cutting along it keeps the island one disk (a path that
starts on the border and never returns to it) but lets the surface open there, like the
darts of a sewing pattern. :func:`slit_island` repeats: find the peak, cut, relax with
SLIM (:func:`texture.relax.relax_island`) from the map before the cut so that the slit
opens (or from a fresh conformal or Tutte map, :func:`_relaxed_cut`), until the energy
excess is below the target or ``max_slits`` were cut, and keeps the result only where it
lowered the energy.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from mnacore.triangles import signed_areas, triangle_areas

from .distortion_faces import face_geometry, symmetric_dirichlet
from .flatten import _cut_flags, is_disk, ordered_boundary, relax_disk, start_map
from .relax import RelaxConfig, boundary_edges, energy_excess, is_injective, relax_island

#: stop slitting an island after this many slits in a row that did not lower its energy.
MAX_MISSES = 2


@dataclass
class SlitResult:
    """Faces/UVs/positions of the (possibly) slit island; ``source (V,)``: vertex of the input island."""

    faces: np.ndarray
    uv: np.ndarray
    source: np.ndarray
    slits: int
    excess_before: float
    excess_after: float
    stopped_by_length: bool = False
    """the next slit would have reached ``max_length`` (:func:`slit_island`), above the target"""


def face_energy(xyz: np.ndarray, uv: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F,) ``tr g + tr g^-1 - 4`` per face of the map UV -> 3D (inf on degenerate faces)."""
    geom = face_geometry(xyz, faces, uv)
    e = np.full(len(faces), np.inf)
    v = geom.valid
    e[v] = symmetric_dirichlet(geom)[v] - 4.0
    return e


def slit_path(xyz: np.ndarray, faces: np.ndarray, energy: np.ndarray) -> list[int] | None:
    """Shortest path (3D edge length) from the border to the interior vertex of highest
    area-weighted mean face ``energy``; None when the island has no interior vertex."""
    V = len(xyz)
    border = np.zeros(V, bool)
    border[ordered_boundary(faces)] = True
    if border.all():
        return None
    area = triangle_areas(xyz, faces)
    # a degenerate face (infinite energy: the far end of a bag that the start map shrank to
    # nothing) is as distorted as any: it weighs as the most distorted finite face (at least
    # 1, an excess far above the bound, where every finite face is near isometric)
    finite = np.isfinite(energy)
    e = np.where(finite, energy, max(float(energy[finite].max()), 1.0) if finite.any() else 1.0)
    num = np.bincount(faces.ravel(), weights=np.repeat(e * area, 3), minlength=V)
    den = np.bincount(faces.ravel(), weights=np.repeat(area, 3), minlength=V)
    he = np.stack([faces, np.roll(faces, -1, axis=1)], -1).reshape(-1, 2)
    keep = ~(border[he[:, 0]] & border[he[:, 1]])  # never walk along (or across) the border
    he = he[keep]
    w = np.linalg.norm(xyz[he[:, 0]] - xyz[he[:, 1]], axis=1) + 1e-12
    g = sp.coo_matrix((w, (he[:, 0], he[:, 1])), shape=(V, V)).tocsr()
    g = g.maximum(g.T)
    dist, pred, src = dijkstra(g, indices=np.flatnonzero(border), min_only=True, return_predecessors=True)
    # the peak: distorted *and* deep inside (a free border already relaxes what lies near it;
    # what it cannot reach is where a cap or a bag closes, far from the border)
    energy_v = num / np.maximum(den, 1e-300)
    score = np.where(border | ~np.isfinite(dist), -np.inf, np.sqrt(np.maximum(energy_v, 0.0)) * dist)
    peak = int(np.argmax(score))
    if not np.isfinite(score[peak]):
        return None
    path = [peak]
    while not border[path[-1]]:
        path.append(int(pred[path[-1]]))
    return path[::-1]


def _embed(xyz: np.ndarray, faces: np.ndarray, cfg: RelaxConfig) -> tuple[np.ndarray | None, str]:
    """(A start (:func:`texture.flatten.start_map`) then SLIM at the isometric scale, or None
    if the start is not valid; :func:`texture.flatten.relax_disk`'s mode)."""
    # relax_disk makes the convex map its two-resolution path needs; SLIM starts here where that is refused
    uv = start_map(xyz, faces, cfg.slim_max_faces)
    signed = signed_areas(uv, faces)
    if not np.isfinite(uv).all() or (signed <= 0).any():
        return None, "start"
    uv *= np.sqrt(triangle_areas(xyz, faces).sum() / signed.sum())
    got, stats = relax_disk(xyz, uv, faces, cfg)
    return got, stats["mode"]


def _opened(xyz: np.ndarray, faces: np.ndarray, closed: np.ndarray, cfg: RelaxConfig) -> np.ndarray | None:
    """The slit island relaxed from its map before the cut (``closed``: the two sides of the
    slit on top of each other), or None where no injective map came of it.

    Free SLIM opens the slit where that lowers the energy, from a map that is already relaxed
    everywhere else: a fresh start (conformal or Tutte) has to relax the whole island again,
    and on a large irregular island it can end, within the iterations a merge trial affords,
    above the uncut island (measured in docs/unwrap.md). Where the opened sides still touch
    or cross somewhere (they start on top of each other), the crossing is repaired in place
    (:func:`texture.multires.untangle`, then :func:`texture.multires.polish`)."""
    from .islands import vertex_adjacency
    from .multires import polish, untangle

    run = relax_island(xyz, closed, faces, cfg, check_crossings=False)
    if is_injective(run.uv, faces):
        return run.uv
    tried = [run.valid_uv] if run.valid_uv is not None else []
    if np.isfinite(run.uv).all() and (signed_areas(run.uv, faces) > 0).all():
        adj = vertex_adjacency(faces, len(xyz))
        edges = boundary_edges(faces)
        fixed = untangle(run.uv, faces, ordered_boundary(faces), adj, edges, xyz)
        if fixed is not None:
            # the repair squashes the faces around the crossing: guarded SLIM relaxes them again
            tried.append(relax_island(xyz, polish(xyz, *fixed, faces, adj, edges), faces, cfg).uv)
    tried = [u for u in tried if is_injective(u, faces)]
    return min(tried, key=lambda u: energy_excess(xyz, u, faces)) if tried else None


def _relaxed_cut(xyz: np.ndarray, faces: np.ndarray, closed: np.ndarray, cfg: RelaxConfig,
                 embed_cfg: RelaxConfig | None = None) -> tuple[np.ndarray | None, float, str | None]:
    """(UVs of the slit island, their energy excess, the fresh embedding's relax_disk mode or
    None where none ran), (None, inf, mode) where no map was found. ``embed_cfg``: the SLIM
    options of the fresh embedding (default ``cfg``).

    The slit opened from the relaxed map (:func:`_opened`) first: SLIM descends from the
    map before the cut, so it keeps what was relaxed. Where the opened map is no better
    than the closed one, the slit's sides wanted to overlap (around a saddle there is more
    angle than in a plane; around a cap, less), and a fresh embedding (:func:`_embed`),
    which may leave that local optimum, is tried too; the better is kept. Above
    ``cfg.multires_faces`` faces only the fresh embedding runs (SLIM on the whole island from
    the closed map would cost minutes)."""
    opened = None if 0 < cfg.multires_faces < len(faces) else _opened(xyz, faces, closed, cfg)
    tried = [] if opened is None else [(opened, float(energy_excess(xyz, opened, faces)))]
    mode = None
    if not tried or tried[0][1] >= energy_excess(xyz, closed, faces):
        fresh, mode = _embed(xyz, faces, cfg if embed_cfg is None else embed_cfg)
        if fresh is not None:
            tried.append((fresh, float(energy_excess(xyz, fresh, faces))))
    return (*min(tried, key=lambda t: t[1]), mode) if tried else (None, np.inf, mode)


def slit_island(xyz: np.ndarray, faces: np.ndarray, uv: np.ndarray, cfg: RelaxConfig, target: float,
                max_slits: int, max_length: float = np.inf) -> SlitResult:
    """Cut up to ``max_slits`` slits while the energy excess exceeds ``target``; see module docstring.

    ``max_length``: the 3D length the slits together must stay under (each adds its path's
    length of seam). A slit that would reach it is not cut: a caller that can only use the
    island if its seams stay short (a merge trial) stops paying for relaxations it would
    refuse."""
    import igl

    faces = np.asarray(faces, np.int64)
    source = np.arange(len(xyz))
    before = energy_excess(xyz, uv, faces)
    best = SlitResult(faces, uv, source, 0, before, before)
    cur_faces, cur_uv, cur_src = faces, uv, source
    misses, length = 0, 0.0
    # above cfg.multires_faces a slit's fresh embedding is made in two resolutions only, and
    # where they fail the island is not slit further: the split stage halves what stays above
    # the bound, into halves where SLIM is cheaper. Plain SLIM there (and the scaffold its free
    # run then needs) cost 35-55 s a slit on a 30k-face island of an unseen scan (the beast:
    # eight such slits, 289 s, left it at excess 0.244, and it was halved after all); what made
    # the coarse copy fail (a start map that squeezes most of the disk) is the island's shape,
    # which one more slit path leaves as it is (7 of 7 retries failed again, 2-12 s each)
    embed_cfg = replace(cfg, slim_max_faces=cfg.multires_faces) if cfg.multires_faces > 0 else cfg
    for k in range(max_slits):
        if best.excess_after <= target:
            break
        p = xyz[cur_src]
        path = slit_path(p, cur_faces, face_energy(p, cur_uv, cur_faces))
        if path is None or len(path) < 2:
            break
        length += float(np.linalg.norm(np.diff(p[path], axis=0), axis=1).sum())
        if length >= max_length:
            best = replace(best, stopped_by_length=True)
            break
        _, new_faces, src = igl.cut_mesh(p, cur_faces, _cut_flags(cur_faces, [path]))
        new_faces = np.asarray(new_faces, np.int64)
        if not is_disk(new_faces):
            break
        new_src = cur_src[np.asarray(src, np.int64)]
        new_uv, excess, mode = _relaxed_cut(xyz[new_src], new_faces, cur_uv[np.asarray(src, np.int64)], cfg, embed_cfg)
        if new_uv is None or (mode == "start" and 0 < cfg.multires_faces < len(new_faces)):
            break  # no map, or two resolutions failed on a large island (above)
        cur_faces, cur_uv, cur_src = new_faces, new_uv, new_src
        if excess < best.excess_after:
            best = SlitResult(cur_faces, cur_uv, cur_src, k + 1, before, excess)
            misses = 0
        else:
            misses += 1
            if misses >= MAX_MISSES:  # two slits that did not help: halving will do better
                break
    return best
