"""Packing one layout of the unwrap's islands: the turns it is packed in, and packing it.

The pieces the unwrap's packing search (:mod:`texture.unwrap_layout`) is made of: the
islands' outlines as the packer takes them (:func:`outline_arrays`), a layout packed for real
in one of the :data:`PACK_MODES` (:func:`best_packed`), the search over the largest islands'
quarter turns (:func:`quarter_turned`), and the chosen layout packed once more with xatlas's
exhaustive placement (:func:`brute_packed`). Why each exists, and what it gained on the
benchmark fits, is told in :mod:`texture.unwrap_layout`.
"""
from __future__ import annotations

import itertools
import weakref
from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from mnacore.triangles import triangle_areas

from .outlines import island_outlines
from .pack import Packing, pack_islands
from .scale_search import GUESS_UTILIZATION, coarse_size, estimate_layouts, plan_layouts
from .similarity import similarity_fit
from .unwrap_islands import Island

#: (turn every island to its minimum-area bounding rectangle first, xatlas PackOptions); the
#: last: every turn chosen here (:func:`quarter_turned`), xatlas only translates
PACK_MODES: tuple[tuple[bool, dict], ...] = (
    (False, {}),
    (False, {"rotate_charts": False}),
    (True, {"rotate_charts_to_axis": False}),
    (False, {"rotate_charts": False, "rotate_charts_to_axis": False}),
)
#: the mode of a layout whose quarter turns were chosen here
FIXED_TURNS = 3
#: islands (the largest, UV area) whose quarter turns are searched: 4^4 sets are guessed. All
#: of them, the first too: turning every island alike would change nothing on a square atlas
#: if xatlas placed islands the same way turned, but it fills from one corner (fixing the
#: largest island's turn lost 0.01-0.02 on bob, spot and the torus)
TURNED_ISLANDS = 4
#: up to this many islands every set of the largest islands' quarter turns is guessed; with
#: more, a guess packs more islands (its cost grows with them) and the sets are searched one
#: island at a time (:func:`_turn_sets`). Eight: the island target of a single-part mesh
EXHAUSTIVE_TURN_ISLANDS = 8
#: passes over the turned islands of that one-at-a-time search
TURN_PASSES = 2
#: candidates searched per round, best first guess first
PACK_SEARCHED = 3
#: the guesses' outlines are simplified within this many coarse texels
#: (:func:`guess_tolerance`): below what xatlas's rasteriser resolves
GUESS_TEXELS = 0.5


def min_rect_rotation(uv: np.ndarray) -> np.ndarray:
    """(2, 2) rotation (det +1) that turns ``uv``'s minimum-area bounding rectangle to the
    axes, long side along u. The rectangle has a side on the convex hull (rotating calipers:
    every hull edge's direction is tried). Identity where the hull is degenerate."""
    try:
        hull = uv[ConvexHull(uv).vertices]
    except (QhullError, ValueError):
        return np.eye(2)
    edge = np.roll(hull, -1, axis=0) - hull
    edge = edge[np.linalg.norm(edge, axis=1) > 0]
    e = edge / np.linalg.norm(edge, axis=1)[:, None]
    n = np.column_stack([-e[:, 1], e[:, 0]])
    w = np.ptp(hull @ e.T, axis=0)
    h = np.ptp(hull @ n.T, axis=0)
    k = int(np.argmin(w * h))
    r = np.array([e[k], n[k]])  # rows: the new u and v axes; det = |e|^2 = 1
    return r if w[k] >= h[k] else np.array([n[k], -e[k]])


def turned(islands: list[Island], mode: tuple[bool, dict], cache: dict | None = None) -> list[Island]:
    """The islands as packed in ``mode`` (rotated about their UV centroid, or as they are).
    ``cache`` keeps each island's rotation by its UVs array (the search turns the same
    islands in every layout that shares them: 33,000 hulls for 1,500 islands)."""
    if not mode[0]:
        return islands
    out = []
    for isl in islands:
        key = ("rect", id(isl.uv))
        hit = None if cache is None else cache.get(key)
        if hit is None or hit[0]() is not isl.uv:  # a weak reference: a freed array's id may pass to another
            hit = (weakref.ref(isl.uv), min_rect_rotation(isl.uv))
            if cache is not None:
                cache[key] = hit
        c = isl.uv.mean(0)
        out.append(replace(isl, uv=(isl.uv - c) @ hit[1].T + c))
    return out


