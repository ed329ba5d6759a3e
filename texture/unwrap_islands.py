"""Island-level steps of :mod:`texture.unwrap`: regions -> flattened, relaxed, slit, split islands.

Every function takes the unwrap's config (:class:`texture.unwrap.UnwrapConfig`) and
works on :class:`Island` lists; positions are in the unit-ball frame and UVs at the
isometric scale (UV area = 3D area), so all islands share one texel density.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mnacore.triangles import isometric_triangle, signed_areas, triangle_areas

from .flatten import cut_to_disk, holed_map, relax_disk, split_pinched, start_map
from .holes import cut_seam, flatten_filled
from .meshprep import face_components
from .parallel import parallel_map
from .relax import RelaxConfig, energy_excess, is_injective, relax_island
from .slits import slit_island


@dataclass
class Island:
    """One flattened island: ``faces (Fi, 3)`` into ``uv (Vi, 2)``; ``work_faces (Fi,)``
    working face of each face; ``work_vertex (Vi,)`` working vertex of each vertex."""

    faces: np.ndarray
    uv: np.ndarray
    xyz: np.ndarray
    work_faces: np.ndarray
    work_vertex: np.ndarray
    label: int
    kept_start: bool = False
    """Its relaxation failed and kept its start (:func:`texture.flatten.relax_disk`):
    no slits (they cut toward a relaxed map's distortion peak), the split stage halves it."""
    holed: bool = False
    """Flattened uncut with its holes (:func:`texture.flatten.holed_map`, within the bound it
    was given): the disk steps (SLIM, slits) leave it as it is."""
    slits: int = 0
    """Slits cut into it (:func:`slit_islands`): its relaxed map alone missed ``cfg.slit_target``."""


def _fiedler_halves(vertices: np.ndarray, faces: np.ndarray) -> list[np.ndarray] | None:
    """Two halves (equal area) along the Fiedler vector of the face graph, edges weighted by
    their 3D length: a balanced cut with a short border (spectral bisection). None if the
    eigen-solve fails."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import eigsh

    from .regions import face_adjacency

    adj = face_adjacency(vertices, faces)
    F = len(faces)
    if F < 4 or len(adj.a) == 0:
        return None
    w = sp.coo_matrix((adj.length + 1e-12, (adj.a, adj.b)), shape=(F, F)).tocsr()
    w = w + w.T
    lap = sp.diags(np.asarray(w.sum(1)).ravel()) - w
    try:
        # shift-invert just below 0: the two smallest eigenpairs of the (PSD) Laplacian
        _, vec = eigsh(lap.tocsc(), k=2, sigma=-1e-6, which="LM", v0=np.ones(F))
    except Exception:  # ARPACK / factorisation failures: the caller falls back to the axis
        return None
    f = vec[:, 1]
    area = triangle_areas(vertices, faces)
    order = np.argsort(f, kind="stable")
    cut = int(np.searchsorted(np.cumsum(area[order]), 0.5 * area.sum()))
    lo = np.zeros(F, bool)
    lo[order[:max(1, min(cut, F - 1))]] = True
    return [np.flatnonzero(lo), np.flatnonzero(~lo)]


#: islands are halved by "spectral" bisection (Fiedler vector, short border), then by "axis"
#: (longest axis) when that halving is rejected; "axis": only the latter.
SPLIT = "spectral"
#: a halving may raise the atlas's distortion at most this factor on the way (see refine_islands).
BLOWUP = 3.0


def _split_halves(vertices: np.ndarray, faces: np.ndarray, method: str = "axis") -> list[np.ndarray]:
    """Face index sets of two halves of a region: spectral bisection (``method="spectral"``),
    or across its longest bounding-box axis (also when the spectral one fails)."""
    halves = _fiedler_halves(vertices, faces) if method == "spectral" else None
    if halves is not None:
        return halves
    c = vertices[faces].mean(1)
    axis = int(np.argmax(np.ptp(c, 0)))
    med = np.median(c[:, axis])
    lo = c[:, axis] <= med
    if lo.all() or not lo.any():
        lo = np.arange(len(faces)) < len(faces) // 2
    return [np.flatnonzero(lo), np.flatnonzero(~lo)]


def flatten_halves(xyz: np.ndarray, faces: np.ndarray, work_faces: np.ndarray, label: int, depth: int,
                   stats: dict, method: str = "axis", holed: HoledRule | None = None) -> list[Island]:
    """:func:`flatten_region` of each connected piece of the two halves of ``faces``."""
    out = []
    for half in _split_halves(xyz, faces, method):
        hv = face_components(faces[half])
        for h in np.unique(hv):
            part = half[hv == h]
            out += flatten_region(xyz, faces[part], work_faces[part], label, depth, stats, holed)
    return out


@dataclass(frozen=True)
class HoledRule:
    """When a disk with holes stays uncut (:func:`flatten_region`): its conformal map
    (:func:`texture.flatten.holed_map`) relaxed by free SLIM (``relax``) must stay an
    embedding within ``within`` energy excess; regions above ``max_faces`` faces are cut as
    usual (the two-resolution SLIM of large islands needs a disk)."""

    within: float
    relax: RelaxConfig
    max_faces: int
    max_slits: int = 0
    """slits of a region flattened with its small holes filled (:mod:`texture.holes`)"""


def holed_rule(cfg) -> HoledRule | None:
    """The unwrap config's :class:`HoledRule` (the bound every island is flattened to,
    ``cfg.slit_target``; SLIM alone up to ``cfg.slim_max_faces``), or None where
    ``cfg.holed_islands`` is off."""
    if not cfg.holed_islands:
        return None
    return HoledRule(cfg.slit_target, relax_config(cfg), cfg.slim_max_faces, cfg.max_slits)


def _holed(p: np.ndarray, f: np.ndarray, rule: HoledRule | None) -> np.ndarray | None:
    """The region's uncut map at the isometric scale (:func:`texture.flatten.holed_map`, then
    free SLIM) when ``rule`` keeps it, else None."""
    if rule is None or len(f) > rule.max_faces:
        return None
    uv = holed_map(p, f)
    if uv is None:
        return None
    uv *= np.sqrt(triangle_areas(p, f).sum() / signed_areas(uv, f).sum())
    if energy_excess(p, uv, f) > rule.within:
        uv = relax_island(p, uv, f, rule.relax, check_crossings=False).uv
    return uv if is_injective(uv, f) and energy_excess(p, uv, f) <= rule.within else None


def flatten_region(xyz: np.ndarray, faces: np.ndarray, work_faces: np.ndarray, label: int,
                    depth: int, stats: dict, holed: HoledRule | None = None,
                    max_added: float = np.inf) -> list[Island]:
    """Disk-cut and embed one connected region (``faces`` index ``xyz``; conformal where
    that is an embedding, else Tutte: :func:`texture.flatten.start_map`); see module docstring.
    ``holed``: a piece that is a disk with holes is kept uncut (a ``holed`` island) where
    the :class:`HoledRule` allows. ``max_added``: the seam a flattening with holes filled
    may add (:func:`texture.holes.flatten_filled`)."""
    vid, inv = np.unique(faces, return_inverse=True)
    local = inv.reshape(-1, 3)
    split, src = split_pinched(local)
    out = []
    pieces = face_components(split)
    for comp in np.unique(pieces):  # a pinch split can separate pieces
        sel = np.flatnonzero(pieces == comp)
        cv, ci = np.unique(split[sel], return_inverse=True)
        f = ci.reshape(-1, 3)
        p = xyz[vid[src[cv]]]
        uncut = _holed(p, f, holed)
        if uncut is not None:
            stats["holed"] = stats.get("holed", 0) + 1
            out.append(Island(f, uncut, p, work_faces[sel], vid[src[cv]], label, holed=True))
            continue
        try:
            disk = cut_to_disk(p, f)
        except (RuntimeError, ValueError, KeyError, IndexError):
            disk = None
        # the filled flattening is kept only where it adds no more seam than the cuts to a disk
        # it saves: its slits stop there (and it is dropped) instead of being relaxed for nothing
        fill = holed is not None and len(f) <= holed.max_faces
        saves = cut_seam(p, f, disk) if fill and disk is not None else np.inf
        filled = flatten_filled(p, f, holed.relax, holed.within, holed.max_slits, min(max_added, saves)) if fill else None
        if filled is not None and filled.added <= saves:
            # relaxed and slit already: the disk steps leave it as it is
            stats["filled"] = stats.get("filled", 0) + 1
            stats["cut_edges"] += filled.cut_edges
            out.append(Island(filled.faces, filled.uv, p[filled.source], work_faces[sel],
                              vid[src[cv]][filled.source], label, holed=True))
            continue
        try:
            if disk is None:
                raise RuntimeError("the region could not be cut to a disk")
            if len(disk.faces) == 1:  # SLIM needs two faces: place a lone triangle isometrically
                uv = np.zeros((len(disk.source), 2))
                uv[disk.faces[0]] = isometric_triangle(p[disk.source][disk.faces[0]])
            else:
                uv = start_map(p[disk.source], disk.faces)
            if not np.isfinite(uv).all() or (signed_areas(uv, disk.faces) <= 0).any():
                raise RuntimeError("start embedding folded (numerically)")
        except (RuntimeError, ValueError, KeyError, IndexError):
            if depth <= 0:
                raise
            stats["region_splits"] += 1
            out += flatten_halves(xyz, vid[src[cv]][f], work_faces[sel], label, depth - 1, stats,
                                  holed=holed)
            continue
        stats["cut_edges"] += disk.cut_edges
        xyz_d = p[disk.source]
        area3, area_uv = triangle_areas(xyz_d, disk.faces).sum(), signed_areas(uv, disk.faces).sum()
        uv *= np.sqrt(area3 / area_uv)
        out.append(Island(disk.faces, uv, xyz_d, work_faces[sel], vid[src[cv]][disk.source], label))
    return out


#: label of the islands of a component flattened whole (:func:`whole_components`).
WHOLE = -1
#: below this many faces in all, islands are relaxed in this process: starting workers costs
#: more than SLIM on them (:func:`relax_islands`; merge trials run ahead only from there too)
POOL_FACES = 2000


def whole_components(xyz, work_faces, comp, reg, cfg, fstats: dict) -> tuple[list[Island], set]:
    """(islands, components): components the charts split into several regions that flatten
    *whole* (cut to a disk, embedded, SLIM, slits) within ``cfg.slit_target`` energy excess.

    The charts are fitted to the whole shape, so on a many-part shape one chart often
    covers halves of several small parts (a wheel split between two charts); a part that
    flattens as one island needs no seam between them. Tried on components of at most
    ``cfg.whole_max_faces`` faces. Slits are cut here already (they are kept).
    """
    pairs = np.unique(np.stack([comp, reg], 1), axis=0)
    n_reg = np.bincount(pairs[:, 0], minlength=int(comp.max()) + 1)
    sizes = np.bincount(comp)
    trial: dict[int, list[Island]] = {}
    for c in np.flatnonzero((n_reg > 1) & (sizes <= cfg.whole_max_faces)):
        sel = np.flatnonzero(comp == c)
        try:
            trial[int(c)] = flatten_region(xyz, work_faces[sel], sel, WHOLE, 0, {"region_splits": 0, "cut_edges": 0},
                                           holed_rule(cfg))
        except (RuntimeError, ValueError, KeyError, IndexError):
            continue
    tried = [isl for isls in trial.values() for isl in isls]
    relax_islands(tried, cfg)
    slit_islands(tried, cfg)
    islands, whole = [], set()
    for c, isls in list(trial.items()):
        if all(energy_excess(isl.xyz, isl.uv, isl.faces) <= cfg.slit_target for isl in isls):
            whole.add(c)
            islands += isls
            del trial[c]
    fstats["whole_trials"] = trial  # the rest, for prefer_whole once the chart regions are flat
    return islands, whole


def _contribution(isls: list[Island]) -> float:
    """Sum of 3D area times energy excess (inf if an island has a degenerate UV face)."""
    return float(sum(triangle_areas(i.xyz, i.faces).sum() * energy_excess(i.xyz, i.uv, i.faces) for i in isls))


def prefer_whole(islands: list[Island], trials: dict, comp: np.ndarray) -> tuple[list[Island], int]:
    """Replace a component's chart-region islands by its whole flattening (``trials``: component
    -> islands of :func:`whole_components` that missed ``slit_target``) when that distorts less
    (area times excess): the charts' cut did not help there. Returns (islands, components swapped)."""
    swapped = 0
    for c, whole in trials.items():
        mine = [isl for isl in islands if isl.label != WHOLE and comp[isl.work_faces[0]] == c]
        if mine and _contribution(whole) < _contribution(mine):
            islands = [isl for isl in islands if isl.label == WHOLE or comp[isl.work_faces[0]] != c] + whole
            swapped += 1
    return islands, swapped


