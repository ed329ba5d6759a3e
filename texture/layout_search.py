"""Which layout of the islands to pack: as they are, or with one island cut in two.

The layouts are packed at the coarse resolution (:func:`texture.scale_search.plan_layouts`)
in rounds, as :mod:`texture.policy` decides: round one, the uncut islands and the centroid
cuts with xatlas's default options, then the other option sets; round two, while no layout
reached the target, the off-centre cuts, best first guess first. The best cut is kept when
it gains ``split_gain`` over the uncut islands.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import policy as P
from .atlas_config import AtlasConfig
from .layouts import Merged, Prepared, cut_layout, island_count, merge
from .parallel import default_workers
from .scale_search import Plan, estimate_layouts, plan_layouts


@dataclass(frozen=True)
class Cut:
    """One island cut: the island's rank by UV area, the cut's axis and position."""

    island_rank: int
    across_long_axis: bool
    area_fraction: float
    through_centroid: bool

    def to_json(self) -> dict:
        return {"island_rank": self.island_rank, "across_long_axis": self.across_long_axis,
                "area_fraction": self.area_fraction, "through_centroid": self.through_centroid}


@dataclass(frozen=True)
class Candidate:
    """A layout: prepared pieces, and the cut that made it (None: the islands as they are)."""

    layout: list[Prepared]
    cut: Cut | None = None

    @property
    def islands(self):
        return merge(self.layout).islands


@dataclass
class LayoutStats:
    """What the layout search found (coarse utilisations; ``None`` where not searched)."""

    split_islands: int = 0
    utilization_coarse_uncut: float | None = None
    utilization_coarse_cuts: list[float] | None = None
    utilization_coarse_off_centre_cuts: list[float | None] | None = None
    utilization_coarse_cut: float | None = None
    cut: Cut | None = None

    def to_json(self) -> dict:
        """The keys set so far, in atlas.json's order (a search that stopped early has fewer)."""
        out = {"split_islands": self.split_islands}
        for key in ("utilization_coarse_uncut", "utilization_coarse_cuts", "utilization_coarse_off_centre_cuts",
                    "utilization_coarse_cut"):
            if getattr(self, key) is not None:
                out[key] = getattr(self, key)
        if self.cut is not None:
            out["cut"] = self.cut.to_json()
        return out


@dataclass(frozen=True)
class LayoutChoice:
    """The layout to pack, its coarse plan (None: xatlas found none), what the search found."""

    merged: Merged
    plan: Plan | None
    stats: LayoutStats = field(default_factory=LayoutStats)


def ranked_islands(layout: list[Prepared]) -> list[tuple[float, int, int]]:
    """(UV area, piece, island) of every island, largest first."""
    ranked = []
    for k, pp in enumerate(layout):
        if pp.island is not None:
            area = np.bincount(pp.island, weights=pp.source.uv_area())  # same faces, same ids
            ranked += [(float(a), k, i) for i, a in enumerate(area)]
    ranked.sort(key=lambda t: (-t[0], t[1], t[2]))
    return ranked


def cut_candidates(layout: list[Prepared], ranked: list, cuts: P.CutSet, max_islands: int) -> list[Candidate]:
    """The layouts of ``cuts`` on the ranked islands that keep within ``max_islands``."""
    out = []
    for rank, (_, k, i) in enumerate(ranked[:cuts.islands]):
        for long_axis in cuts.axes:
            for fraction in cuts.fractions:
                cut = cut_layout(layout, k, i, long_axis, fraction)
                if island_count(cut) <= max_islands:
                    out.append(Candidate(cut, Cut(rank, long_axis, 0.5 if fraction is None else fraction,
                                                  fraction is None)))
    return out


