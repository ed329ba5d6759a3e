"""The packing search of the unwrap and of the export: which way to turn the islands, and which to halve.

Both the unwrap (:mod:`texture.unwrap`) and the export's atlas (:mod:`texture.atlas`) pack
through :func:`choose_layout`; what it aims at is a :class:`LayoutGoal` (the unwrap's
:class:`texture.unwrap.UnwrapConfig` carries the same fields).

The unwrap's islands are few and large (2-8 on a single-part mesh), and relaxed islands are
round blobs: their minimum-area bounding rectangles are only 55-75 % full. With so few
islands xatlas cannot fill the gaps, so utilisation is set by the islands' shapes and turns
(0.40-0.56 on the benchmark fits with the islands packed as they came). Two things help,
and which one, and where, is not predictable from the shapes, so layouts are *packed* to be
compared:

1. **Turns** (:data:`texture.layout_packing.PACK_MODES`). xatlas's own
   ``rotate_charts_to_axis`` turns each island to an axis of its own choosing; turning every
   island to its minimum-area bounding rectangle here (a rotation: an isometry, never a
   mirror; distortion and texel density do not change) and switching xatlas's turn off packed tighter in coarse plans on four of six
   fits (bob 0.51 -> 0.57, eight 0.44 -> 0.50) and looser on the others (spot 0.42 -> 0.36);
   once its mirrored islands were turned back, it won only on the eight uncut (0.50), but
   it won four of the six halving rounds. So every layout is packed in several modes and
   the best is kept.
2. **Halvings** (:func:`texture.halving.halve_across`), only while no layout reaches
   ``cfg.pack_target``: one of the ``PACK_CUT_ISLANDS`` largest islands cut in two along mesh
   edges (UVs kept, so flips, overlap and distortion do not change), across or along its
   principal axis, in the middle or a quarter off one end. A halving adds seam, so it is kept
   only when it gains ``cfg.pack_cut_gain``, at most ``cfg.pack_max_cuts`` of them; of those
   that pay, the round makes the shortest that reaches ``cfg.pack_target``, else the one that
   gains most per length of cut (:func:`_chosen`); such an
   ordinary halving never takes a connected component from within ``cfg.long_max_islands``
   islands past it (:func:`texture.halving.may_halve`). A part that flattened as one island
   (its fewest possible seams), or one at ``cfg.long_max_islands`` (a cut takes it past the
   island target), is halved only for ``cfg.pack_first_seam_gain``.

   **Protrusions** (:mod:`texture.spikes`) are candidates of the same rounds: a limb or
   an arm left on a body's island unrolls as a strip sticking out of it, which the
   halvings' positions (15-85 % of the area along an axis) never cut off; cut at its
   neck it costs its width in seam. Such a cut is short, so the per-length rule makes it
   first; where the rounds made one and end below ``cfg.pack_target`` they run again
   without them, and the better packing is kept (:func:`choose_layout`).

3. **Quarter turns** (:func:`texture.layout_packing.quarter_turned`), last: the chosen
   islands, each turned to its minimum-area rectangle, then each of the ``TURNED_ISLANDS``
   largest by a quarter turn (0, 90, 180 or 270 degrees: rotations, never a mirror), packed with xatlas's own turns off
   (it only translates). xatlas turns each island on its own as it places it, largest first;
   which turns let a few large islands nest is a question of the set, and the 4^4 sets
   are cheap to guess (one xatlas call each, 0.5-1 s in all). On six benchmark fits' final
   layouts it gained 0.000-0.023 (bob 0.593 -> 0.616, spot 0.559 -> 0.582) and lost
   nowhere: the layout it starts from is kept where no set packs better. Where the result is
   still below ``cfg.pack_target`` and the search stopped at a halving that did not pay,
   that halving is quarter-turned too and kept when it gains what it must buy over the
   result, measured as the layouts will be delivered: the ordinary one for
   ``cfg.pack_cut_gain`` (spot: 0.582 -> 0.627, one more island; genus2's gains 0.016 and is
   not kept), else the part's first seam for ``cfg.pack_first_seam_gain`` (a single-island
   head, decimated-max: 0.49 -> 0.62, where the same cut gained 0.092 as xatlas turns it).
   With more than ``EXHAUSTIVE_TURN_ISLANDS`` islands each guess packs them all, and the 256
   sets cost 5-25 times what a one-island-at-a-time search does
   (:func:`texture.layout_packing._turn_sets`), which packed as well there. Quarter-turn
   packing, all sets -> one at a time, on unseen scattered parts (one island each): 200
   spheres, none above the 0.387 floor -> 0.391, 33.5 -> 4.2 s; 60 parts 0.484 -> 0.486,
   13.5 -> 2.5 s; 40 parts 0.603 -> 0.608; 25 parts 0.591 -> 0.598; the truck's 16
   islands 0.629 -> none above its 0.622 floor, 4.8 -> 1.3 s (its unwrap 0.6685 -> 0.6674).
   On spot's three islands it packed 0.014 below all sets (its unwrap 0.574 against 0.630):
   up to eight islands every set is guessed.
4. **Two cuts at once** (:func:`_paired_halvings`), where the result is still below
   ``cfg.pack_target`` after a round in which no single halving paid: some cuts pay only in
   pairs (two like parts halved one at a time keep the atlas's shape), so even halvings are
   tried two at a time, each still buying what it costs; the pair that packs best is judged
   quarter-turned, as it will be delivered (the same head: pairs at 0.51-0.55 as xatlas
   turns them, 0.60-0.67 quarter-turned).

5. **Exhaustive placement** (:func:`texture.layout_packing.brute_packed`), once, on the
   layout chosen above: xatlas's ``bruteForce`` tries every position for each island where
   its default tries a sample of them. It is too slow for the search itself (the search with it throughout took
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

import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from mnacore.triangles import triangle_areas

from .halving import LONG_CUTS, halve_across, island_parts, may_halve
from .layout_packing import (
    PACK_MODES,
    PACK_SEARCHED,
    Packed,
    best_packed,
    brute_packed,
    guess_tolerance,
    island_arrays,
    outline_arrays,
    quarter_turned,
    turned,
    whole_islands,
)
from .pack import Packing, pack_islands
from .parallel import MIN_FACES, parallel_map
from .regions import face_adjacency
from .scale_search import estimate_layouts
from .spikes import spike_cuts
from .unwrap_islands import Island

#: the modes an uncut layout is packed in first (the last mode needs turns chosen for it)
UNCUT_MODES = (0, 1, 2)
#: cut positions (fraction of the island's area before the cut) of each halving tried:
#: the middle, a quarter off the low end, a quarter off the high end
PACK_CUTS = (LONG_CUTS, np.linspace(0.15, 0.3, 4), np.linspace(0.7, 0.85, 4))
#: modes a halving is packed in: turning to the minimum-area rectangle won four of six halving
#: rounds on the benchmark fits, xatlas's own turns the others; without turns none
HALVING_MODES = (0, 2)
#: the largest islands (3D area) whose halvings are tried
PACK_CUT_ISLANDS = 3
#: default utilisation a first seam must buy (``pack_first_seam_gain``; why: UnwrapConfig)
FIRST_SEAM_GAIN = 0.1
#: default most packing halvings (``pack_max_cuts``; why: UnwrapConfig)
MAX_CUTS = 4


@dataclass(frozen=True)
class LayoutGoal:
    """What :func:`choose_layout` aims at: the fields it reads of its ``cfg``, named and
    meant as in :class:`texture.unwrap.UnwrapConfig` (which passes itself); the export builds
    one from its :class:`texture.atlas_config.AtlasConfig`
    (:func:`texture.atlas_stages.layout_goal`)."""

    resolution: int
    padding: int
    pack_target: float
    pack_cut_gain: float
    long_max_islands: int
    pack_first_seam_gain: float = FIRST_SEAM_GAIN
    pack_max_cuts: int = MAX_CUTS


@dataclass
class LayoutChoice:
    """The islands to pack (turned and halved), their packing, and what the search did."""

    islands: list[Island]
    packing: Packing
    stats: dict = field(default_factory=dict)


def _halvings(islands: list[Island], comp: np.ndarray, cfg, first_seam: bool, cache: dict,
              middle_only: bool = False, spikes: bool = False) -> list[tuple[list[Island], dict]]:
    """Every halving tried this round: (islands after it, its description). ``first_seam``:
    the halvings :func:`may_halve` refuses (of a part that flattened as one island, its first
    seam, or of a part at ``cfg.long_max_islands``, past the island target), which must buy
    ``cfg.pack_first_seam_gain``; else the others. ``middle_only``: the even halvings only
    (:func:`_paired_halvings`). ``spikes``: each of the same islands' protrusions cut off at
    its neck (:func:`texture.spikes.spike_cuts`) is a candidate too. ``cache`` keeps each
    island's halvings and protrusion cuts (:func:`_cut_key`)."""
    part, per_comp = island_parts(islands, comp)
    area = [float(triangle_areas(i.xyz, i.faces).sum()) for i in islands]
    jobs, tried, done = [], [], {}
    for rank, k in enumerate(np.argsort(area, kind="stable")[::-1][:PACK_CUT_ISLANDS]):
        count = int(per_comp[part[k]])
        if may_halve(count, cfg) == first_seam:
            continue
        for along in (False, True):
            for w, where in enumerate(("middle", "low_quarter", "high_quarter")[:1 if middle_only else 3]):
                key = _cut_key(islands[k], "halved", along, w)
                if _cached(cache, islands[k], key):
                    done[len(tried)] = cache[key][2]
                else:
                    jobs.append((len(tried), key, (islands[k], along, PACK_CUTS[w], _adjacency(islands[k], cache))))
                tried.append((k, {"island_rank": rank, "along_axis": along, "at": where}))
    # each halving is a maximum flow on its band and moves its ears: independent, so they run in
    # the pool where the islands are large (the 111k-face scan: 18 a round, a quarter of its packing)
    halved_faces = sum(len(islands[k].faces) for k in {tried[i][0] for i, _, _ in jobs})  # each island cut, once
    for (i, key, job), got in zip(jobs, parallel_map(_halve_job, [j[2] for j in jobs], parallel=halved_faces >= MIN_FACES)):
        done[i] = got
        cache[key] = (job[0].faces, job[0].uv, got)
    out = [(islands[:k] + islands[k + 1:] + done[i][0], {**d, "cut_length": done[i][1], "first_seam": first_seam})
           for i, (k, d) in enumerate(tried) if done[i] is not None]
    if spikes and not middle_only:
        for k, d in dict(tried).items():  # each island halved above, once
            key = _cut_key(islands[k], "spikes")
            if not _cached(cache, islands[k], key):
                cache[key] = (islands[k].faces, islands[k].uv, spike_cuts(islands[k], _adjacency(islands[k], cache)))
            for pieces, length, what in cache[key][2]:
                out.append((islands[:k] + islands[k + 1:] + pieces,
                            {"island_rank": d["island_rank"], "along_axis": None, "at": "spike", **what,
                             "cut_length": length, "first_seam": first_seam}))
    return out