def relax_config(cfg, coarse_excess_limit: float = 0.0) -> RelaxConfig:
    """The SLIM options of an :class:`texture.unwrap.UnwrapConfig` (``coarse_excess_limit``:
    :attr:`texture.relax.RelaxConfig.coarse_excess_limit`)."""
    return RelaxConfig(iterations=cfg.slim_iterations, min_gain=cfg.slim_min_gain, multires_faces=cfg.multires_faces,
                       slim_max_faces=cfg.slim_max_faces, coarse_excess_limit=coarse_excess_limit,
                       scaffold_above=cfg.slit_target if cfg.scaffold else 0.0)


def _relax_job(job, _shared=None):
    xyz, uv, faces, rcfg = job
    return relax_disk(xyz, uv, faces, rcfg)


def relax_islands(islands: list[Island], cfg, coarse_excess_limit: float = 0.0) -> dict:
    """SLIM every island (:func:`texture.flatten.relax_disk`), largest first, in parallel
    processes (``coarse_excess_limit``: :attr:`texture.relax.RelaxConfig.coarse_excess_limit`)."""
    rcfg = relax_config(cfg, coarse_excess_limit)
    order = sorted((i for i in range(len(islands)) if not islands[i].holed), key=lambda i: -len(islands[i].faces))
    jobs = [(islands[i].xyz, islands[i].uv, islands[i].faces, rcfg) for i in order]
    done = parallel_map(_relax_job, jobs, parallel=sum(len(j[2]) for j in jobs) >= POOL_FACES and len(jobs) > 1)
    st = {"iterations_max": 0, "free": 0, "guarded": 0, "scaffold": 0, "kept_start": 0, "multires": 0}
    for i, (uv, s) in zip(order, done):
        islands[i].uv = uv
        islands[i].kept_start = s["mode"] == "start"
        st["iterations_max"] = max(st["iterations_max"], s["iterations"])
        st["kept_start" if s["mode"] == "start" else s["mode"]] += 1
    return st


