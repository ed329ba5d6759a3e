"""Merging neighbouring islands whose union flattens as well: fewer seams where the charts cut more than needed.

The charts are fitted for the reconstruction, not for seams: three charts on a torus leave
four regions whose borders, laid end to end, are three times the two loops that cut a torus
to a disk, and each region flattens far below the distortion the unwrap accepts. So after
the regions are flattened, relaxed and slit, :func:`merge_islands` tries to join neighbours:
the union of two islands that share a border is cut to a disk, embedded, relaxed and slit
like any region (:func:`texture.unwrap_islands.flatten_region`), and it replaces the two when

- every island it gives stays within ``cfg.slit_target`` energy excess: the bound every
  island of the unwrap is flattened to (slits are cut up to it, a component is kept whole
  within it); and
- its seams are shorter than the two islands' together (a union that is not a disk needs
  cuts, and slits add seams: the border it removes must pay for them).

Two islands whose mean energy excess (area-weighted) is above ``cfg.slit_target`` are not
tried (:func:`_pairs`: the union's map restricted to each is a map of it); nor is a union
holding one refused before for its distortion where the rest of it cannot dilute that
trial's strain to the bound (:func:`_holds_failed`, the same rule with the refused trial's
map for the part it covered). Neighbours are
tried in order of the border they share (longest first), in rounds: each
round a matching (no island in two pairs) is flattened at once (in parallel processes), the
accepted pairs are merged, and a pair that failed is not tried again unless one side changed.
Rounds go on until no untried pair is left, also after a round that merged nothing: the
pairs its matching left out are tried next (bob: 1 trial and no merge before, 6 trials and
3 merges now, seam 6.68 -> 5.22).
A round with fewer trials than worker processes also runs, on the idle ones, the trials the
next round makes if all of this round's are refused (:func:`_ahead`); a trial is the same
whenever its islands are, so the next round uses what ran ahead on islands still there
instead of running it again. Refused trials are most of the stage's time and late rounds
often hold one trial, so this shortens the stage without changing any result (lion
113.7 -> 84.4 s, elephant 83.1 -> 73.1 s, the same unwraps: benchmarks/RESULTS.md); where a
trial merges, what ran ahead on its islands is dropped.
A union above ``cfg.merge_max_faces`` faces gets a cheaper trial (for time only: a trial
costs a flattening of both islands again, and a failed two-resolution flattening falls back to
SLIM at about a second per iteration at 50k faces): no slits, and no full-resolution SLIM where
the two-resolution flattening (:mod:`texture.multires`) fails or its coarse map already misses
the bound. It is tried only where that can pass (:func:`_cheap_union`): neither island was slit,
the two make a disk (no cut), and the union's total curvature is at most that of a spherical
cap that flattens within the bound (:data:`CAP_CURVATURE`). The 1M-face bunny's unions
(7.9 and 8.7 radians) are not tried (they failed, at 37 s, when they were).
A part of three or more islands that passes the same test whole is tried whole in the first
round (:func:`_whole_groups`): a pair at a time, a 1M-face heightfield was flattened again
at every round as its union grew (656k, 957k and 1M faces: 121 s; whole: one trial, 49 s).
With both, an unseen 65k-face heightfield (gentle waves: total curvature under 1 radian for
every union) went from 5 islands, seam 7.0, utilisation 0.50 to 2 islands, seam 0.79,
utilisation 0.80, and 31.8 -> 11.3 s (benchmarks/RESULTS.md).
A trial relaxes with at most ``MERGE_ITERATIONS`` SLIM
iterations (stopping early only makes the bound harder to meet) and takes as many slits as
any island may (``cfg.max_slits``): the seam test above already makes a union pay for every
slit it takes, so a cap on slits only refused unions that save more border than their slits
cost (bob: a union saving 3.3 of seam stayed at excess 0.109 after two slits; with the
island's own cap the atlas went 5 -> 4 islands, seam 5.59 -> 4.88, spot 4 -> 3 islands,
seam 5.22 -> 4.05, distortion_metric 0.068 -> 0.101);
a union whose disk cuts alone cost the border it removes is refused before relaxing, and
its slits stop where their length would use up the rest of that border (the trial would
be refused after them: the merges are the same, the refused trials cost less).

On the 13 benchmark fits (1000 steps) this merged 10 pairs on 6 meshes (torus seam 6.64 ->
4.77, sphere 2.90 -> 2.50, bunny 4.37 -> 4.00) and left distortion_metric at most 0.114
(the issue's bound is 0.15); with one slit per trial 6 of the 10 were lost.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from mnacore.triangles import triangle_areas

from .flatten import is_disk
from .islands import edge_keys, edge_use_counts, half_edges
from .parallel import default_workers
from .relax import boundary_edges, energy_excess
from .unwrap_islands import POOL_FACES, HoledRule, Island, flatten_region, holed_rule, relax_islands, slit_islands

#: SLIM iterations of a trial's relaxations
MERGE_ITERATIONS = 60
#: total curvature (radians) of a spherical cap whose best map has energy excess
#: ``CAP_EXCESS`` (the default ``slit_target``): 83 degrees of arc. Measured (libigl SLIM on
#: caps of a 5-times subdivided icosahedron): 60 degrees (pi) 0.026, 70 (4.13) 0.049, 80 (5.19)
#: 0.087, 90 (2 pi) 0.138. The excess grows about as the curvature squared (2.2-2.4 measured), so
#: another bound scales it by the square root.
CAP_CURVATURE = 5.5
CAP_EXCESS = 0.1


@dataclass(frozen=True)
class InteriorEdges:
    """The working mesh's edges used by two faces, as sorted integer keys ``lo * base + hi`` of
    their working vertices: where an island border is a seam (an edge used once is the
    surface's own open border)."""

    keys: np.ndarray
    base: int

    def contain(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Whether each working-vertex pair ``(a, b)`` is one of these edges."""
        return np.isin(np.minimum(a, b) * self.base + np.maximum(a, b), self.keys)


def interior_edges(work_faces: np.ndarray) -> InteriorEdges:
    """:class:`InteriorEdges` of the working mesh ``work_faces``."""
    base = int(work_faces.max()) + 1
    keys = edge_keys(np.arange(base), work_faces)
    return InteriorEdges(np.unique(keys[edge_use_counts(keys) >= 2]), base)


def island_seam(isl: Island, interior: InteriorEdges) -> float:
    """Half the 3D length of ``isl``'s border edges that are seams (each seam edge borders two
    island sides: here or in a neighbour), as the harness counts seams."""
    he = half_edges(isl.faces)
    border = he[edge_use_counts(edge_keys(np.arange(len(isl.uv)), isl.faces)) == 1]
    seam = interior.contain(isl.work_vertex[border[:, 0]], isl.work_vertex[border[:, 1]])
    length = np.linalg.norm(isl.xyz[border[:, 0]] - isl.xyz[border[:, 1]], axis=1)
    return 0.5 * float(length[seam].sum())


def _border_seam(faces: np.ndarray, xyz: np.ndarray, interior: InteriorEdges) -> float:
    """:func:`island_seam` of the working faces ``faces`` as one uncut island."""
    used = np.unique(faces)
    local = np.searchsorted(used, faces)
    return island_seam(Island(local, np.zeros((len(used), 2)), xyz[used], np.zeros(0, np.int64), used, 0), interior)


def _shared_borders(islands: list[Island], adj, n_faces: int) -> dict[tuple[int, int], float]:
    """(island i, island j) with i < j -> 3D length of the working-mesh edges between them."""
    owner = np.full(n_faces, -1)
    for k, isl in enumerate(islands):
        owner[isl.work_faces] = k
    a, b = owner[adj.a], owner[adj.b]
    cross = (a != b) & (a >= 0) & (b >= 0)
    n = len(islands)
    pair = np.minimum(a[cross], b[cross]) * n + np.maximum(a[cross], b[cross])
    keys, inv = np.unique(pair, return_inverse=True)
    length = np.bincount(inv.reshape(-1), weights=adj.length[cross], minlength=len(keys))
    return {(int(k // n), int(k % n)): float(w) for k, w in zip(keys, length)}


def _strain(isl: Island, keep: np.ndarray | None = None) -> tuple[float, float]:
    """(3D area, area times energy excess) of an island, or of its faces ``keep`` (a mask)."""
    faces = isl.faces if keep is None else isl.faces[keep]
    if len(faces) == 0:
        return 0.0, 0.0
    area = float(triangle_areas(isl.xyz, faces).sum())
    return area, area * float(energy_excess(isl.xyz, isl.uv, faces))


@dataclass(frozen=True)
class FailedUnion:
    """A trial refused for its distortion: its working faces (a mask) and the strain of its
    flattened islands together (:func:`_strain`: area, area times excess)."""

    faces: np.ndarray
    area: float
    strain: float


def _faces_mask(isls: list[Island], n_faces: int) -> np.ndarray:
    """The working faces of ``isls`` as a mask over the ``n_faces`` working faces."""
    mask = np.zeros(n_faces, bool)
    for isl in isls:
        mask[isl.work_faces] = True
    return mask


def _holds_failed(isls: list[Island], failed: list[FailedUnion], n_faces: int, bound: float) -> bool:
    """Whether the union of ``isls`` holds a union refused before (:class:`FailedUnion`) whose
    strain, with the strain of the rest of the union in its islands' present maps, is above
    ``bound`` times the union's area: the rule :func:`_pairs` applies to two islands, with the
    refused trial's flattening standing for the part it covered. The union's map restricted
    to that part is a map of it, with one slit budget for all, so the union seldom does better
    there than the trial did; the rest can only dilute the excess by its area (the bunny's
    last trial: the whole part, holding two refused unions at 0.110 and 0.104, ended at 0.127
    after 8 slits, 10 of its unwrap's 28 s of merging)."""
    if not failed:
        return False
    inside = _faces_mask(isls, n_faces)
    for f in failed:
        if not inside[f.faces].all():
            continue
        rest = [_strain(isl, ~f.faces[isl.work_faces]) for isl in isls]
        area = f.area + sum(a for a, _ in rest)
        if f.strain + sum(s for _, s in rest) > bound * area:
            return True
    return False


def total_curvature(xyz: np.ndarray, faces: np.ndarray) -> float:
    """Gaussian curvature of the surface ``faces`` (into ``xyz``) summed over its interior
    vertices (their angle defects, libigl), in radians. On a disk it is 2 pi less its border's
    turning (Gauss-Bonnet): bumps and noise inside cancel, a dome or a saddle does not."""
    import igl

    k = igl.gaussian_curvature(np.ascontiguousarray(xyz, np.float64), np.ascontiguousarray(faces, np.int64))
    inner = np.zeros(len(xyz), bool)
    inner[faces] = True
    inner[boundary_edges(faces)] = False
    return float(k[inner].sum())


def _cheap_union(isls: list[Island], xyz: np.ndarray, work_faces: np.ndarray, bound: float) -> bool:
    """Whether a union above ``cfg.merge_max_faces`` faces is tried (it gets neither cuts nor
    slits: see the module docstring): islands that were not slit, that make a disk together
    (``work_faces``: the working mesh's), of total curvature (:func:`total_curvature`) at most
    that of a spherical cap that flattens within ``bound`` (:data:`CAP_CURVATURE`)."""
    if any(i.slits or i.kept_start for i in isls):
        return False
    union = work_faces[np.concatenate([i.work_faces for i in isls])]
    return abs(total_curvature(xyz, union)) <= CAP_CURVATURE * np.sqrt(bound / CAP_EXCESS) and is_disk(union)


def _whole_groups(islands: list[Island], shared: dict, cfg, strain: list, xyz: np.ndarray,
                  work_faces: np.ndarray) -> list[tuple[int, ...]]:
    """Three or more islands that are all of a part (connected by shared borders), above
    ``cfg.merge_max_faces`` faces together, within the bound on average (as :func:`_pairs`
    asks of two) and that :func:`_cheap_union` accepts: tried whole in the first round. Merged
    a pair at a time, such a part is flattened again at every round as its union grows (a
    1M-face heightfield: trials of 656k, 957k and 1M faces, 121 s)."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    if not shared:
        return []
    a, b = np.array(list(shared)).T
    n = len(islands)
    _, comp = connected_components(sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(n, n)), directed=False)
    out = []
    for c in np.unique(comp):
        g = tuple(np.flatnonzero(comp == c).tolist())
        if (len(g) >= 3 and sum(len(islands[k].faces) for k in g) > cfg.merge_max_faces
                and sum(strain[k][1] for k in g) <= cfg.slit_target * sum(strain[k][0] for k in g)
                and _cheap_union([islands[k] for k in g], xyz, work_faces, cfg.slit_target)):
            out.append(g)
    return out


def _pairs(islands: list[Island], shared: dict, failed: dict, cfg, strain: list, skipped: dict,
           xyz: np.ndarray, work_faces: np.ndarray, busy: set[int],
           refused: tuple[list[FailedUnion], dict] | None = None) -> list[tuple[int, int]]:
    """This round's pairs: neighbours by shared border, longest first, each island in one pair
    at most, none that failed before, none above ``cfg.merge_max_faces`` faces that
    :func:`_cheap_union` refuses (those go into ``failed``: refused until one side changes), and
    none whose islands' mean energy excess (``strain``: :func:`_strain` of each island) is above
    ``cfg.slit_target`` (those go into ``skipped``, by the islands' ids).

    The last rests on the union's map restricted to either island being a map of that
    island: with the same slit budget (``cfg.max_slits``) for the two together, a union seldom
    flattens an island better than the island's own relaxed and slit map did (only where its
    cut or slits fall inside it), so its area-weighted excess is about at least the two
    islands' mean, and its largest island's at least that. Islands within the bound always
    pass. It skips the trials on a surface no few islands can flatten (crumpled below its
    face size) and next to an island whose own slits stopped short of the bound; the trials
    it saved, and that it lost no merge, are measured in docs/unwrap.md. ``busy``: islands
    already in this round's trials (updated). ``refused``: (the trials refused for their
    distortion so far, a dict that receives the pairs skipped for holding one:
    :func:`_holds_failed`, the same rule with a refused trial's map for the part it covered);
    such a pair goes into ``failed`` too.
    """
    out = []
    for p, q in sorted(shared, key=lambda pq: (-shared[pq], pq)):
        strained = strain[p][1] + strain[q][1] > cfg.slit_target * (strain[p][0] + strain[q][0])
        if strained:
            skipped[(id(islands[p]), id(islands[q]))] = (islands[p], islands[q])
        if (p in busy or q in busy or (id(islands[p]), id(islands[q])) in failed
                or islands[p].kept_start or islands[q].kept_start or strained):
            continue
        if refused is not None and _holds_failed([islands[p], islands[q]], refused[0], len(work_faces), cfg.slit_target):
            refused[1][(id(islands[p]), id(islands[q]))] = (islands[p], islands[q])
            failed[(id(islands[p]), id(islands[q]))] = (islands[p], islands[q])  # until one side changes
            continue
        if (len(islands[p].faces) + len(islands[q].faces) > cfg.merge_max_faces
                and not _cheap_union([islands[p], islands[q]], xyz, work_faces, cfg.slit_target)):
            failed[(id(islands[p]), id(islands[q]))] = (islands[p], islands[q])  # until one side changes
            continue
        busy.update((p, q))
        out.append((p, q))
    return out


def _union(islands: list[Island], group: tuple[int, ...], xyz, work_faces, interior: InteriorEdges, seam_pq: float,
           holed: HoledRule | None = None) -> tuple[list[Island], float]:
    """(the ``group``'s islands flattened as one region (cut to a disk, embedded), the seam
    length its slits must stay under), or ([], 0) where that fails or its cuts alone already
    cost the seams the union would save (slits only add more)."""
    sel = np.concatenate([islands[k].work_faces for k in group])
    # the union's own border seams, before any cut: what is left of the seam it saves is all
    # its cuts and slits may add (a flattening with its holes filled stops there, not after
    # eight slits: a 4.2k-face union of a cow spent 17.5 s on them, then was refused)
    border = _border_seam(work_faces[sel], xyz, interior)
    if border >= seam_pq:
        return [], 0.0
    try:
        new = flatten_region(xyz, work_faces[sel], sel, islands[group[0]].label, 0,
                             {"region_splits": 0, "cut_edges": 0}, holed, seam_pq - border)
    except (RuntimeError, ValueError, KeyError, IndexError):
        return [], 0.0
    spare = seam_pq - sum(island_seam(i, interior) for i in new)
    return (new, spare) if spare > 0 else ([], 0.0)


def _faces(islands: list[Island], group: tuple[int, ...]) -> int:
    """Faces of a trial's union."""
    return sum(len(islands[k].faces) for k in group)


def _key(islands: list[Island], group: tuple[int, ...]) -> tuple[int, ...]:
    """A trial's key: the ids of its islands (the same islands flatten the same union)."""
    return tuple(id(islands[k]) for k in group)


def _ahead(islands: list[Island], shared: dict, todo: list, failed: dict, cfg, strain: list, skipped: dict,
           xyz: np.ndarray, work_faces: np.ndarray, refused: tuple[list[FailedUnion], dict], idle: int) -> list:
    """Up to ``idle`` pairs to try this round besides ``todo``: those the next round tries if
    every trial of this one is refused (:func:`_pairs` with them failed; its bookkeeping on
    copies). A trial is the same whenever its islands are, so where they are still there and
    still chosen next round its result is used, not run again: a round of one trial leaves
    the other cores idle, and refused trials are most of the stage's time (57-88 % on the
    unseen meshes traced, 78 % on lion: benchmarks/RESULTS.md). Where a trial of this round merges, what ran ahead
    on its islands is dropped. So that the round takes no longer than its own trials would, a
    trial runs ahead only where it has no more faces than the round's largest (a trial's time
    grows with its union's faces: a larger one run ahead and not used took lilium's merge
    stage 0.6 -> 1.6 s) and that largest has ``POOL_FACES`` or more (below, starting workers
    costs more than the trials: the decimated knight's unions of 54 and 98 faces, 0.2 -> 1.2 s)."""
    size = max(_faces(islands, g) for g in todo)
    if idle <= 0 or size < POOL_FACES:
        return []
    assumed = dict(failed)
    for g in todo:
        if len(g) == 2:
            assumed[_key(islands, g)] = (islands[g[0]], islands[g[1]])
    nxt = _pairs(islands, shared, assumed, cfg, strain, dict(skipped), xyz, work_faces, set(),
                 (list(refused[0]), dict(refused[1])))
    return [g for g in nxt if _faces(islands, g) <= size][:idle]


def merge_islands(islands: list[Island], xyz: np.ndarray, work_faces: np.ndarray, adj, cfg,
                  note: Callable[[str], None] | None = None) -> tuple[list[Island], dict]:
    """(islands, stats): see the module docstring. ``adj``: the working mesh's face adjacency
    (:func:`texture.regions.face_adjacency`); ``cfg``: a :class:`texture.unwrap.UnwrapConfig`.
    ``note``: called at each round with a line saying how far the merge is (the stage bar's
    text: the stage can run a minute, refused trials most of it)."""
    st = {"merges": 0, "tried": 0, "seam_removed": 0.0, "trials": [], "skipped_strained": 0, "skipped_holding_refused": 0,
          "ran_ahead": 0, "ran_ahead_used": 0}
    if cfg.merge_max_faces <= 0 or len(islands) < 2:
        return islands, st
    # a union above the face cap gets the two-resolution flattening only: where that fails,
    # full-resolution SLIM would cost about a second per iteration (see the module docstring)
    slim_cap = cfg.merge_max_faces if cfg.slim_max_faces <= 0 else min(cfg.slim_max_faces, cfg.merge_max_faces)
    # trials keep the guarded run alone (no scaffold, texture.scaffold): a union whose free
    # map overlaps itself is a bag or saddle-rimmed region; the scaffold lays it out within
    # the bound, so it passes, and as one large ragged island it packs worse than its parts
    # (measured in docs/unwrap.md, step 6)
    trial_cfg = replace(cfg, slim_iterations=min(cfg.slim_iterations, MERGE_ITERATIONS), slim_max_faces=slim_cap,
                        scaffold=False)
    interior = interior_edges(work_faces)
    holed = holed_rule(cfg)
    seam = [island_seam(isl, interior) for isl in islands]
    strain = [_strain(isl) for isl in islands]
    # trials run ahead on cores a round leaves idle (:func:`_ahead`), by the ids of their
    # islands: (those islands, kept alive so that no id is reused, (flattened union, spare seam))
    ran: dict[tuple[int, ...], tuple[tuple[Island, ...], tuple[list[Island], float]]] = {}
    workers = default_workers()
    skipped: dict[tuple[int, int], tuple[Island, Island]] = {}  # pairs not tried for their strain
    # pairs of islands (by identity) whose union failed; the islands are kept with their ids, so
    # that an island merged away and freed cannot hand its id to a new one (which would then
    # pass for the failed pair's member and never be tried)
    failed: dict[tuple[int, int], tuple[Island, Island]] = {}
    refused: list[FailedUnion] = []  # trials refused for their distortion (:func:`_holds_failed`)
    held: dict[tuple[int, int], tuple[Island, Island]] = {}  # pairs skipped for holding one
    first, rounds = True, 0
    while True:  # each round merges a pair or fails one more: it ends when no pair is left
        shared = _shared_borders(islands, adj, len(work_faces))
        todo: list[tuple[int, ...]] = _whole_groups(islands, shared, cfg, strain, xyz, work_faces) if first else []
        first = False
        todo += _pairs(islands, shared, failed, cfg, strain, skipped, xyz, work_faces, {k for g in todo for k in g},
                       (refused, held))
        if not todo:
            break
        rounds += 1
        if note is not None:
            note(f"merge round {rounds}: {len(todo)} to try, {st['tried']} tried, {st['merges']} merged")
        ahead = _ahead(islands, shared, todo, failed, cfg, strain, skipped, xyz, work_faces, (refused, held),
                       workers - len(todo))
        fresh = [g for g in todo + ahead if _key(islands, g) not in ran]
        seam_run = [sum(seam[k] for k in g) for g in fresh]
        unions = [_union(islands, g, xyz, work_faces, interior, s, holed) for g, s in zip(fresh, seam_run)]
        flat = [isl for new, _ in unions for isl in new]
        relax_islands(flat, trial_cfg, cfg.slit_target)
        # a slit adds its length of seam: past the union's spare seam the trial is refused anyway;
        # a union above the face cap takes no slits (see the module docstring)
        small = [(isl, spare) for g, (new, spare) in zip(fresh, unions) for isl in new
                 if _faces(islands, g) <= cfg.merge_max_faces]
        slit_islands([isl for isl, _ in small], trial_cfg, [spare for _, spare in small])
        for g, u in zip(fresh, unions):
            ran[_key(islands, g)] = (tuple(islands[k] for k in g), u)
        st["ran_ahead"] += len(fresh) - sum(g in todo for g in fresh)
        st["ran_ahead_used"] += sum(g not in fresh for g in todo)
        seam_of = [sum(seam[k] for k in g) for g in todo]
        faces_of = [_faces(islands, g) for g in todo]
        trials = [ran.pop(_key(islands, g))[1][0] for g in todo]
        st["tried"] += len(todo)
        drop, add = set(), []
        for g, new, before, n in zip(todo, trials, seam_of, faces_of):
            excess = [float(energy_excess(i.xyz, i.uv, i.faces)) for i in new]
            new_seam = sum(island_seam(i, interior) for i in new) if new else float("inf")
            relaxed = bool(new) and not any(i.kept_start for i in new)  # a map made, not a start kept
            ok = relaxed and max(excess) <= cfg.slit_target
            st["trials"].append({"faces": n, "islands": len(g), "excess": max(excess, default=None), "seam_before": before,
                                 "seam_after": new_seam if new else None, "merged": ok and new_seam < before})
            if st["trials"][-1]["merged"]:
                drop.update(g)
                add += new
                st["merges"] += len(g) - 1
                st["seam_removed"] += before - new_seam
            elif len(g) == 2:
                failed[(id(islands[g[0]]), id(islands[g[1]]))] = (islands[g[0]], islands[g[1]])
            if relaxed and np.isfinite(excess).all() and max(excess) > cfg.slit_target:
                # refused for its distortion: a union holding it is judged by it (:func:`_holds_failed`)
                parts = [_strain(i) for i in new]
                refused.append(FailedUnion(_faces_mask([islands[k] for k in g], len(work_faces)),
                                           sum(a for a, _ in parts), sum(s for _, s in parts)))
        keep = [k for k in range(len(islands)) if k not in drop]
        islands = [islands[k] for k in keep] + add
        alive = {id(isl) for isl in islands}
        ran = {k: v for k, v in ran.items() if all(id(isl) in alive for isl in v[0])}
        seam = [seam[k] for k in keep] + [island_seam(i, interior) for i in add]
        strain = [strain[k] for k in keep] + [_strain(i) for i in add]
    st["skipped_strained"] = len(skipped)
    st["skipped_holding_refused"] = len(held)
    return islands, st