def _cut_key(isl: Island, *what) -> tuple:
    """The search cache's key of a cut of ``isl`` (:func:`_halvings`): an island is the same
    while its faces and UV arrays are (the search makes new islands, it never changes one), so
    the rounds, the quarter-turned judgements and the pairs reuse what an earlier step cut
    instead of cutting it again (the same cut: :func:`texture.halving.halve_across` and
    :func:`texture.spikes.spike_cuts` depend on the island only)."""
    return ("cut", id(isl.faces), id(isl.uv), *what)


def _cached(cache: dict, isl: Island, key: tuple) -> bool:
    """``key`` holds a cut of this island (the entry keeps its arrays, so no other array can take their ids)."""
    hit = cache.get(key)
    return hit is not None and hit[0] is isl.faces and hit[1] is isl.uv


def _adjacency(isl: Island, cache: dict):
    """The island's face adjacency, made once for all its cuts."""
    key = _cut_key(isl, "adjacency")
    if not _cached(cache, isl, key):
        cache[key] = (isl.faces, isl.uv, face_adjacency(isl.xyz, isl.faces))
    return cache[key][2]


def _halve_job(job, _shared=None):
    """A worker's :func:`halve_across` of ``(island, along, cuts, adjacency)``."""
    isl, along, cuts, adj = job
    return halve_across(isl, along, cuts, adj)


