"""The unwrap's packing search: which way to turn the islands, and which to halve, before packing.

The unwrap's islands are few and large (2-8 on a single-part mesh), and relaxed islands are
round blobs: their minimum-area bounding rectangles are only 55-75 % full. With so few
islands xatlas cannot fill the gaps, so utilisation is set by the islands' shapes and turns
(0.40-0.56 on the benchmark fits with the islands packed as they came). Two things help,
and which one, and where, is not predictable from the shapes, so layouts are *packed* to be
compared (as the export's cut rounds do, :mod:`texture.layout_search`):

1. **Turns** (:data:`PACK_MODES`). xatlas's own ``rotate_charts_to_axis`` turns each island
   to an axis of its own choosing; turning every island to its minimum-area bounding
   rectangle here (a rotation: an isometry, never a mirror; distortion and texel density do
   not change) and switching xatlas's turn off packed tighter in coarse plans on four of six
   fits (bob 0.51 -> 0.57, eight 0.44 -> 0.50) and looser on the others (spot 0.42 -> 0.36);
   once its mirrored islands were turned back, it won only on the eight uncut (0.50), but
   it won four of the six halving rounds. So every layout is packed in several modes and
   the best is kept.
2. **Halvings** (:func:`texture.halving.halve_across`), only while no layout reaches
   ``cfg.pack_target``: one of the ``PACK_CUT_ISLANDS`` largest islands cut in two along mesh
   edges (UVs kept, so flips, overlap and distortion do not change), across or along its
   principal axis, in the middle or a quarter off one end. A halving adds seam, so it is kept
   only when it gains ``cfg.pack_cut_gain``, at most ``cfg.pack_max_cuts`` of them; such an
   ordinary halving never takes a connected component from within ``cfg.long_max_islands``
   islands past it (:func:`texture.halving.may_halve`). A part that flattened as one island
   (its fewest possible seams), or one at ``cfg.long_max_islands`` (a cut takes it past the
   island target), is halved only for ``cfg.pack_first_seam_gain``.

3. **Quarter turns** (:func:`_quarter_turned`), last: the chosen islands, each turned to its
   minimum-area rectangle, then each of the ``TURNED_ISLANDS`` largest by a quarter turn
   (0, 90, 180 or 270 degrees: rotations, never a mirror), packed with xatlas's own turns off
   (it only translates). xatlas turns each island on its own as it places it, largest first;
   which turns let a few large islands nest is a question of the set, and the 4^4 sets
   are cheap to guess (one xatlas call each, 0.5-1 s in all). On six benchmark fits' final
   layouts it gained 0.000-0.023 (bob 0.593 -> 0.616, spot 0.559 -> 0.582) and lost
   nowhere: the layout it starts from is kept where no set packs better. Where the result is
   still below ``cfg.pack_target`` and the search stopped at an ordinary halving that did not
   pay, that halving is quarter-turned too and kept when it gains ``cfg.pack_cut_gain`` over
   the result: the gain a halving must buy, measured as the layouts will be delivered (spot:
   0.582 -> 0.627, one more island; genus2's last halving gains 0.016 and is not kept).
4. **Two cuts at once** (:func:`_paired_halvings`), where the result is still below
   ``cfg.pack_target`` after a round in which no single halving paid: some cuts pay only in
   pairs (two like parts halved one at a time keep the atlas's shape), so even halvings are
   tried two at a time, each still buying what it costs.

5. **Exhaustive placement** (:func:`_brute_packed`), once, on the layout chosen above:
   xatlas's ``bruteForce`` tries every position for each island where its default tries a
   sample of them. It is too slow for the search itself (the search with it throughout took
   limbs' packing 26 -> 172 s and the assembly's 7 -> 22 s), but one packing of the chosen
   layout costs about as much as one of the search's packings, and it is kept only where it
   packs better (islands, seams and distortion do not change). On 24 unwraps (19 benchmark
   fits, 5 unseen inputs) it gained on 8 (the truck 0.629 -> 0.669, the assembly 0.504 ->
   0.533, limbs 0.582 -> 0.598, pretzel3 0.606 -> 0.620, bumpy, a gear, bob and spot
   0.003-0.006) and was not kept on 16. Packing the quarter-turn search's best sets with it
   too gained 0.010 on bob and 0.003 on the truck, lost 0.003 on the assembly: not kept.

Every candidate (halving x mode) is first packed once into an unbounded atlas
(:func:`texture.scale_search.estimate_layouts`, one xatlas call); only the
``PACK_SEARCHED`` best guesses are searched and packed (on the benchmark fits the guess's
top three held the best search in five of six rounds, and a search costs about ten guesses).
"""
from __future__ import annotations