def _round_one(candidates: list[Candidate], goal: AtlasConfig, policy: P.SearchPolicy) -> list[Plan | None]:
    """Every layout with xatlas's default options, then the other option sets for the layouts
    :func:`texture.policy.other_options_for` names. Each layout keeps its better plan.

    Each layout gets a fresh search: xatlas's validity is not monotone in the scale, so a
    search from another layout's scale can stop at the first failure far below what a fresh
    guess finds.
    """
    arrays = [c.islands for c in candidates]
    kw = {"resolution": goal.resolution, "padding": goal.padding, "max_attempts": policy.max_attempts}
    plans = plan_layouts(arrays, candidates=policy.pack_candidates[:1], **kw)
    again = P.other_options_for(plans, goal.target_utilization)
    more = plan_layouts([arrays[i] for i in again], candidates=policy.pack_candidates[1:], **kw)
    for i, p in zip(again, more):
        if p is not None and (plans[i] is None or p.utilization > plans[i].utilization):
            p.attempts += plans[i].attempts if plans[i] is not None else 0
            plans[i] = p
        elif p is not None:
            plans[i].attempts += p.attempts
    return plans


def off_centre_plans(arrays: list, goal: AtlasConfig, policy: P.SearchPolicy = P.DEFAULT_POLICY,
                     workers: int | None = None) -> list[Plan | None]:
    """Coarse plans of the off-centre cut layouts ``arrays`` (None where not searched).

    Their first guesses (one xatlas call each) rank them; a layout whose guess is far below
    the target (``policy.prune_margin``) is not searched, and the others are searched best
    guess first, ``workers`` at a time, until one reaches the target. The guess ranks layouts
    only roughly (the best search can have one of the lower guesses), so batches continue
    until the target is reached rather than stopping at the best guess.
    """
    opts = policy.pack_candidates[0]
    workers = workers or default_workers()
    kw = {"resolution": goal.resolution, "padding": goal.padding}
    guess = estimate_layouts(arrays, options=opts, workers=workers, **kw)
    order = P.off_centre_order(guess, goal.target_utilization, policy.prune_margin)
    plans = [None] * len(arrays)
    for at in range(0, len(order), workers):
        batch = order[at:at + workers]
        found = plan_layouts([arrays[i] for i in batch], candidates=(opts,), starts=[guess[i].tpu for i in batch],
                             workers=workers, max_attempts=policy.max_attempts, **kw)
        for i, p in zip(batch, found):
            plans[i] = p
        if any(p is not None and p.utilization >= goal.target_utilization for p in plans):
            break
    return plans


def search_layouts(layout: list[Prepared], goal: AtlasConfig,
                   policy: P.SearchPolicy = P.DEFAULT_POLICY) -> LayoutChoice:
    """The islands as they are, or with one cut: the layout that packs best (module docstring)."""
    stats = LayoutStats()
    ranked = []
    if goal.max_islands > 0 and island_count(layout) + 1 <= goal.max_islands:
        ranked = ranked_islands(layout)
    candidates = [Candidate(layout)] + cut_candidates(layout, ranked, policy.centroid_cuts, goal.max_islands)
    if len(candidates) == 1:
        arrays = candidates[0].islands
        plan = plan_layouts([arrays], candidates=policy.pack_candidates, resolution=goal.resolution,
                            padding=goal.padding, max_attempts=policy.max_attempts)[0]
        return LayoutChoice(merge(layout), plan, stats)
    plans = _round_one(candidates, goal, policy)
    base = plans[0]
    if base is None:
        return LayoutChoice(merge(layout), base, stats)
    stats.utilization_coarse_uncut = base.utilization
    stats.utilization_coarse_cuts = [p.utilization for p in plans[1:] if p is not None]
    if P.widen(plans, goal.target_utilization):
        wider = cut_candidates(layout, ranked, policy.off_centre_cuts, goal.max_islands)
        if wider:
            more = off_centre_plans([c.islands for c in wider], goal, policy)
            stats.utilization_coarse_off_centre_cuts = [None if p is None else p.utilization for p in more]
            candidates, plans = candidates + wider, plans + more
    best = P.best_cut(plans)
    if P.keep_cut(base, plans[best], goal.split_gain):
        stats.split_islands = 1
        stats.utilization_coarse_cut = plans[best].utilization
        stats.cut = candidates[best].cut
        return LayoutChoice(merge(candidates[best].layout), plans[best], stats)
    return LayoutChoice(merge(layout), base, stats)