#: one round's halvings (islands after each, its description) and the ``PACK_SEARCHED`` best
#: guesses among them (candidate index, mode index)
Ranked = tuple[list[tuple[list[Island], dict]], list[tuple[int, int]]]


def _ranked_halvings(islands: list[Island], comp: np.ndarray, cfg, cache: dict, first_seam: bool = False,
                     spikes: bool = False) -> Ranked:
    """Every halving this round (:func:`_halvings`, with ``spikes``), each guessed in
    :data:`HALVING_MODES` by one unbounded pack, and the best guesses."""
    cands = _halvings(islands, comp, cfg, first_seam, cache, spikes=spikes)
    return cands, _best_guesses([c for c, _ in cands], islands, cfg, cache)


def _mode_guesses(layouts: list[list[Island]], tol: float, cfg, cache: dict) -> list[tuple[float, int, int]]:
    """(guessed utilisation, layout index, mode index) of each layout in each mode of
    :data:`HALVING_MODES`: one unbounded pack of its outlines, simplified within ``tol``."""
    out = []
    for m in HALVING_MODES:
        mode = PACK_MODES[m]
        arrays = [outline_arrays(turned(c, mode, cache), cache, tolerance=tol) for c in layouts]
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


def _chosen(options: list[tuple], cfg, base: float) -> tuple:
    """Which of a round's packed halvings that pay is made: ``options`` are (packing, length of
    the cut, what it is, and whatever else the caller keeps with it), ``base`` the utilisation of the layout they cut. A halving buys
    utilisation with seam. Where some reach ``cfg.pack_target``, the one with the shortest
    cut among them (utilisation past the target buys nothing its extra seam is worth); else
    the one that buys the most utilisation per length of cut (the next round buys the rest).
    Measured against the most utilisation (docs/unwrap.md, step 9): the cup with a handle
    took a cut of 3.29 for 0.623 where one of 1.42 packed 0.605 (seam 4.44 -> 3.87), the
    sphere's first cut 2.70 for 0.506 where one of 1.82 packed 0.504 (seam 3.22 -> 2.91)."""
    reach = [o for o in options if o[0].utilization >= cfg.pack_target]
    if reach:
        return min(reach, key=lambda o: (o[1], -o[0].utilization))
    return max(options, key=lambda o: (o[0].utilization - base) / max(o[1], 1e-12))  # the first of equals