import itertools
import time
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from mnacore.triangles import triangle_areas

from .halving import LONG_CUTS, halve_across, island_parts, may_halve
from .outlines import island_outlines
from .pack import Packing, pack_islands
from .regions import face_adjacency
from .scale_search import GUESS_UTILIZATION, coarse_size, estimate_layouts, plan_layouts
from .similarity import similarity_fit
from .unwrap_islands import Island

#: (turn every island to its minimum-area bounding rectangle first, xatlas PackOptions); the
#: last: every turn chosen here (:func:`_quarter_turned`), xatlas only translates
PACK_MODES: tuple[tuple[bool, dict], ...] = (
    (False, {}),
    (False, {"rotate_charts": False}),
    (True, {"rotate_charts_to_axis": False}),
    (False, {"rotate_charts": False, "rotate_charts_to_axis": False}),
)
#: the modes an uncut layout is packed in first (the last mode needs turns chosen for it)
UNCUT_MODES = (0, 1, 2)
#: the mode of a layout whose quarter turns were chosen here
FIXED_TURNS = 3
#: islands (the largest, UV area) whose quarter turns are searched: 4^4 sets are guessed. All
#: of them, the first too: turning every island alike would change nothing on a square atlas
#: if xatlas placed islands the same way turned, but it fills from one corner (fixing the
#: largest island's turn lost 0.01-0.02 on bob, spot and the torus)
TURNED_ISLANDS = 4
#: cut positions (fraction of the island's area before the cut) of each halving tried:
#: the middle, a quarter off the low end, a quarter off the high end
PACK_CUTS = (LONG_CUTS, np.linspace(0.15, 0.3, 4), np.linspace(0.7, 0.85, 4))
#: modes a halving is packed in: turning to the minimum-area rectangle won four of six halving
#: rounds on the benchmark fits, xatlas's own turns the others; without turns none
HALVING_MODES = (0, 2)
#: the largest islands (3D area) whose halvings are tried
PACK_CUT_ISLANDS = 3
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


def turned(islands: list[Island], mode: tuple[bool, dict]) -> list[Island]:
    """The islands as packed in ``mode`` (rotated about their UV centroid, or as they are)."""
    if not mode[0]:
        return islands
    out = []
    for isl in islands:
        c = isl.uv.mean(0)
        out.append(replace(isl, uv=(isl.uv - c) @ min_rect_rotation(isl.uv).T + c))
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
class LayoutChoice:
    """The islands to pack (turned and halved), their packing, and what the search did."""

    islands: list[Island]
    packing: Packing
    stats: dict = field(default_factory=dict)


@dataclass
class _Packed:
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


def _whole_islands(islands: list[Island], index: list[np.ndarray], packing: Packing) -> Packing:
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


def _best_packed(layouts: list[list[Island]], modes: list[int], cfg, cache: dict,
                 floor: float = 0.0) -> _Packed | None:
    """The best of the (islands, mode index) pairs packed for real (:func:`texture.pack.pack_islands`
    from its coarse plan), or None if none packs above ``floor``.

    The coarse plan's utilisation is not the packing's: xatlas's 90-degree turns mirror
    islands, and keeping them the right way round cost up to 0.07 (bob: 0.574 coarse, 0.508
    packed), so the layouts are compared packed. Keeping islands unmirrored only lowers a
    plan's utilisation, so plans are packed best first, and those whose coarse utilisation
    cannot beat ``floor`` or the best packing so far are not packed (each packing costs
    several coarse searches).

    Only the islands' outlines are packed (the same regions: what the packer hands xatlas
    and checks anyway), and the winner's placement is carried to all its vertices
    (:func:`_whole_islands`): at 1M faces every packing of the whole faces cost seconds
    in areas, outlines and worker traffic alone."""
    kw = {"resolution": cfg.resolution, "padding": cfg.padding}
    plans = []
    for layout, m in zip(layouts, modes):
        index: list = []
        placed = turned(layout, PACK_MODES[m])
        arrays = outline_arrays(placed, cache, index)
        plan = plan_layouts([arrays], candidates=(PACK_MODES[m][1],), **kw)[0]
        if plan is not None:
            plans.append((plan, arrays, index, layout, placed, m))
    best = None
    for plan, arrays, index, layout, placed, m in sorted(plans, key=lambda p: -p[0].utilization):  # stable: ties keep order
        if plan.utilization <= max(floor, best.utilization if best is not None else 0.0):
            break
        got = _Packed(layout, m, pack_islands(*arrays, plan=plan, **kw), placed, index)
        if best is None or got.utilization > best.utilization:
            best = got
    return best


