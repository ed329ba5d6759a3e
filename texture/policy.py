"""The packing search policy: how hard to search, which layouts to try, when to fall back.

Everything the export *decides* about packing is here, as a :class:`SearchPolicy` (the
knobs) and small pure functions on search results (the decisions); the mechanics that
carry them out are :mod:`texture.layout_search` (cuts and rounds) and :mod:`texture.pack`
(the final packing). The export's guarantees do not depend on the policy: whatever it
says, a packing never overlaps, never mirrors an island, and stays inside the unit square
(a shelf packing is the last resort, :mod:`texture.shelf`); the policy only trades time
for utilisation.

Why the defaults are what they are. xatlas's packer is a heuristic: which island cut
helps, and which option set packs best, is not predictable from the islands' shapes
(neither the islands' bounding-box nor convex-hull fill ranks the cuts), so layouts are
*packed* to be compared, and the number of layouts tried is the cost.
"""
from __future__ import annotations

from dataclasses import dataclass

from .scale_search import Plan


@dataclass(frozen=True)
class CutSet:
    """Cuts tried on the ``islands`` largest islands (by UV area): across (True) and/or along
    (False) their principal axis, at each of ``fractions`` of their area (None = through the
    UV centroid)."""

    islands: int
    axes: tuple[bool, ...]
    fractions: tuple[float | None, ...]


@dataclass(frozen=True)
class SearchPolicy:
    """Knobs of the packing search (the defaults are :data:`DEFAULT_POLICY`)."""

    pack_candidates: tuple[dict, ...] = ({}, {"rotate_charts": False})
    """xatlas ``PackOptions`` overrides tried in turn (highest utilisation kept). 90-degree
    turns help islands of differing aspect and can hurt a few large near-square ones
    (a 3-chart fit at 2048: 0.51 with them, 0.54 without); ``bruteForce`` gained < 0.001
    at 12x the time, so it is not tried."""
    max_attempts: int = 16
    """xatlas calls per scale search."""
    centroid_cuts: CutSet = CutSet(3, (True,), (None,))
    """Round one: the largest islands cut through their UV centroid, across their long axis
    (halving the long side; a cut along it never packed best). Three, not two: the third
    largest island's cut is sometimes the only one to reach the target, and each more costs
    one coarse search per option set."""
    off_centre_cuts: CutSet = CutSet(2, (True, False), (0.25, 0.75))
    """Round two, only while no layout reached the target: a quarter of the area cut off
    either end of the two largest islands, across and along their axis, with xatlas's default
    options only (the best off-centre cut was always of one of the two largest islands and
    packed best with the default options; it lifted fits from about 0.55 to 0.6 where every
    centroid cut stayed below)."""
    prune_margin: float = 0.07
    """A search may give up after its first guess (an unbounded pack) when that implies a
    utilisation this far below the target: the bounded search ended between 0.01 below and
    0.065 above the first guess on every layout measured."""
    mirror_tries: int = 5
    """xatlas calls per placement to get every island the right way round before turning
    the rest back in their boxes (:func:`texture.placement.attempt`)."""
    unmirror_steps: int = 8
    """Scale steps (``FINE_SHRINK`` each) tried for a packing with no island mirrored before
    the search without xatlas's 90-degree turns (which never mirror)."""

    def __post_init__(self):
        for name, least in (("max_attempts", 1), ("mirror_tries", 1), ("unmirror_steps", 0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < least:
                raise ValueError(f"SearchPolicy.{name} must be an integer >= {least}, got {value!r}")
        if not self.prune_margin >= 0:
            raise ValueError(f"SearchPolicy.prune_margin must be >= 0, got {self.prune_margin!r}")


DEFAULT_POLICY = SearchPolicy()


def utilization(plan: Plan | None) -> float:
    """A plan's utilisation, -1 for no plan (never the best)."""
    return plan.utilization if plan is not None else -1.0


def best_cut(plans: list[Plan | None]) -> int:
    """Index of the best plan among the cut layouts (``plans[1:]``; ``plans[0]`` is uncut)."""
    return max(range(1, len(plans)), key=lambda i: utilization(plans[i]))


def reached(plans: list[Plan | None], target: float) -> bool:
    """Whether some layout packs at least ``target`` (never, for target 0: "no target")."""
    return max(utilization(p) for p in plans) >= target > 0


def other_options_for(plans: list[Plan | None], target: float) -> list[int]:
    """Layouts that are searched with the other option sets after xatlas's defaults: every
    layout while none reached ``target``, else only the uncut islands and the best cut."""
    return [0, best_cut(plans)] if reached(plans, target) else list(range(len(plans)))


def widen(plans: list[Plan | None], target: float) -> bool:
    """Whether the off-centre round runs: no centroid layout packs ``target``."""
    return max(p.utilization for p in plans if p is not None) < target


def keep_cut(base: Plan, cut: Plan | None, split_gain: float) -> bool:
    """A cut adds a seam: keep it only when it gains ``split_gain`` of utilisation."""
    return cut is not None and cut.utilization >= base.utilization + split_gain


def off_centre_order(guesses: list, target: float, margin: float) -> list[int]:
    """Off-centre layouts worth a search, best first guess first: those whose guess (an
    :class:`texture.scale_search.Estimate` or None) is within ``margin`` of ``target``."""
    live = (i for i, g in enumerate(guesses) if g is not None and g.utilization >= target - margin)
    return sorted(live, key=lambda i: (-guesses[i].utilization, i))


def keep_relaxed(relaxed: Plan | None, raw: Plan | None, target: float) -> bool:
    """Relaxed islands are rounder than the charts' near-square domains and can pack looser:
    the charts' own UVs replace them only when the relaxed layout misses ``target`` and the
    unrelaxed one reaches it."""
    return not (utilization(relaxed) < target and raw is not None and raw.utilization >= target)