def _best_halving(ranked: Ranked, cfg, base: float | None, floor: float, cache: dict) -> tuple[Packed, dict] | None:
    """The halving :func:`_chosen` makes among a round's best guesses
    (:func:`_ranked_halvings`), each packed, and its description; None if none packs above
    ``floor``. ``base``: the utilisation of the layout the round cuts; None for the one that
    packs best (a round that fell short, whose halvings are judged again quarter-turned: what
    it gains there, not per length before, is what is asked of it)."""
    cands, top = ranked
    options = [(got, cands[i][1]["cut_length"], cands[i][1]) for i, m in top
               if (got := best_packed([cands[i][0]], [m], cfg, cache, floor)) is not None]
    if not options:
        return None
    got, _, d = (_chosen(options, cfg, base) if base is not None
                 else max(options, key=lambda o: o[0].utilization))  # the first of equals
    return got, d


def _paired_halvings(islands: list[Island], comp: np.ndarray, cfg, cache: dict, ranked: list[Ranked],
                     floor: float) -> tuple[Packed, list[dict]] | None:
    """Two halvings at once, for the islands where no single one paid: among the layouts cut
    twice that gain what both cuts must buy over ``floor`` (each a first seam or an ordinary
    cut, as :func:`_halvings` makes them), the one :func:`_chosen` makes (the two cuts' length
    together), with its two descriptions; else None.

    One cut can leave the atlas's shape as it was, so that its gain shows only with a second:
    two like parts (two tori unrolled as strips lie stacked 2:1 however one is halved: 0.40,
    both halved 0.76 as delivered), or an island whose halves are each as wide as the whole
    (an open cone's sector: 0.38, 0.41 halved once, 0.67 twice). Such a first cut halves an island
    evenly (two like halves side by side keep the whole's aspect), so the first cuts are the
    middle ones of the round that fell short (``ranked``: its ordinary and first-seam
    candidates; a single cut's guess cannot rank them, as their gain shows only in pairs):
    at most two axes of ``PACK_CUT_ISLANDS`` islands; each layout they leave is halved evenly
    again (the second cut of such a pair is the even one too), and the pairs are guessed and
    searched like one round's halvings; the one that packs best is judged quarter-turned too,
    and the pair made is delivered quarter-turned where that packs better."""
    firsts = [c for cands, _ in ranked for c in cands if c[1]["at"] == "middle"]
    pairs = [(c, [first, d]) for layout, first in firsts for seam in (False, True)
             for c, d in _halvings(layout, comp, cfg, seam, cache, middle_only=True)]
    modes: dict[int, list[int]] = {}  # the best guesses' modes of each pair, best first
    for j, m in _best_guesses([c for c, _ in pairs], islands, cfg, cache):
        modes.setdefault(j, []).append(m)

    def need(j: int) -> float:
        return floor + sum(cfg.pack_first_seam_gain if d["first_seam"] else cfg.pack_cut_gain for d in pairs[j][1])

    packed = {j: got for j, ms in modes.items()
              if (got := best_packed([pairs[j][0]] * len(ms), ms, cfg, cache)) is not None}
    # the pair that packs best is judged as it will be delivered, quarter-turned (the turns
    # are the search's most costly step, so one pair, as for the halving that fell short)
    turned_pair = None
    if packed:
        j = max(packed, key=lambda k: packed[k].utilization)  # the first of equals
        if (got := quarter_turned(pairs[j][0], cfg, cache, max(need(j), packed[j].utilization))) is not None:
            packed[j], turned_pair = got, j
    options = [(got, sum(d["cut_length"] for d in pairs[j][1]), pairs[j][1], j) for j, got in packed.items()
               if got.utilization >= need(j)]
    if not options:
        return None
    got, _, descriptions, j = _chosen(options, cfg, floor)
    if j != turned_pair:  # delivered quarter-turned where that packs better
        got = quarter_turned(pairs[j][0], cfg, cache, got.utilization) or got
    return got, descriptions