def _halvings(islands: list[Island], comp: np.ndarray, cfg, first_seam: bool,
              middle_only: bool = False) -> list[tuple[list[Island], dict]]:
    """Every halving tried this round: (islands after it, its description). ``first_seam``:
    the halvings :func:`may_halve` refuses (of a part that flattened as one island, its first
    seam, or of a part at ``cfg.long_max_islands``, past the island target), which must buy
    ``cfg.pack_first_seam_gain``; else the others. ``middle_only``: the even halvings only
    (:func:`_paired_halvings`)."""
    part, per_comp = island_parts(islands, comp)
    area = [float(triangle_areas(i.xyz, i.faces).sum()) for i in islands]
    out = []
    for rank, k in enumerate(np.argsort(area, kind="stable")[::-1][:PACK_CUT_ISLANDS]):
        count = int(per_comp[part[k]])
        if may_halve(count, cfg) == first_seam:
            continue
        adj = face_adjacency(islands[k].xyz, islands[k].faces)  # once for its six halvings
        for along in (False, True):
            for where, cuts in zip(("middle", "low_quarter", "high_quarter")[:1 if middle_only else 3], PACK_CUTS):
                halved = halve_across(islands[k], along, cuts, adj)
                if halved is not None:
                    out.append((islands[:k] + islands[k + 1:] + halved[0],
                                {"island_rank": rank, "along_axis": along, "at": where, "cut_length": halved[1],
                                 "first_seam": first_seam}))
    return out


#: one round's halvings (islands after each, its description) and the ``PACK_SEARCHED`` best
#: guesses among them (candidate index, mode index)
Ranked = tuple[list[tuple[list[Island], dict]], list[tuple[int, int]]]


def _ranked_halvings(islands: list[Island], comp: np.ndarray, cfg, cache: dict, first_seam: bool = False) -> Ranked:
    """Every halving this round (:func:`_halvings`), each guessed in :data:`HALVING_MODES` by
    one unbounded pack, and the best guesses."""
    cands = _halvings(islands, comp, cfg, first_seam)
    return cands, _best_guesses([c for c, _ in cands], islands, cfg, cache)


def _mode_guesses(layouts: list[list[Island]], tol: float, cfg, cache: dict) -> list[tuple[float, int, int]]:
    """(guessed utilisation, layout index, mode index) of each layout in each mode of
    :data:`HALVING_MODES`: one unbounded pack of its outlines, simplified within ``tol``."""
    out = []
    for m in HALVING_MODES:
        mode = PACK_MODES[m]
        arrays = [outline_arrays(turned(c, mode), cache, tolerance=tol) for c in layouts]
        est = estimate_layouts(arrays, resolution=cfg.resolution, padding=cfg.padding, options=mode[1])
        out += [(e.utilization, i, m) for i, e in enumerate(est) if e is not None]
    return out


def guess_layouts(layouts: list[list[Island]], cfg) -> list[float]:
    """Each layout's first guess, the better of its modes (:func:`_mode_guesses`), simplified
    at the tolerance of the first layout's islands: how the cut ways of
    :func:`texture.long_islands.split_long_islands` are compared."""
    best = [0.0] * len(layouts)
    for u, i, _ in _mode_guesses(layouts, guess_tolerance(layouts[0], cfg), cfg, {}):
        best[i] = max(best[i], u)
    return best


def _best_guesses(layouts: list[list[Island]], islands: list[Island], cfg, cache: dict) -> list[tuple[int, int]]:
    """The ``PACK_SEARCHED`` best (layout index, mode index) of ``layouts`` (:func:`_mode_guesses`,
    simplified at the tolerance of the uncut ``islands``)."""
    if not layouts:
        return []
    guesses = _mode_guesses(layouts, guess_tolerance(islands, cfg), cfg, cache)
    guesses.sort(key=lambda g: (-g[0], g[1], g[2]))
    return [(i, m) for _, i, m in guesses[:PACK_SEARCHED]]