def island_arrays(islands: list[Island]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(uv, faces, island): the islands as one split-vertex UV mesh, as the packer takes it."""
    offsets = np.cumsum([0] + [len(isl.uv) for isl in islands])
    return (np.concatenate([isl.uv for isl in islands]),
            np.concatenate([isl.faces + offsets[i] for i, isl in enumerate(islands)]),
            np.repeat(np.arange(len(islands)), [len(isl.faces) for isl in islands]))


def outline_arrays(islands: list[Island], cache: dict, index: list | None = None, tolerance: float = 0.0,
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(uv, faces, island) of the islands' outlines only (:func:`texture.outlines.island_outlines`:
    the same region per island, border vertices only): what xatlas needs for a guess
    (:func:`texture.scale_search.estimate_layouts`), without the faces inside (a million
    at 1M input faces, pickled to a worker per candidate). ``cache`` keeps each island's
    outline by its faces array: a turned island shares them, and a rotation keeps a
    triangulation valid. ``index``: a list that receives each island's outline vertices
    (indices into its ``uv``), in the order of the returned ``uv``. ``tolerance``: the
    outlines simplified within it, for guesses (:func:`guess_tolerance`; a rotation keeps
    the simplification, as it keeps a triangulation)."""
    uvs, faces, owner = [], [], []
    offset = 0
    for k, isl in enumerate(islands):
        key = (id(isl.faces), tolerance)
        hit = cache.get(key)
        if hit is None or hit[0] is not isl.faces:
            tri = island_outlines(isl.uv, isl.faces, np.zeros(len(isl.faces), np.int64), tolerance)
            vid, inv = np.unique(tri, return_inverse=True)
            hit = cache[key] = (isl.faces, vid, inv.reshape(-1, 3))
        uvs.append(isl.uv[hit[1]])
        if index is not None:
            index.append(hit[1])
        faces.append(hit[2] + offset)
        owner.append(np.full(len(hit[2]), k))
        offset += len(hit[1])
    return np.concatenate(uvs), np.concatenate(faces), np.concatenate(owner)


def guess_tolerance(islands: list[Island], cfg) -> float:
    """UV distance of ``GUESS_TEXELS`` coarse texels at the scale a guess packs at (its
    unbounded pack aims at ``GUESS_UTILIZATION`` of the coarse atlas): the guesses' outlines
    are simplified within it (:func:`texture.outlines.island_outlines`). The islands' total
    area, and so the tolerance, is the same for every halving and turn of them."""
    area = float(sum(np.abs(triangle_areas(isl.uv, isl.faces)).sum() for isl in islands))
    res, _ = coarse_size(cfg.resolution, cfg.padding)
    return GUESS_TEXELS * np.sqrt(area / GUESS_UTILIZATION) / res if area > 0 else 0.0


@dataclass
class Packed:
    """One layout packed in one mode."""

    islands: list[Island]
    mode: int
    packing: Packing
    """of the islands' outlines, turned as in ``mode``"""
    placed: list[Island]
    """the islands turned as in ``mode``"""
    index: list[np.ndarray]
    """each island's outline vertices"""

    @property
    def utilization(self) -> float:
        return self.packing.utilization


def whole_islands(islands: list[Island], index: list[np.ndarray], packing: Packing) -> Packing:
    """The packing of the islands' outlines (vertices ``index`` of each island) carried to
    all their vertices: each island moved by the rotation and translation that moved its
    outline (the packer moves islands rigidly at one scale and never mirrors one)."""
    uv, start = [], 0
    for isl, vid in zip(islands, index):
        src, dst = isl.uv[vid], packing.uv[start:start + len(vid)]
        start += len(vid)
        fit = similarity_fit(src, dst)
        uv.append(packing.scale * (isl.uv - src.mean(0)) @ fit.rotation.T + dst.mean(0))
    return replace(packing, uv=np.concatenate(uv))


def best_packed(layouts: list[list[Island]], modes: list[int], cfg, cache: dict,
                floor: float = 0.0, options: dict | None = None) -> Packed | None:
    """The best of the (islands, mode index) pairs packed for real (:func:`texture.pack.pack_islands`
    from its coarse plan), or None if none packs above ``floor``. ``options``: xatlas
    PackOptions set on top of each mode's.

    The coarse plan's utilisation is not the packing's: xatlas's 90-degree turns mirror
    islands, and keeping them the right way round cost up to 0.07 (bob: 0.574 coarse, 0.508
    packed), so the layouts are compared packed. Keeping islands unmirrored only lowers a
    plan's utilisation, so plans are packed best first, and those whose coarse utilisation
    cannot beat ``floor`` or the best packing so far are not packed (each packing costs
    several coarse searches).

    Only the islands' outlines are packed (the same regions: what the packer hands xatlas
    and checks anyway), and the winner's placement is carried to all its vertices
    (:func:`whole_islands`): at 1M faces every packing of the whole faces cost seconds
    in areas, outlines and worker traffic alone."""
    kw = {"resolution": cfg.resolution, "padding": cfg.padding}
    plans = []
    for layout, m in zip(layouts, modes):
        index: list = []
        placed = turned(layout, PACK_MODES[m], cache)
        arrays = outline_arrays(placed, cache, index)
        plan = plan_layouts([arrays], candidates=({**PACK_MODES[m][1], **(options or {})},), **kw)[0]
        if plan is not None:
            plans.append((plan, arrays, index, layout, placed, m))
    best = None
    for plan, arrays, index, layout, placed, m in sorted(plans, key=lambda p: -p[0].utilization):  # stable: ties keep order
        bar = max(floor, best.utilization if best is not None else 0.0)  # what a packing must beat
        if plan.utilization <= bar:
            break
        got = Packed(layout, m, pack_islands(*arrays, plan=plan, floor=bar, **kw), placed, index)
        if best is None or got.utilization > best.utilization:
            best = got
    # a plan above the floor can pack below it (the unmirroring above): then nothing passed
    return best if best is not None and best.utilization > floor else None


def _quarter(d: np.ndarray, k: int) -> np.ndarray:
    """The offsets ``d (N, 2)`` turned by ``k`` quarter turns counter-clockwise (exact:
    coordinates swap and change sign)."""
    for _ in range(k % 4):
        d = np.column_stack([-d[:, 1], d[:, 0]])
    return d


def quarter_turn(isl: Island, k: int) -> Island:
    """``isl`` turned by ``k`` quarter turns counter-clockwise about its UV centroid."""
    if k % 4 == 0:
        return isl
    c = isl.uv.mean(0)
    return replace(isl, uv=_quarter(isl.uv - c, k) + c)


def _turn_sets(big: np.ndarray, n: int, guess) -> dict[tuple, float | None]:
    """Sets of quarter turns of the islands ``big`` (others unturned) -> ``guess(sets)``'s
    utilisation of each (None: not packed). Every set (4^len(big)) where ``n`` (the islands
    packed by each guess) is at most :data:`EXHAUSTIVE_TURN_ISLANDS`; above, a coordinate
    search: from no turns, each island's four turns in turn with the others held at the best so
    far, :data:`TURN_PASSES` times (at most 1 + 12 * passes sets, against 256).

    The one-at-a-time search may miss a set only a joint turn finds: on spot's 3 islands it
    packed 0.014 below the whole search (0.568 against 0.582), and the unwrap with it ended at
    0.574 against 0.630. With many islands it guessed as well where the whole search cost 5-25
    times more (:mod:`texture.unwrap_layout` has the numbers)."""
    sets: dict[tuple, float | None] = {}

    def add(keys):
        new = [k for k in dict.fromkeys(keys) if k not in sets]
        if new:
            sets.update(zip(new, guess(new)))

    if n <= EXHAUSTIVE_TURN_ISLANDS:
        add(list(itertools.product(range(4), repeat=len(big))))
        return sets
    cur = (0,) * len(big)
    add([cur])
    for _ in range(TURN_PASSES):
        for j in range(len(big)):
            tries = [cur[:j] + (q,) + cur[j + 1:] for q in range(4)]
            add(tries)
            # the best guess; the set held so far on a tie (no turn without a gain)
            cur = max(tries, key=lambda k: (-1.0 if sets[k] is None else sets[k], k == cur))
    return sets


def quarter_turned(islands: list[Island], cfg, cache: dict, floor: float) -> Packed | None:
    """The best packing, above ``floor``, of ``islands`` turned to their minimum-area rectangles
    and then by quarter turns (:data:`TURNED_ISLANDS`, sets as :func:`_turn_sets` chooses),
    xatlas's turns off; None if none is above ``floor``. Sets are ranked by one unbounded pack
    each of the outlines alone (turned as arrays: a set of whole islands is made only for the
    ``PACK_SEARCHED`` best, which are packed; 256 turned copies of the 1M-face bunny's islands
    took 0.6 GB)."""
    placed = turned(islands, PACK_MODES[2], cache)
    index: list = []
    uv, faces, owner = outline_arrays(placed, cache, index, guess_tolerance(placed, cfg))
    bounds = np.cumsum([0] + [len(v) for v in index])
    area = [float(np.abs(triangle_areas(isl.uv, isl.faces)).sum()) for isl in placed]
    big = np.argsort(area, kind="stable")[::-1][:TURNED_ISLANDS]

    def turns(key: tuple) -> np.ndarray:
        k = np.zeros(len(placed), np.int64)
        k[big] = key
        return k

    def guess(keys: list[tuple]) -> list[float | None]:
        arrays = []
        for key in keys:
            turned_uv = uv.copy()
            for i, q in zip(big, key):  # the packer moves islands rigidly: where each turns about does not matter
                part = slice(bounds[i], bounds[i + 1])
                turned_uv[part] = _quarter(uv[part] - uv[part].mean(0), int(q))
            arrays.append((turned_uv, faces, owner))
        est = estimate_layouts(arrays, resolution=cfg.resolution, padding=cfg.padding,
                               options=PACK_MODES[FIXED_TURNS][1])
        return [None if e is None else e.utilization for e in est]

    sets = _turn_sets(big, len(placed), guess)
    ranked = sorted((-u, key) for key, u in sets.items() if u is not None)[:PACK_SEARCHED]
    layouts = [[quarter_turn(isl, int(q)) for isl, q in zip(placed, turns(key))] for _, key in ranked]
    return best_packed(layouts, [FIXED_TURNS] * len(layouts), cfg, cache, floor)


def brute_packed(p: Packed, cfg, cache: dict) -> Packed | None:
    """The chosen layout ``p`` packed once more with xatlas's exhaustive placement
    (``bruteForce``) in its mode; None unless that packs better."""
    return best_packed([p.islands], [p.mode], cfg, cache, p.utilization, {"bruteForce": True})