def _slit_job(job, _shared=None):
    xyz, faces, uv, rcfg, target, max_slits, max_length = job
    return slit_island(xyz, faces, uv, rcfg, target, max_slits, max_length)


def slit_islands(islands: list[Island], cfg, max_length: list[float] | None = None) -> dict:
    """Slits in every island whose energy excess exceeds ``cfg.slit_target`` (in parallel
    processes); ``max_length``: per island, the length its slits together must stay under
    (:func:`texture.slits.slit_island`; default none)."""
    rcfg = relax_config(cfg)
    limit = max_length if max_length is not None else [np.inf] * len(islands)
    todo = [i for i, isl in enumerate(islands)
            if cfg.max_slits > 0 and not isl.kept_start and not isl.holed and energy_excess(isl.xyz, isl.uv, isl.faces) > cfg.slit_target]
    jobs = [(islands[i].xyz, islands[i].faces, islands[i].uv, rcfg, cfg.slit_target, cfg.max_slits, limit[i])
            for i in todo]
    done = parallel_map(_slit_job, jobs, parallel=len(jobs) > 1)
    st = {"islands_slit": 0, "slits": 0, "excess_before": [], "excess_after": []}
    for i, r in zip(todo, done):
        st["excess_before"].append(r.excess_before)
        st["excess_after"].append(r.excess_after)
        if r.slits == 0:
            continue
        isl = islands[i]
        isl.faces, isl.uv, isl.xyz = r.faces, r.uv, isl.xyz[r.source]
        isl.work_vertex = isl.work_vertex[r.source]
        isl.slits += r.slits
        st["islands_slit"] += 1
        st["slits"] += r.slits
    return st