def _best_halving(ranked: Ranked, cfg, floor: float, cache: dict) -> tuple[_Packed, dict] | None:
    """The best of a round's best guesses (:func:`_ranked_halvings`), packed, and its
    description; None if none packs above ``floor``."""
    cands, top = ranked
    if not top:
        return None
    best = _best_packed([cands[i][0] for i, _ in top], [m for _, m in top], cfg, cache, floor)
    if best is None:
        return None
    return best, next(d for c, d in cands if c is best.islands)


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


def _quarter_turned(islands: list[Island], cfg, cache: dict, floor: float) -> _Packed | None:
    """The best packing, above ``floor``, of ``islands`` turned to their minimum-area rectangles
    and then by quarter turns (:data:`TURNED_ISLANDS`), xatlas's turns off; None if none is
    above ``floor``. Sets are ranked by one unbounded pack each of the outlines alone (turned
    as arrays: a set of whole islands is made only for the ``PACK_SEARCHED`` best, which are
    packed; 256 turned copies of the 1M-face bunny's islands took 0.6 GB)."""
    placed = turned(islands, PACK_MODES[2])
    index: list = []
    uv, faces, owner = outline_arrays(placed, cache, index, guess_tolerance(placed, cfg))
    bounds = np.cumsum([0] + [len(v) for v in index])
    area = [float(np.abs(triangle_areas(isl.uv, isl.faces)).sum()) for isl in placed]
    big = np.argsort(area, kind="stable")[::-1][:TURNED_ISLANDS]
    sets, arrays = [], []
    for turns in itertools.product(range(4), repeat=len(big)):
        k = np.zeros(len(placed), np.int64)
        k[big] = turns
        sets.append(k)
        turned_uv = uv.copy()
        for i in big:  # the packer moves islands rigidly: where each turns about does not matter
            part = slice(bounds[i], bounds[i + 1])
            turned_uv[part] = _quarter(uv[part] - uv[part].mean(0), int(k[i]))
        arrays.append((turned_uv, faces, owner))
    est = estimate_layouts(arrays, resolution=cfg.resolution, padding=cfg.padding, options=PACK_MODES[FIXED_TURNS][1])
    ranked = sorted((-e.utilization, i) for i, e in enumerate(est) if e is not None)[:PACK_SEARCHED]
    layouts = [[quarter_turn(isl, int(q)) for isl, q in zip(placed, sets[i])] for _, i in ranked]
    return _best_packed(layouts, [FIXED_TURNS] * len(layouts), cfg, cache, floor)


def _paired_halvings(islands: list[Island], comp: np.ndarray, cfg, cache: dict, ranked: list[Ranked],
                     floor: float) -> tuple[_Packed, list[dict]] | None:
    """Two halvings at once, for the islands where no single one paid: the best packing of
    a layout cut twice that gains what both cuts must buy over ``floor`` (each a first seam or
    an ordinary cut, as :func:`_halvings` makes them), with its two descriptions; else None.

    One cut can leave the atlas's shape as it was, so that its gain shows only with a second:
    two like parts (two tori unrolled as strips lie stacked 2:1 however one is halved: 0.40,
    both halved 0.76 as delivered), or an island whose halves are each as wide as the whole
    (an open cone's sector: 0.38, 0.41 halved once, 0.67 twice). Such a first cut halves an island
    evenly (two like halves side by side keep the whole's aspect), so the first cuts are the
    middle ones of the round that fell short (``ranked``: its ordinary and first-seam
    candidates; a single cut's guess cannot rank them, as their gain shows only in pairs):
    at most two axes of ``PACK_CUT_ISLANDS`` islands; each layout they leave is halved evenly
    again (the second cut of such a pair is the even one too), and the pairs are guessed and
    searched like one round's halvings."""
    firsts = [c for cands, _ in ranked for c in cands if c[1]["at"] == "middle"]
    pairs = [(c, [first, d]) for layout, first in firsts for seam in (False, True)
             for c, d in _halvings(layout, comp, cfg, seam, middle_only=True)]
    best = None
    for j, m in _best_guesses([c for c, _ in pairs], islands, cfg, cache):
        need = floor + sum(cfg.pack_first_seam_gain if d["first_seam"] else cfg.pack_cut_gain for d in pairs[j][1])
        got = _best_packed([pairs[j][0]], [m], cfg, cache, need)
        if got is not None and got.utilization >= need and (best is None or got.utilization > best[0].utilization):
            best = (got, pairs[j][1])
    return best


