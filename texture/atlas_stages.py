"""The stages between trimming and packing: orient, relax, unmirror, and the islands handed to the packing search.

Each stage takes the previous one's typed result and decides once; pieces are prepared
(:func:`texture.layouts.prepare`) once and the prepared values travel with them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .atlas_config import AtlasConfig
from .atlas_stats import OrientStats, RelaxStats
from .layout_packing import island_arrays
from .layouts import Merged, Prepared, island_count, prepare, unmirrored
from .orient import Reference, orient_pieces
from .relax import RelaxConfig, relax_meshes
from .trim import Piece
from .unwrap_islands import Island
from .unwrap_layout import MAX_CUTS, LayoutGoal


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


def layout_goal(cfg: AtlasConfig) -> LayoutGoal:
    """The packing search's aim (:func:`texture.unwrap_layout.choose_layout`) from the export's
    options: its utilisation target and cut gain, and ``max_islands`` as the island target
    (halvings never take the atlas from within it to past it, one at it must buy a first
    seam's gain; ``max_islands`` 0: no halvings, only turns)."""
    return LayoutGoal(resolution=cfg.resolution, padding=cfg.padding, pack_target=cfg.target_utilization,
                      pack_cut_gain=cfg.split_gain, long_max_islands=cfg.max_islands,
                      pack_max_cuts=MAX_CUTS if cfg.max_islands > 0 else 0)


def layout_islands(layout: list[Prepared]) -> list[Island]:
    """The prepared pieces' islands as the packing search takes them.

    Each island is its piece's faces of one island id with their own vertices; ``work_faces``
    and ``work_vertex`` number faces and vertices over the pieces in order, ``label`` is the
    chart. The pieces are separate meshes, so the atlas is one part
    (:func:`texture.halving.island_parts`: every face of component 0) and ``max_islands``
    counts all its islands (``work_faces`` number the faces as :func:`texture.layouts.merge`
    lays the pieces out).
    """
    out, f_off, v_off = [], 0, 0
    for pp in layout:
        if pp.island is None:
            continue
        p = pp.piece
        for k in range(pp.n_islands):
            sel = np.flatnonzero(pp.island == k)
            vid, inv = np.unique(p.faces[sel], return_inverse=True)
            out.append(Island(inv.reshape(-1, 3).astype(np.int64), np.asarray(p.uv[vid], np.float64),
                              np.asarray(p.xyz[vid], np.float64), f_off + sel, v_off + vid, int(p.chart)))
        f_off += len(p.faces)
        v_off += len(p.xyz)
    return out


def joined(islands: list[Island]) -> Merged:
    """The packed islands as one split-vertex mesh (island ``k`` numbered ``k``; its UVs are
    replaced by the packing's afterwards)."""
    uv, faces, island = island_arrays(islands)
    chart = np.repeat([isl.label for isl in islands], [len(isl.faces) for isl in islands])
    return Merged(np.concatenate([isl.xyz for isl in islands]), uv, faces, chart, island)