def choose_layout(islands: list[Island], comp: np.ndarray, cfg,
                  note: Callable[[str], None] | None = None) -> LayoutChoice:
    """The islands turned (and halved) as packs best; see module docstring. ``comp`` is the
    connected component of every working face; ``cfg`` a :class:`texture.unwrap.UnwrapConfig` or a
    :class:`LayoutGoal` (the export's).

    The rounds are greedy, and a protrusion's cut (:mod:`texture.spikes`) is short, so it
    gains the most per length and is made first; where the rounds made one and still end
    below ``cfg.pack_target``, they are run again without such cuts and the layout that packs
    better is kept: which cuts add up to the most is not known from the first (on the
    benchmark fits' limbs, protrusions cut off first packed 0.567 where three halvings
    packed 0.576). Where none was made, the rounds without them would make the same cuts
    (the candidates they share are ranked alike), and are not run.

    ``note``: called with a line as each step of the search starts (the stage bar's text: the
    search runs 2-35 s on the unwraps of benchmarks/RESULTS.md, 14 s on a 1,000-face mesh of
    12 islands); it does not change what is chosen."""
    say = note or (lambda _: None)
    cache: dict = {}  # outlines of the islands tried (:func:`outline_arrays`)
    uncut = best_packed([islands] * len(UNCUT_MODES), list(UNCUT_MODES), cfg, cache)
    if uncut is None:  # xatlas placed nothing: the packer's own fallbacks (a shelf packing)
        return LayoutChoice(islands, pack_islands(*island_arrays(islands), resolution=cfg.resolution,
                                                  padding=cfg.padding), {"mode": 0, "halvings": []})
    best, stats = _exhaustive(*_rounds(uncut, comp, cfg, cache, spikes=True, say=say), cfg, cache, say)
    if best.utilization < cfg.pack_target and any(h["at"] == "spike" for h in stats["halvings"]):
        say("pack: the rounds again, without protrusion cuts")
        plain, plain_stats = _exhaustive(*_rounds(uncut, comp, cfg, cache, spikes=False, say=say), cfg, cache, say)
        spiked = best.utilization
        if plain.utilization > best.utilization:
            best, stats = plain, {**plain_stats, "spike_candidates": stats["spike_candidates"]}
        stats["with_spikes"], stats["without_spikes"] = spiked, plain.utilization
    stats["mode"] = best.mode
    return LayoutChoice(best.placed, whole_islands(best.placed, best.index, best.packing), stats)