def _brute_packed(p: _Packed, cfg, cache: dict) -> _Packed | None:
    """The chosen layout ``p`` packed once more with xatlas's exhaustive placement
    (``bruteForce``) in its mode; None unless that packs better."""
    kw = {"resolution": cfg.resolution, "padding": cfg.padding}
    index: list = []
    arrays = outline_arrays(p.placed, cache, index)
    plan = plan_layouts([arrays], candidates=({**PACK_MODES[p.mode][1], "bruteForce": True},), **kw)[0]
    if plan is None or plan.utilization <= p.utilization:
        return None
    got = pack_islands(*arrays, plan=plan, **kw)
    return _Packed(p.islands, p.mode, got, p.placed, index) if got.utilization > p.utilization else None


def choose_layout(islands: list[Island], comp: np.ndarray, cfg) -> LayoutChoice:
    """The islands turned (and halved) as packs best; see module docstring. ``comp`` is the
    connected component of every working face; ``cfg`` a :class:`texture.unwrap.UnwrapConfig`."""
    cache: dict = {}  # outlines of the islands tried (:func:`outline_arrays`)
    best = _best_packed([islands] * len(UNCUT_MODES), list(UNCUT_MODES), cfg, cache)
    if best is None:  # xatlas placed nothing: the packer's own fallbacks (a shelf packing)
        return LayoutChoice(islands, pack_islands(*island_arrays(islands), resolution=cfg.resolution,
                                                  padding=cfg.padding), {"mode": 0, "halvings": []})
    stats = {"utilization_uncut": best.utilization, "halvings": []}
    fell_short = None  # the ordinary round at which the rounds ended, its halving not paying
    first: Ranked = ([], [])
    for _ in range(cfg.pack_max_cuts):
        if best.utilization >= cfg.pack_target:
            break
        ranked = _ranked_halvings(best.islands, comp, cfg, cache)
        got = _best_halving(ranked, cfg, best.utilization + cfg.pack_cut_gain, cache)
        if got is None or got[0].utilization < best.utilization + cfg.pack_cut_gain:
            # a part's first seam (it flattened as one island) must buy more
            first = _ranked_halvings(best.islands, comp, cfg, cache, True)
            got = _best_halving(first, cfg, best.utilization + cfg.pack_first_seam_gain, cache)
            if got is None or got[0].utilization < best.utilization + cfg.pack_first_seam_gain:
                fell_short = ranked
                break
        best = got[0]
        stats["halvings"].append({**got[1], "utilization": best.utilization})
    stats["utilization_turned_as_xatlas"] = best.utilization
    cut = best  # the rounds' layout, on which their last rankings were made
    if len(best.islands) > 1:
        best = _quarter_turned(best.islands, cfg, cache, best.utilization) or best
    if fell_short is not None and best.utilization < cfg.pack_target:
        # the halving that fell short (its round's guesses kept), judged as it will be
        # delivered: quarter-turned too
        missed = _best_halving(fell_short, cfg, 0.0, cache)
        turned_halving = None if missed is None else _quarter_turned(missed[0].islands, cfg, cache,
                                                                      best.utilization + cfg.pack_cut_gain)
        if turned_halving is not None:
            best = turned_halving
            stats["halvings"].append({**missed[1], "utilization": best.utilization, "after_quarter_turns": True})
    # the rounds' own cuts: a pair is made on their layout (``cut``), in place of a missed
    # halving kept above
    made = [h for h in stats["halvings"] if not h.get("after_quarter_turns")]
    if fell_short is not None and best.utilization < cfg.pack_target and len(made) + 2 <= cfg.pack_max_cuts:
        pair = _paired_halvings(cut.islands, comp, cfg, cache, [fell_short, first], best.utilization)
        if pair is not None:
            best = _quarter_turned(pair[0].islands, cfg, cache, pair[0].utilization) or pair[0]
            stats["halvings"] = made + [{**d, "utilization": best.utilization, "paired": True} for d in pair[1]]
    stats["utilization_before_brute"] = best.utilization
    t0 = time.perf_counter()
    brute = _brute_packed(best, cfg, cache)
    stats["brute_force_seconds"] = time.perf_counter() - t0
    if brute is not None:
        best = brute
        stats["brute_force"] = True
    stats["mode"] = best.mode
    return LayoutChoice(best.placed, _whole_islands(best.placed, best.index, best.packing), stats)
