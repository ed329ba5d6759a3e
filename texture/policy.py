"""The packing policy: how hard one packing searches, and when it falls back.

The knobs of :func:`texture.pack.pack_islands` are here, as a :class:`SearchPolicy`; which
layouts (turns, halvings) are packed is :mod:`texture.unwrap_layout`'s search. The
guarantees do not depend on the policy: whatever it says, a packing never overlaps, never mirrors an island, and stays inside the unit square
(a shelf packing is the last resort, :mod:`texture.shelf`); the policy only trades time
for utilisation.

Why the defaults are what they are. xatlas's packer is a heuristic: which option set packs
best is not predictable from the islands' shapes, so the option sets are *packed* to be
compared, and the number of packings tried is the cost.
"""
from __future__ import annotations

from dataclasses import dataclass


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


DEFAULT_POLICY = SearchPolicy()
