"""Charts -> one packed UV atlas: trim overlaps, cut clean borders, split islands, pack.

``build_atlas(charts)`` chains :mod:`texture.trim` (one layer of surface, iso-line
borders) and :mod:`texture.pack` (xatlas packer, one texel density for all charts: every
island keeps its chart-local UV up to a rigid motion and one shared scale, because the
distortion loss shares one scale across charts). The result is a :class:`UVMesh` in the
input frame with UVs in [0,1]^2, plus the measurements the issue asks for.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .charts import ChartGrids
from mna.pointmetrics import POINTS, chamfer_fscore
from .geometry import sample_surface
from .islands import unique_rows, uv_islands
from .orient import Reference, orient_pieces
from .clip import UV_COLUMNS, clip_mesh
from .relax import RelaxConfig, relax_meshes
from .pack import PACK_CANDIDATES, PRUNE_MARGIN, Packing, estimate_layouts, pack_islands, plan_layouts
from .parallel import default_workers
from .trim import Piece, TrimConfig, trim_charts
from .uvmesh import Normalization, UVMesh, make_uv_mesh


@dataclass
class AtlasConfig:
    """Options of :func:`build_atlas`."""

    resolution: int = 2048
    """Texture size (texels) the islands are packed for."""
    padding: int = 8
    """Gutter around each island, in texels at ``resolution``."""
    trim: TrimConfig = field(default_factory=TrimConfig)
    orient: bool = True
    """With a reference surface, reorient inside-out parts of charts (:mod:`texture.orient`)."""
    orient_fragment_island: float = 2e-4
    """An inside-out fragment (under ``trim.min_island_fraction``) that the orientation's
    drop budget cannot take becomes an island of its own, reoriented, when it is at least
    this fraction of the total area; smaller ones stay with their surroundings (0 = all do)."""
    relax: RelaxConfig = field(default_factory=RelaxConfig)
    """Re-flatten every island toward an isometry before packing (:mod:`texture.relax`;
    ``relax.iterations = 0`` keeps the charts' own UVs)."""
    max_islands: int = 6
    """Cut the largest island in two when that packs tighter, if the atlas then has at most
    this many islands (0 = never cut)."""
    split_gain: float = 0.02
    """Cut only when utilisation (coarse packing) rises by at least this much: a cut adds a seam."""
    target_utilization: float = 0.6
    """When neither the uncut islands nor a centroid cut packs this tight (coarse packing),
    off-centre cuts are packed too: about 8 more coarse searches (a few seconds). And when
    the relaxed islands' best layout stays below it, the charts' own UVs are laid out too
    and kept instead if they reach it (``relax_kept``). 0 = never."""
    seed: int = 0
    """Seed of the surface samples used for the coverage check."""


@dataclass
class Atlas:
    """A packed atlas.

    Attributes:
        mesh: UV mesh in the input frame, UVs in [0,1]^2 (v up).
        chart: (F,) chart id of each face.
        island: (F,) island id of each face (islands are numbered chart by chart).
        normalization: input frame -> unit ball (from charts.npz).
        packing: packer result (scale, utilisation, ...).
        stats: JSON-friendly measurements (coverage, doubly covered area, islands, timings).
    """

    mesh: UVMesh
    chart: np.ndarray
    island: np.ndarray
    normalization: Normalization
    packing: Packing
    stats: dict

    @property
    def mesh_unit(self) -> UVMesh:
        return self.mesh.transformed(self.normalization)


def _prepared(p: Piece, cache: dict | None = None) -> tuple[Piece, np.ndarray]:
    """(``p`` welded, with vertices shared by islands split; island per face). ``cache``, keyed
    by the piece object, spares the work for the pieces that candidate layouts share."""
    if cache is not None and id(p) in cache:
        return cache[id(p)][1:]
    q = _welded(p)
    isl = uv_islands(q.faces, q.uv)
    out = (_split_shared(q, isl), isl)
    if cache is not None:
        cache[id(p)] = (p, *out)  # holding p keeps its id from being reused
    return out


def _merge(pieces: list[Piece], cache: dict | None = None):
    """Concatenate pieces -> (xyz, chart-local uv, faces, chart per face, island per face)."""
    xyz, uv, faces, chart, island = [], [], [], [], []
    v_off = i_off = 0
    for p in pieces:
        if len(p.faces) == 0:
            continue
        p, isl = _prepared(p, cache)
        xyz.append(p.xyz)
        uv.append(p.uv)
        faces.append(p.faces + v_off)
        chart.append(np.full(len(p.faces), p.chart))
        island.append(isl + i_off)
        v_off += len(p.xyz)
        i_off += int(isl.max()) + 1
    if not faces:
        raise ValueError("no chart has any in-domain surface left: nothing to texture")
    return tuple(np.concatenate(a) for a in (xyz, uv, faces, chart, island))


def _split_shared(p: Piece, island: np.ndarray) -> Piece:
    """One vertex per (vertex, island): islands touching at a single vertex (connected through
    no edge, so separate islands) must not share it, or packing one would move the other's corner."""
    n = int(island.max()) + 1
    key = p.faces.ravel() * n + np.repeat(island, 3)
    uniq, inverse = np.unique(key, return_inverse=True)
    if len(uniq) == len(p.xyz):
        return p
    return Piece(p.chart, p.xyz[uniq // n], p.uv[uniq // n], inverse.reshape(-1, 3))


def relax_pieces(pieces: list[Piece], cfg: RelaxConfig, cache: dict | None = None) -> tuple[list[Piece], dict]:
    """Every island of ``pieces`` relaxed by :func:`texture.relax.relax_meshes` at one shared scale
    (all islands in parallel).

    Returns the pieces (welded, islands split at shared vertices, UVs still in chart units)
    and stats: the 3D-area weighted mean of ``tr g + tr g^-1 - 4`` at the isometric scale
    before and after, SLIM iterations, islands stopped by a border crossing.
    """
    prepared = [(p, *_prepared(p, cache)) if len(p.faces) else (p, p, None) for p in pieces]
    live = [(q, isl) for _, q, isl in prepared if isl is not None]
    stats = {"relax_iterations_max": 0, "relax_stopped_by_crossing": 0}
    if cfg.iterations <= 0 or not live:
        return pieces, stats
    # one scale for all charts (UVs in chart units -> isometric units), as isometric_scale
    uv_total = sum(float(q.uv_area().sum()) for q, _ in live)
    scale = float(np.sqrt(sum(float(q.area().sum()) for q, _ in live) / uv_total)) if uv_total > 0 else 1.0
    out, before, after, area = [], 0.0, 0.0, 0.0
    done = iter(relax_meshes([(q.xyz, q.uv, q.faces, isl) for _, q, isl in prepared if isl is not None],
                             cfg, scale=scale))
    for p, q, isl in prepared:
        if isl is None:
            out.append(p)
            continue
        uv_new, st = next(done)
        out.append(Piece(q.chart, q.xyz, uv_new, q.faces))
        a = st["area"]
        before += a * st["energy_before"]
        after += a * st["energy_after"]
        area += a
        stats["relax_iterations_max"] = max([stats["relax_iterations_max"], *st["iterations"]])
        stats["relax_stopped_by_crossing"] += st["stopped_by_crossing"]
    stats["relax_energy_before"] = before / area if area > 0 else float("nan")
    stats["relax_energy_after"] = after / area if area > 0 else float("nan")
    return out, stats


def cut_island(pieces: list[Piece], k: int, island: int, long_axis: bool = True,
               fraction: float | None = None) -> list[Piece]:
    """``pieces`` with island ``island`` of piece ``k`` cut in two by a straight UV line.

    The line runs across the principal axis of the island's UV area (``long_axis``) or along
    it, through the island's UV centroid (``fraction`` None) or at the position that leaves
    ``fraction`` of the island's UV area (by face centre) on the low side of the axis: 0.25
    cuts about a quarter off one end, 0.75 off the other. The cut is an iso-line cut like
    every other border; the parts become separate pieces (same chart).
    """
    if fraction is not None and not 0.0 < fraction < 1.0:
        raise ValueError(f"cut_island: fraction must lie in (0, 1), got {fraction}")
    p = pieces[k]
    sel = uv_islands(p.faces, p.uv) == island
    w = p.uv_area()[sel]
    centre = p.uv[p.faces[sel]].mean(1)
    c = (centre * w[:, None]).sum(0) / w.sum()
    d = centre - c
    axis = np.linalg.eigh((d * w[:, None]).T @ d)[1][:, -1 if long_axis else 0]
    at = 0.0
    if fraction is not None:
        proj = d @ axis
        order = np.argsort(proj, kind="stable")
        cum = np.cumsum(w[order])
        at = proj[order][min(int(np.searchsorted(cum, fraction * cum[-1])), len(order) - 1)]
    field = (p.uv - c) @ axis - at
    inside = Piece(p.chart, p.xyz, p.uv, p.faces[sel])
    out = [q for j, q in enumerate(pieces) if j != k]
    if (~sel).any():
        out.append(Piece(p.chart, p.xyz, p.uv, p.faces[~sel]))
    return out + _halves(inside, field)


def _halves(p: Piece, field: np.ndarray, passes: int = 4) -> list[Piece]:
    """``p`` cut at ``field = 0`` into exactly two islands where possible.

    A straight line across a non-convex island can leave several pieces on one side: every
    piece but the largest on each side goes over to the other side (its vertices' field
    changes sign, and the cut is redone), so the cut adds one island, not several.
    """
    attrs = np.column_stack([p.xyz, p.uv])
    field = field.copy()
    for _ in range(passes):
        halves, changed = [], False
        for sign in (1.0, -1.0):
            c = clip_mesh(attrs, p.faces, sign * field, plane=UV_COLUMNS)
            half = Piece(p.chart, c.attrs[:, :3], c.attrs[:, 3:5], c.faces)
            halves.append(half)
            if len(half.faces) == 0:
                continue
            isl = uv_islands(half.faces, half.uv)
            if isl.max() == 0:
                continue
            keep = int(np.argmax(np.bincount(isl, weights=half.uv_area())))
            verts = c.source_vertex[np.unique(half.faces[isl != keep])]
            verts = verts[verts >= 0]
            if len(verts):
                field[verts] = -sign * np.maximum(np.abs(field[verts]), 1e-9)
                changed = True
        if not changed:
            break
    return [h for h in halves if len(h.faces)]


#: the largest islands (by UV area) tried for a cut, across their principal axis (halving
#: their long side; along it was never the best on the bunny, spot, bob and eight fits).
#: Three, not two: on the eight fit only the third largest cut reached 0.6 (coarse 0.61;
#: the two largest lost, 0.48 and 0.52); each more costs one more coarse search.
CUT_ISLANDS, CUT_AXES = 3, (True,)
#: the wider second round (see ``AtlasConfig.target_utilization``): off-centre cuts, a quarter
#: of the area from either end, across and along the principal axis of the two largest
#: islands, packed with xatlas's default options only. On 18 such cuts of each of seven fits
#: the best off-centre cut was of one of the two largest islands and packed best with the
#: default options (t-shirt: 0.626 with them, 0.505 without); it lifted a face fit from 0.54
#: to 0.61 and a t-shirt fit from 0.57 to 0.63 (coarse), where every centroid cut stayed below 0.6.
OFF_CENTRE_ISLANDS, OFF_CENTRE_AXES, OFF_CENTRE_FRACTIONS = 2, (True, False), (0.25, 0.75)


def _off_centre_plans(layouts: list, cfg: AtlasConfig, workers: int | None = None) -> list:
    """Coarse plans of the off-centre cut layouts (None where not searched).

    Their first guesses (one xatlas call each) rank them; a layout whose guess is far below
    the target (``PRUNE_MARGIN``) is not searched, and the others are searched best guess
    first, ``workers`` at a time, until one reaches the target. The guess ranks layouts only
    roughly: on a bunny fit the first two searches reached 0.614 and 0.598, and the best of
    all eight (0.629) had only the sixth best guess; searching all eight took 9 s instead of 2.
    """
    opts = PACK_CANDIDATES[0]
    workers = workers or default_workers()
    guess = estimate_layouts(layouts, resolution=cfg.resolution, padding=cfg.padding, options=opts, workers=workers)
    order = sorted((i for i, g in enumerate(guess) if g is not None and g[0] >= cfg.target_utilization - PRUNE_MARGIN),
                   key=lambda i: (-guess[i][0], i))
    plans = [None] * len(layouts)
    for at in range(0, len(order), workers):
        batch = order[at:at + workers]
        found = plan_layouts([layouts[i] for i in batch], resolution=cfg.resolution, padding=cfg.padding,
                             candidates=(opts,), starts=[guess[i][1] for i in batch], workers=workers)
        for i, p in zip(batch, found):
            plans[i] = p
        if any(p is not None and p.utilization >= cfg.target_utilization for p in plans):
            break
    return plans


def _layout(pieces: list[Piece], cfg: AtlasConfig):
    """(merged pieces as :func:`_merge` gives them, coarse packing plan, stats): the islands
    as they are, or with one cut.

    xatlas's packer is a heuristic: which cut helps is not predictable from the shapes
    (on a bunny fit, cutting the largest island lost 0.09 of utilisation and cutting the
    second largest gained 0.13; neither the islands' bounding-box nor convex-hull fill ranked
    the cuts), so the cuts are packed: first the centroid cuts of the ``CUT_ISLANDS`` largest
    islands, then, if no layout reached ``cfg.target_utilization``, the off-centre cuts
    (``OFF_CENTRE_*``). Each is packed at the coarse resolution and the best is kept if it
    gains ``split_gain`` over the uncut islands.
    """
    cache: dict = {}  # the layouts share all pieces but the cut one

    def arrays(ps):
        _, uv, faces, _, island = _merge(ps, cache)
        return uv, faces, island

    stats = {"split_islands": 0}
    ranked = []  # (UV area, piece, island)
    if cfg.max_islands > 0 and island_count(pieces, cache) + 1 <= cfg.max_islands:
        for k, p in enumerate(pieces):
            if len(p.faces):
                area = np.bincount(_prepared(p, cache)[1], weights=p.uv_area())  # same faces, same ids
                ranked += [(float(a), k, i) for i, a in enumerate(area)]
        ranked.sort(key=lambda t: (-t[0], t[1], t[2]))

    def cuts(n_islands, axes, fractions):  # [(layout, description)]
        out = []
        for rank, (_, k, i) in enumerate(ranked[:n_islands]):
            for long_axis in axes:
                for fraction in fractions:
                    cut = cut_island(pieces, k, i, long_axis, fraction)
                    if island_count(cut, cache) <= cfg.max_islands:
                        out.append((cut, {"island_rank": rank, "across_long_axis": long_axis,
                                          "area_fraction": 0.5 if fraction is None else fraction,
                                          "through_centroid": fraction is None}))
        return out

    # each layout gets a fresh search with both option sets (xatlas's validity is not
    # monotone in the scale, so a search from the uncut layout's scale stops at the first
    # failure: 0.62 where a fresh guess found 0.69 on a bunny fit; one option set alone lost
    # the gain on a sphere's two caps), all in parallel
    layouts = [(pieces, None)] + cuts(CUT_ISLANDS, CUT_AXES, (None,))
    if len(layouts) == 1:
        return _merge(pieces, cache), plan_layouts([arrays(pieces)], resolution=cfg.resolution,
                                                   padding=cfg.padding)[0], stats
    # xatlas's default options for every layout, then the other option sets: for every layout
    # while none reached the target, else only for the uncut islands and the best cut (6
    # searches instead of 8). A cut that packs best without rotations is not rare: on the spot
    # fit one reached 0.62 that way against 0.52 with them, where the best default was 0.56
    plans = plan_layouts([arrays(ps) for ps, _ in layouts], resolution=cfg.resolution, padding=cfg.padding,
                         candidates=PACK_CANDIDATES[:1])
    top = max(range(1, len(plans)), key=lambda i: plans[i].utilization if plans[i] is not None else -1.0)
    reached = max(p.utilization if p is not None else -1.0 for p in plans) >= cfg.target_utilization > 0
    again = [0, top] if reached else list(range(len(layouts)))
    more = plan_layouts([arrays(layouts[i][0]) for i in again], resolution=cfg.resolution, padding=cfg.padding,
                        candidates=PACK_CANDIDATES[1:])
    for i, p in zip(again, more):
        if p is not None and (plans[i] is None or p.utilization > plans[i].utilization):
            p.attempts += plans[i].attempts if plans[i] is not None else 0
            plans[i] = p
        elif p is not None:
            plans[i].attempts += p.attempts
    base = plans[0]
    if base is None:
        return _merge(pieces, cache), base, stats
    stats["utilization_coarse_uncut"] = base.utilization
    stats["utilization_coarse_cuts"] = [p.utilization for p in plans[1:] if p is not None]
    if max(p.utilization for p in plans if p is not None) < cfg.target_utilization:
        wider = cuts(OFF_CENTRE_ISLANDS, OFF_CENTRE_AXES, OFF_CENTRE_FRACTIONS)
        if wider:
            more = _off_centre_plans([arrays(ps) for ps, _ in wider], cfg)
            stats["utilization_coarse_off_centre_cuts"] = [None if p is None else p.utilization for p in more]
            layouts, plans = layouts + wider, plans + more
    best = max(range(1, len(plans)), key=lambda i: plans[i].utilization if plans[i] is not None else -1.0)
    if plans[best] is not None and plans[best].utilization >= base.utilization + cfg.split_gain:
        stats["split_islands"] = 1
        stats["utilization_coarse_cut"] = plans[best].utilization
        stats["cut"] = layouts[best][1]
        return _merge(layouts[best][0], cache), plans[best], stats
    return _merge(pieces, cache), base, stats


def _welded(p: Piece) -> Piece:
    """One vertex per distinct (UV, 3D) point: clipping can leave exact duplicates, which
    :func:`uv_islands` treats as one point but xatlas (by index) as a cut, splitting the island."""
    first, inverse = unique_rows(np.column_stack([p.uv, p.xyz]))
    if len(first) == len(p.uv):
        return p
    return Piece(p.chart, p.xyz[first], p.uv[first], inverse.reshape(-1)[p.faces])


def _unmirrored(p: Piece) -> Piece:
    """``p`` with every island whose UVs run clockwise, seen from its faces' front (the side
    their winding faces), reflected (u -> -u): a texture then reads the right way round from
    outside. Flattening and packing never reflect (SLIM is flip-free, the packer only
    rotates), so this holds in the packed atlas."""
    q, isl = _prepared(p)
    t = q.uv[q.faces]
    signed = 0.5 * ((t[:, 1, 0] - t[:, 0, 0]) * (t[:, 2, 1] - t[:, 0, 1])
                    - (t[:, 1, 1] - t[:, 0, 1]) * (t[:, 2, 0] - t[:, 0, 0]))
    mirrored = np.bincount(isl, weights=signed) < 0
    if not mirrored.any():
        return p
    flip = np.zeros(len(q.uv), bool)
    flip[q.faces[mirrored[isl]].ravel()] = True  # split vertices: each belongs to one island
    uv = q.uv.copy()
    uv[flip, 0] *= -1.0
    return Piece(q.chart, q.xyz, uv, q.faces)


def island_count(pieces: list[Piece], cache: dict | None = None) -> int:
    """Islands the pieces make (as :func:`_merge` numbers them); ``cache`` as for :func:`_prepared`."""
    return sum(int(_prepared(p, cache)[1].max()) + 1 for p in pieces if len(p.faces))


def _oriented(pieces: list[Piece], reference: Reference, cfg: AtlasConfig,
              cache: dict | None = None) -> tuple[list[Piece], dict]:
    """:func:`orient_pieces` with fragment islands (``cfg.orient_fragment_island``) only where
    they keep the atlas within ``cfg.max_islands``, or where it exceeds that without them too.

    A fragment island trades a little folded area for an island: on a many-part shape (already
    over the island budget) that is the better trade, on a single-part one the few islands are
    the point (a torus demo fit: 6 islands without them, 13 with).
    """
    total = sum(float(p.area().sum()) for p in pieces)
    min_area = cfg.trim.min_island_fraction * total
    if cfg.orient_fragment_island <= 0:
        return orient_pieces(pieces, reference, min_area)
    out, stats = orient_pieces(pieces, reference, min_area, min_fragment_island=cfg.orient_fragment_island * total)
    stats["orient_fragment_islands"] = True
    # orientation splits and reverses islands but never merges them: when the pieces already
    # have more islands than the budget, orienting again without fragment islands cannot
    # get within it (the 13-part truck: 7.5 s saved)
    if 0 < cfg.max_islands < island_count(out, cache) and island_count(pieces, cache) <= cfg.max_islands:
        plain, plain_stats = orient_pieces(pieces, reference, min_area)
        if island_count(plain, cache) <= cfg.max_islands:
            return plain, {**plain_stats, "orient_fragment_islands": False}
    return out, stats


def coverage_stats(charts: ChartGrids, xyz: np.ndarray, faces: np.ndarray, reference: np.ndarray | None,
                   seed: int) -> dict:
    """F-score of the run's kept mesh and of the trimmed atlas ``(xyz, faces)`` against ``reference`` (unit frame)."""
    trimmed_pts, _ = sample_surface(xyz, faces, POINTS, seed)
    kept_pts = ref = None
    if charts.kept_vertices is not None and len(charts.kept_faces):
        kept = charts.normalization.apply(charts.kept_vertices)
        kept_pts, _ = sample_surface(kept, charts.kept_faces, POINTS, seed + 1)
        if reference is None:  # an independent sample, so "before" is not compared with itself
            ref, _ = sample_surface(kept, charts.kept_faces, POINTS, seed + 2)
    if reference is not None:
        ref = reference
    out = {"coverage_reference": "input" if reference is not None else "kept_mesh"}
    if ref is None:
        return out
    after = chamfer_fscore(trimmed_pts, ref)
    out.update(fscore_trimmed=after.fscore, chamfer_trimmed=after.chamfer)
    if kept_pts is not None:
        before = chamfer_fscore(kept_pts, ref)
        out.update(fscore_kept=before.fscore, chamfer_kept=before.chamfer, fscore_drop=before.fscore - after.fscore)
    return out


def build_atlas(charts: ChartGrids, config: AtlasConfig | None = None, reference_points: np.ndarray | None = None,
                reference: Reference | None = None) -> Atlas:
    """Trim, orient, cut, split and pack ``charts``.

    ``reference_points`` (unit frame) for the coverage check; ``reference`` (the input mesh
    with normals, unit frame) to orient every island outward.
    """
    cfg = config or AtlasConfig()
    t0 = time.perf_counter()
    trimmed = trim_charts(charts, cfg.trim)
    t_trim = time.perf_counter()
    pieces, orient_stats = trimmed.pieces, {}
    prepared: dict = {}  # _prepared pieces, shared by the island counts and the relaxation
    if reference is not None and cfg.orient:
        pieces, orient_stats = _oriented(pieces, reference, cfg, prepared)
    t1 = time.perf_counter()
    relaxed, relax_stats = relax_pieces(pieces, cfg.relax, prepared)
    unmirrored = [_unmirrored(p) for p in pieces]
    relaxed = unmirrored if relaxed is pieces else [_unmirrored(p) for p in relaxed]
    pieces = unmirrored
    t_relax = time.perf_counter()
    merged, plan, split_stats = _layout(relaxed, cfg)
    if relaxed is not pieces and 0 < cfg.target_utilization:
        # relaxed islands are rounder than the charts' near-square domains and can pack looser:
        # keep the charts' own UVs only when the relaxed layouts miss the utilisation target
        # and the unrelaxed reach it (coarse packing)
        got = plan.utilization if plan is not None else -1.0
        relax_stats["relax_kept"] = True
        if got < cfg.target_utilization:
            raw = _layout(pieces, cfg)
            relax_stats["utilization_coarse_relaxed"] = got
            relax_stats["utilization_coarse_unrelaxed"] = raw[1].utilization if raw[1] is not None else None
            if raw[1] is not None and raw[1].utilization >= cfg.target_utilization:
                merged, plan, split_stats = raw
                relax_stats["relax_kept"] = False
    (xyz, uv_local, faces, chart, island) = merged
    packing = pack_islands(uv_local, faces, island, resolution=cfg.resolution, padding=cfg.padding, plan=plan)
    t2 = time.perf_counter()
    mesh = make_uv_mesh(charts.normalization.invert(xyz), faces, packing.uv, name="atlas")
    stats = {
        "charts": int(charts.n_charts),
        "charts_used": int(len(np.unique(chart))),
        "islands": int(island.max()) + 1,
        "faces": int(len(faces)),
        **trimmed.stats,
        **orient_stats,
        **relax_stats,
        **split_stats,
        **coverage_stats(charts, xyz, faces, reference_points, cfg.seed),
        "utilization": packing.utilization,
        "packer": packing.packer,
        "uv_scale": packing.scale,
        "texels_per_chart_unit": packing.texels_per_unit,
        "resolution": packing.resolution,
        "padding": packing.padding,
        "timings": {"trim": t_trim - t0, "orient": t1 - t_trim, "relax": t_relax - t1, "pack": t2 - t_relax},
    }
    return Atlas(mesh, chart, island, charts.normalization, packing, stats)