def overlaps_itself(isl: Island) -> bool:
    """Whether the island's map folds over itself: a face turned over, its border crossing
    itself, or a hole loop running counter-clockwise (:func:`texture.relax.is_injective`; a
    face of zero UV area, a sliver, is not counted here)."""
    return not is_injective(isl.uv, isl.faces, slivers=True)


def audit_islands(islands: list[Island], xyz: np.ndarray, work_faces: np.ndarray, cfg) -> tuple[list[Island], dict]:
    """Every island checked before packing (:func:`overlaps_itself`); one that overlaps itself
    is flattened again from its faces as a disk (cut, a conformal or Tutte start, then SLIM
    that keeps it injective: :func:`flatten_region` without holed islands, :func:`relax_islands`).

    Every path that makes an island is meant to keep its map injective; this is the net under
    them, as no check short of one like this saw the hole that lapped over itself (a map of a
    plate with holes). ``stats``: how many islands were flattened again, and how many of
    those could not be (kept as they were: the harness's overlap then shows them)."""
    out, stats = [], {"reflattened": 0, "reflatten_failed": 0}
    for isl in islands:
        if len(isl.faces) < 2 or not overlaps_itself(isl):
            out.append(isl)
            continue
        fstats = {"region_splits": 0, "cut_edges": 0}
        try:
            new = flatten_region(xyz, work_faces[isl.work_faces], isl.work_faces, isl.label, cfg.max_split_depth, fstats)
        except (RuntimeError, ValueError, KeyError, IndexError):
            new = []
        relax_islands(new, cfg)
        if new and not any(overlaps_itself(i) for i in new):
            out += new
            stats["reflattened"] += 1
        else:
            out.append(isl)
            stats["reflatten_failed"] += 1
    return out, stats