def _exhaustive(best: Packed, stats: dict, cfg, cache: dict, say: Callable[[str], None]) -> tuple[Packed, dict]:
    """``best`` packed with xatlas's exhaustive placement where that packs tighter (module
    docstring, step 5), and ``stats`` with what it did."""
    say(f"pack: exhaustive placement (utilisation {best.utilization:.2f})")
    stats["utilization_before_brute"] = best.utilization
    t0 = time.perf_counter()
    brute = brute_packed(best, cfg, cache)
    stats["brute_force_seconds"] = time.perf_counter() - t0
    if brute is not None:
        best = brute
        stats["brute_force"] = True
    return best, stats


def _rounds(uncut: Packed, comp: np.ndarray, cfg, cache: dict, spikes: bool,
            say: Callable[[str], None]) -> tuple[Packed, dict]:
    """The halving rounds from the uncut layout's packing ``uncut``, then the quarter turns,
    the halving that fell short quarter-turned and the paired halvings (module docstring,
    steps 2-4): (the packing, what was done). ``spikes``: protrusions cut off at their necks
    are candidates of the ordinary rounds too."""
    best = uncut
    stats = {"utilization_uncut": best.utilization, "halvings": [], "spike_candidates": 0}
    fell_short = None  # the ordinary round at which the rounds ended, its halving not paying
    first: Ranked = ([], [])
    for r in range(cfg.pack_max_cuts):
        if best.utilization >= cfg.pack_target:
            break
        say(f"pack round {r + 1}: utilisation {best.utilization:.2f}, {len(best.islands)} islands")
        ranked = _ranked_halvings(best.islands, comp, cfg, cache, spikes=spikes)
        stats["spike_candidates"] += sum(d["at"] == "spike" for _, d in ranked[0])
        got = _best_halving(ranked, cfg, best.utilization, best.utilization + cfg.pack_cut_gain, cache)
        if got is None:
            # a part's first seam (it flattened as one island) must buy more
            first = _ranked_halvings(best.islands, comp, cfg, cache, True, spikes=spikes)
            stats["spike_candidates"] += sum(d["at"] == "spike" for _, d in first[0])
            got = _best_halving(first, cfg, best.utilization, best.utilization + cfg.pack_first_seam_gain, cache)
            if got is None:
                fell_short = ranked
                break
        best = got[0]
        stats["halvings"].append({**got[1], "utilization": best.utilization})
    stats["utilization_turned_as_xatlas"] = best.utilization
    cut = best  # the rounds' layout, on which their last rankings were made
    if len(best.islands) > 1:
        say(f"pack: quarter turns (utilisation {best.utilization:.2f})")
        best = quarter_turned(best.islands, cfg, cache, best.utilization) or best
    if fell_short is not None and best.utilization < cfg.pack_target:
        # the halvings that fell short (their round's guesses kept), judged as they will be
        # delivered: quarter-turned too; an ordinary one first, then a first seam (as the
        # rounds try them), each for what it must buy
        say("pack: the last halving, quarter-turned")
        for ranking, gain in ((fell_short, cfg.pack_cut_gain), (first, cfg.pack_first_seam_gain)):
            missed = _best_halving(ranking, cfg, None, 0.0, cache)
            turned_halving = None if missed is None else quarter_turned(missed[0].islands, cfg, cache,
                                                                         best.utilization + gain)
            if turned_halving is not None:
                best = turned_halving
                stats["halvings"].append({**missed[1], "utilization": best.utilization, "after_quarter_turns": True})
                break
    # the rounds' own cuts: a pair is made on their layout (``cut``), in place of a missed
    # halving kept above
    made = [h for h in stats["halvings"] if not h.get("after_quarter_turns")]
    if fell_short is not None and best.utilization < cfg.pack_target and len(made) + 2 <= cfg.pack_max_cuts:
        say("pack: two cuts at once")
        pair = _paired_halvings(cut.islands, comp, cfg, cache, [fell_short, first], best.utilization)
        if pair is not None:
            best = pair[0]  # already quarter-turned where that packs better
            stats["halvings"] = made + [{**d, "utilization": best.utilization, "paired": True} for d in pair[1]]
    return best, stats
