"""The stages between trimming and packing: orient, relax, unmirror, choose the layout.

Each stage takes the previous one's typed result and decides once; pieces are prepared
(:func:`texture.layouts.prepare`) once and the prepared values travel with them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import policy as P
from .atlas_config import AtlasConfig
from .atlas_stats import OrientStats, RelaxStats
from .layout_search import LayoutChoice, search_layouts
from .layouts import Prepared, island_count, prepare, unmirrored
from .orient import Reference, orient_pieces
from .relax import RelaxConfig, relax_meshes
from .trim import Piece


@dataclass(frozen=True)
class Oriented:
    """The orientation stage: the pieces, prepared, and its stats (None: not oriented)."""

    layout: list[Prepared]
    stats: OrientStats | None


def orient_stage(pieces: list[Piece], reference: Reference | None, cfg: AtlasConfig) -> Oriented:
    """:func:`orient_pieces` with fragment islands (``cfg.orient_fragment_island``) only where
    they keep the atlas within ``cfg.max_islands``, or where it exceeds that without them too.

    A fragment island trades a little folded area for an island: on a many-part shape (already
    over the island budget) that is the better trade, on a single-part one the few islands are
    the point (a torus: 6 islands without them, 13 with). Without a reference (or with
    ``cfg.orient`` off) the pieces pass unchanged.
    """
    if reference is None or not cfg.orient:
        return Oriented([prepare(p) for p in pieces], None)
    total = sum(float(p.area().sum()) for p in pieces)
    min_area = cfg.trim.min_island_fraction * total
    if cfg.orient_fragment_island <= 0:
        out, stats = orient_pieces(pieces, reference, min_area)
        return Oriented([prepare(p) for p in out], OrientStats(**stats))
    out, stats = orient_pieces(pieces, reference, min_area, min_fragment_island=cfg.orient_fragment_island * total)
    layout = [prepare(p) for p in out]
    # orientation splits and reverses islands but never merges them: when the pieces already
    # have more islands than the budget, orienting again without fragment islands cannot
    # get within it (and would cost a second orientation)
    if 0 < cfg.max_islands < island_count(layout) and island_count([prepare(p) for p in pieces]) <= cfg.max_islands:
        plain, plain_stats = orient_pieces(pieces, reference, min_area)
        plain_layout = [prepare(p) for p in plain]
        if island_count(plain_layout) <= cfg.max_islands:
            return Oriented(plain_layout, OrientStats(**plain_stats, orient_fragment_islands=False))
    return Oriented(layout, OrientStats(**stats, orient_fragment_islands=True))


@dataclass(frozen=True)
class Relaxed:
    """The relaxation stage: the relaxed pieces (None: not relaxed) and their stats."""

    pieces: list[Piece] | None
    stats: RelaxStats


def relax_stage(layout: list[Prepared], cfg: RelaxConfig) -> Relaxed:
    """Every island of the prepared pieces relaxed by :func:`texture.relax.relax_meshes` at
    one shared scale (all islands in parallel).

    The relaxed pieces are the prepared ones (welded, islands split at shared vertices) with
    new UVs, still in chart units; stats as :class:`texture.atlas_stats.RelaxStats`.
    """
    live = [pp for pp in layout if pp.island is not None]
    stats = RelaxStats()
    if cfg.iterations <= 0 or not live:
        return Relaxed(None, stats)
    # one scale for all charts (UVs in chart units -> isometric units), as isometric_scale
    uv_total = sum(float(pp.piece.uv_area().sum()) for pp in live)
    scale = float(np.sqrt(sum(float(pp.piece.area().sum()) for pp in live) / uv_total)) if uv_total > 0 else 1.0
    done = iter(relax_meshes([(pp.piece.xyz, pp.piece.uv, pp.piece.faces, pp.island) for pp in live], cfg,
                             scale=scale))
    out, before, after, area = [], 0.0, 0.0, 0.0
    for pp in layout:
        if pp.island is None:
            out.append(pp.source)
            continue
        uv_new, st = next(done)
        q = pp.piece
        out.append(Piece(q.chart, q.xyz, uv_new, q.faces))
        before += st["area"] * st["energy_before"]
        after += st["area"] * st["energy_after"]
        area += st["area"]
        stats.iterations_max = max([stats.iterations_max, *st["iterations"]])
        stats.stopped_by_crossing += st["stopped_by_crossing"]
    stats.energy_before = before / area if area > 0 else float("nan")
    stats.energy_after = after / area if area > 0 else float("nan")
    return Relaxed(out, stats)


def unmirrored_layout(layout: list[Prepared]) -> list[Prepared]:
    """The prepared pieces with mirrored islands reflected (:func:`texture.layouts.unmirrored`);
    a piece with none keeps its prepared value."""
    out = []
    for pp in layout:
        p = unmirrored(pp)
        out.append(pp if p is pp.source else prepare(p))
    return out


def choose_layout(relaxed: list[Prepared], raw: list[Prepared] | None, cfg: AtlasConfig,
                  stats: RelaxStats, policy: P.SearchPolicy = P.DEFAULT_POLICY) -> LayoutChoice:
    """The layout to pack: of the relaxed islands, or (``raw``, the charts' own UVs, given when
    the pieces were relaxed) of the unrelaxed ones where :func:`texture.policy.keep_relaxed`
    says so. Records the choice in ``stats``."""
    goal = cfg
    choice = search_layouts(relaxed, goal, policy)
    if raw is None or not 0 < goal.target_utilization:
        return choice
    stats.kept = True
    if P.utilization(choice.plan) >= goal.target_utilization:
        return choice
    other = search_layouts(raw, goal, policy)
    stats.compared_unrelaxed = True
    stats.coarse_relaxed = P.utilization(choice.plan)
    stats.coarse_unrelaxed = other.plan.utilization if other.plan is not None else None
    if P.keep_relaxed(choice.plan, other.plan, goal.target_utilization):
        return choice
    stats.kept = False
    return other
