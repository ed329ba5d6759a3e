"""Pack UV islands into [0,1]^2 with xatlas's packer, at one texel density for all islands.

xatlas (``Atlas.add_uv_mesh`` + ``generate``) places the islands; each island gets its
own material id (``face_materials``) so islands that share UV positions (charts are all
parametrised over [-1,1]^2) are never merged. xatlas does not promise to keep an island's
shape: it rotates islands by any angle (``rotate_charts_to_axis``), stretches them by up to
a texel to align their extents to whole texels, and silently *shrinks* an island that is
larger than the atlas. So we never use xatlas's UVs directly: per island we fit the
similarity ``x -> s R x + t`` (weighted Procrustes, :func:`similarity_fit`) from its input
UVs to xatlas's, keep only the rotation ``R``, and re-place the island at the one shared
scale ``texels_per_unit`` around xatlas's centroid. Every island thus keeps its exact shape
and all share one scale.

A placement is accepted only when it is *valid*: every island lies within
``MAX_FIT_RESIDUAL`` texels of where xatlas put it (so xatlas's gutters still hold), all
UVs are inside the square, and no texel centre is covered by two islands (rasterised).
An island that xatlas shrank, split or re-parametrised fails the first test, and the scale
is lowered. Search: xatlas packs once into an unbounded atlas at a guessed scale, the scale
is set so its larger side matches ``resolution``, then it is lowered by ``SHRINK`` until a
placement is valid and bisected between the largest valid and smallest invalid scale.
If xatlas never gives a valid placement (e.g. an island it always splits), a shelf packer
of padded bounding boxes (:func:`shelf_pack`) places the islands instead: any input packs.

Speed: the search runs at ``resolution / COARSE`` with the gutter scaled alike
(:func:`plan_packing`, every ``PACK_CANDIDATES``), and the best placement scaled up is the
packing once it passes the overlap test at full resolution; only if it does not, a search
at full resolution follows.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from mnacore.triangles import triangle_areas

from .mirrors import mirrored_islands, turn_back
from .outlines import island_outlines
from .parallel import parallel_map
from .raster import iter_hits
from .similarity import similarity_fit

#: largest allowed distance (texels) between xatlas's placement and the re-placed island.
MAX_FIT_RESIDUAL = 2.0
#: faces below this fraction of the median UV area carry no weight in the fit (xatlas drops them).
SOLID_FACE_REL = 1e-2
#: scale step while no placement is valid, and relative width at which bisection stops.
SHRINK, BISECT_TOL = 0.95, 0.005
#: xatlas calls per placement to get every island the right way round (see :func:`_attempt`)
MIRROR_TRIES = 5
#: scale steps (FINE_SHRINK each) tried for a packing with no island mirrored before the
#: search without xatlas's 90-degree turns
UNMIRROR_STEPS = 8
#: xatlas ``PackOptions`` overrides tried in turn (highest utilisation kept). Its 90-degree
#: chart rotations sometimes pack a few large islands worse: on a 3-chart bunny fit at 2048,
#: 0.51 with them and 0.54 without; ``bruteForce`` gained < 0.001 at 12x the time.
PACK_CANDIDATES = ({}, {"rotate_charts": False})
#: candidates are compared at ``resolution / COARSE``; the full-resolution search then starts
#: from the coarse scale and steps by ``FINE_SHRINK``
COARSE, FINE_SHRINK = 4, 0.985
#: UVs handed to xatlas are scaled so the median face is UV_UNIT on a side (see _xatlas_pack)
UV_UNIT = 100.0
#: the coarse search stops at 1 %: the plan only has to rank layouts, and each step is an xatlas call
COARSE_BISECT_TOL = 0.01
#: a search may give up after its first guess (an unbounded pack) when that implies a utilisation
#: this far below what it must reach: on 16 cut layouts of a face and a t-shirt fit the bounded
#: search ended between 0.01 below and 0.065 above the first guess
PRUNE_MARGIN = 0.07


@dataclass
class Packing:
    """Result of :func:`pack_islands`.

    Attributes:
        uv: (V, 2) packed UVs in [0,1]^2 (same vertex order as the input).
        scale: packed UV per input UV unit (one value for every island).
        texels_per_unit: ``scale * resolution``.
        utilization: fraction of [0,1]^2 covered (texel centres at ``resolution``).
        overlap_texels: texels covered by two different islands (always 0).
        seconds: packing time.
        attempts: xatlas calls.
        packer: ``"xatlas"`` or ``"shelf"`` (the fallback).
    """

    uv: np.ndarray
    scale: float
    texels_per_unit: float
    resolution: int
    padding: int
    utilization: float
    overlap_texels: int
    seconds: float
    attempts: int
    packer: str = "xatlas"


def _xatlas_pack(uv, faces, island, resolution, padding, tpu, options: dict | None = None):
    import xatlas

    # xatlas drops faces whose UV area is below a fixed float epsilon (~1e-7) and then splits
    # an island where only such slivers held it together: hand it UVs in units where the
    # median face is UV_UNIT on a side (the placement in texels does not change). At a unit
    # of 1 an older genus-2 fit's 6 islands came back as 7 charts and a torus fit's 8 islands
    # as 44 (at 10: 11); at 100 both are whole. Moving the islands apart in UV as well kept
    # them whole too but changed xatlas's layouts (a bunny fit packed 0.64 -> 0.56).
    area = triangle_areas(uv, faces)
    median = float(np.median(area[area > 0])) if (area > 0).any() else 1.0
    unit = UV_UNIT / np.sqrt(median)
    atlas = xatlas.Atlas()
    atlas.add_uv_mesh((uv * unit).astype(np.float32), faces.astype(np.uint32), island.astype(np.uint32).reshape(-1, 1))
    po = xatlas.PackOptions()
    po.resolution = int(resolution)
    po.padding = int(padding)
    po.texels_per_unit = float(tpu / unit)
    po.bilinear = True
    po.bruteForce = False
    for k, v in (options or {}).items():
        setattr(po, k, v)
    atlas.generate(pack_options=po)
    return atlas


class _Islands:
    """Per-island vertex lists and fit weights of a split-vertex UV mesh (computed once).

    xatlas is handed each island's *outline*, not its faces (:attr:`xatlas_mesh`): the
    packer only sees the region an island covers, and an ear-clipped outline covers the
    same region with a tenth of the faces or fewer (a relaxed bunny fit: 76k faces -> 4.7k,
    each xatlas call at 512^2 0.23 s -> 0.1 s, same layouts). The outline's vertices are
    the island's border vertices, so the fit in :func:`_place` uses them and places the
    whole island with the same motion.
    """

    def __init__(self, uv, faces, island, outlines: bool = True):
        self.uv, self.faces, self.island = uv, faces, island
        self.n = int(island.max()) + 1
        vert_island = np.full(len(uv), -1)
        vert_island[faces.ravel()] = np.repeat(island, 3)
        area = triangle_areas(uv, faces)
        self.area = float(area.sum())
        used = np.flatnonzero(vert_island >= 0)
        order = used[np.argsort(vert_island[used], kind="stable")]
        self.verts = np.split(order, np.cumsum(np.bincount(vert_island[used], minlength=self.n))[:-1])
        self._vert_island, self._outlines = vert_island, outlines

    @cached_property
    def _xatlas(self):
        x_faces = island_outlines(self.uv, self.faces, self.island) if self._outlines else self.faces
        # xatlas gets the outline faces over their own vertices (src: theirs -> ours)
        src, inverse = np.unique(x_faces, return_inverse=True)
        # vertex weight: area of its solid faces, so slivers xatlas drops never steer the fit
        # ("solid" against the island's own median: outlines and whole islands mix)
        area = triangle_areas(self.uv, x_faces)
        x_island = self._vert_island[x_faces[:, 0]]
        order = np.argsort(x_island, kind="stable")
        cuts = np.cumsum(np.bincount(x_island, minlength=self.n))[:-1]
        median = np.zeros(self.n)
        for i, a in enumerate(np.split(area[order], cuts)):
            median[i] = np.median(a) if len(a) else 0.0
        solid = area > SOLID_FACE_REL * median[x_island]
        weight = np.bincount(x_faces[solid].ravel(), np.repeat(area[solid], 3), len(self.uv))
        return (self.uv[src], inverse.reshape(-1, 3), x_island), src, weight

    @property
    def xatlas_mesh(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(uv, faces, island) handed to xatlas: the islands' outlines."""
        return self._xatlas[0]

    def xatlas_mesh_mirrored(self, flip: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:attr:`xatlas_mesh` with the islands where ``flip`` (n,) is set reflected (u -> -u)."""
        uv, faces, x_island = self.xatlas_mesh
        if not flip.any():
            return uv, faces, x_island
        uv = uv.copy()
        uv[flip[self._vert_island[self.src]], 0] *= -1.0
        return uv, faces, x_island

    @property
    def src(self) -> np.ndarray:
        """Our vertex of each vertex of :attr:`xatlas_mesh`."""
        return self._xatlas[1]

    @property
    def weight(self) -> np.ndarray:
        """(V,) fit weight per vertex (0 off the outlines)."""
        return self._xatlas[2]


def _place(isl: _Islands, atlas, tpu: float) -> tuple[np.ndarray, float, list[int]]:
    """Texel positions (V, 2) re-placed rigidly at ``tpu``, the largest deviation from xatlas
    (texels), and the islands placed mirrored (a reflection of their UVs fits xatlas's)."""
    vmap, _, out_uv = atlas[0]
    dst = np.zeros_like(isl.uv)
    seen = np.zeros(len(isl.uv), bool)
    # xatlas normalises by w, h; its vertices are the outlines' (isl.src -> ours)
    dst[isl.src[vmap]] = out_uv.astype(np.float64) * np.array([atlas.width, atlas.height])
    seen[isl.src[vmap]] = True
    placed = np.zeros_like(isl.uv)
    worst, turned = 0.0, []
    for k, verts in enumerate(isl.verts):
        w = isl.weight[verts] * seen[verts]
        if w.sum() <= 0:  # zero UV area: covers no texel, xatlas ignores it; keep it inside the square
            placed[verts] = _inside_square(isl.uv[verts] * tpu, dst[verts][seen[verts]], atlas)
            continue
        fit = similarity_fit(isl.uv[verts], dst[verts], w)
        mu_s, mu_d = _wmean(isl.uv[verts], w), _wmean(dst[verts], w)
        placed[verts] = tpu * (isl.uv[verts] - mu_s) @ fit.rotation.T + mu_d
        on = w > 0
        worst = max(worst, float(np.abs(placed[verts][on] - dst[verts][on]).max()))
        if np.linalg.det(fit.rotation) < 0:
            turned.append(k)
    return placed, worst, turned


def _inside_square(px: np.ndarray, near: np.ndarray, atlas) -> np.ndarray:
    """``px`` translated to centre on ``near``'s centroid (or the atlas centre), then into the atlas."""
    size = np.array([atlas.width, atlas.height], np.float64)
    centre = near.mean(0) if len(near) else size / 2
    px = px - 0.5 * (px.min(0) + px.max(0)) + centre
    px -= np.minimum(px.min(0), 0)
    return px - np.maximum(px.max(0) - size, 0)


def _wmean(p, w):
    return (w @ p) / w.sum() if w.sum() > 0 else p.mean(0)


def _inside(isl: _Islands, px: np.ndarray, resolution: int) -> bool:
    used = np.concatenate(isl.verts)
    return bool(px[used].min() >= 0 and px[used].max() <= resolution)


def _attempt(isl: _Islands, resolution, padding, tpu, options, unmirror: bool = False):
    """Texel positions of a valid xatlas placement at ``tpu`` (with ``unmirror``: with no
    island mirrored), or None.

    xatlas's 90-degree chart "rotation" is a transpose: the island it turns comes back
    mirrored. Such islands are handed to xatlas mirrored on the next try, so that the
    transpose turns them the right way round (a transpose of a reflection is a rotation);
    an island xatlas then leaves alone is handed over unmirrored again. After
    ``MIRROR_TRIES`` xatlas calls the islands still mirrored are turned back inside the box
    xatlas gave them (:func:`texture.mirrors.reflect_in_box`), if half the gutter remains.
    """
    flip = np.zeros(isl.n, bool)
    for _ in range(MIRROR_TRIES if unmirror else 1):
        atlas = _xatlas_pack(*isl.xatlas_mesh_mirrored(flip), resolution, padding, tpu, options)
        if atlas.atlas_count != 1 or atlas.width > resolution or atlas.height > resolution:
            return None
        px, residual, mirrored = _place(isl, atlas, tpu)
        if residual > MAX_FIT_RESIDUAL or not _inside(isl, px, resolution):
            return None
        if not mirrored or not unmirror:
            break
        flip[mirrored] ^= True
    else:
        px = turn_back(isl, px, mirrored, resolution, padding)
        if px is None:
            return None
    # xatlas keeps charts `padding` texels apart and each island moved <= residual: if two
    # moves cannot close the gutter, skip the (slow) rasterised check; pack_islands runs it
    # on the packing it returns anyway
    if 2 * residual + 1 >= padding and verify_packing(px / resolution, isl.faces, isl.island, resolution)[0]:
        return None
    return px


def _first_guess(isl: _Islands, resolution, padding, options) -> float:
    """Texels per unit at which xatlas's pack into an unbounded atlas just fits ``resolution``."""
    tpu = resolution * np.sqrt(0.6 / isl.area)
    free = _xatlas_pack(*isl.xatlas_mesh, 0, padding, tpu, options)
    return tpu * (resolution - 1) / max(free.width, free.height, 1)


def _search(isl: _Islands, resolution, padding, options, max_attempts, tpu: float | None = None,
            shrink: float = SHRINK, tol: float = BISECT_TOL, min_estimate: float = 0.0):
    """(tpu, texel positions, xatlas calls) of the largest valid xatlas placement found, or None.

    Without a starting ``tpu`` the first guess comes from a pack into an unbounded atlas;
    if the utilisation that guess implies is below ``min_estimate``, the search stops there
    (None): the bounded search rarely ends far from it (see ``PRUNE_MARGIN``).
    """
    attempts = 0
    if tpu is None:
        tpu = _first_guess(isl, resolution, padding, options)
        attempts = 1
        if isl.area * tpu**2 / resolution**2 < min_estimate:
            return None
    good = bad = None  # (tpu, texel positions) of the largest valid / tpu of the smallest invalid
    while attempts < max_attempts:
        if good is not None and bad is not None and bad / good[0] - 1 < tol:
            break
        attempts += 1
        px = _attempt(isl, resolution, padding, tpu, options)
        if px is not None:
            good = (tpu, px)
        else:
            bad = tpu
        if good is None:
            tpu *= shrink
        elif bad is None:
            tpu /= shrink  # the square can pack tighter than the first guess suggested
        else:
            tpu = np.sqrt(good[0] * bad)
    return None if good is None else (*good, attempts)


@dataclass
class Plan:
    """A coarse packing: which xatlas options, at what scale, for what utilisation."""

    utilization: float
    texels_per_unit: float  # at the full resolution
    options: dict
    attempts: int
    uv: np.ndarray | None = None  # (V, 2) the coarse placement in [0,1]^2 (same vertex order)


def _coarse(resolution: int, padding: int) -> tuple[int, int]:
    factor = COARSE if resolution >= COARSE * 128 else 1
    return resolution // factor, max(1, int(round(padding / factor)))


def _coarse_search(job, _shared=None):
    """One candidate of one layout at the coarse resolution: (util, tpu, placement, calls) or None."""
    uv, faces, island, resolution, padding, opts, max_attempts, min_estimate, start = job
    res, pad = _coarse(resolution, padding)
    isl = _Islands(np.asarray(uv, np.float64), np.asarray(faces, np.int64), np.asarray(island, np.int64))
    if isl.area <= 0:
        return None
    found = _search(isl, res, pad, opts, max_attempts, start, tol=COARSE_BISECT_TOL, min_estimate=min_estimate)
    if found is None:
        return None
    tpu, px, n = found
    util = verify_packing(px / res, isl.faces, isl.island, res)[1]
    return util, tpu * resolution / res, px / res, n + (start is not None)


def _estimate_job(job, _shared=None):
    uv, faces, island, resolution, padding, opts = job
    res, pad = _coarse(resolution, padding)
    isl = _Islands(np.asarray(uv, np.float64), np.asarray(faces, np.int64), np.asarray(island, np.int64))
    if isl.area <= 0:
        return None
    tpu = _first_guess(isl, res, pad, opts)
    return isl.area * tpu**2 / res**2, tpu


def estimate_layouts(layouts: list[tuple[np.ndarray, np.ndarray, np.ndarray]], *, resolution: int = 2048,
                     padding: int = 8, options: dict | None = None,
                     workers: int | None = None) -> list[tuple[float, float] | None]:
    """Per layout ``(uv, faces, island)``, one xatlas call: (the utilisation its first guess
    implies, the guess itself in coarse texels per unit: a ``start`` for :func:`plan_layouts`),
    or None. The bounded search ends near it (see ``PRUNE_MARGIN``): a rough way to rank layouts."""
    jobs = [(uv, faces, island, resolution, padding, dict(options or {})) for uv, faces, island in layouts]
    return parallel_map(_estimate_job, jobs, workers)


def plan_layouts(layouts: list[tuple[np.ndarray, np.ndarray, np.ndarray]], *, resolution: int = 2048,
                 padding: int = 8, max_attempts: int = 16, workers: int | None = None,
                 candidates: tuple[dict, ...] = PACK_CANDIDATES, min_estimate: float = 0.0,
                 starts: list[float | None] | None = None) -> list[Plan | None]:
    """:func:`plan_packing` of several island layouts ``(uv, faces, island)``, searches in parallel.

    Every layout x ``candidates`` (xatlas option sets) search is independent and xatlas
    holds the GIL, so they run in up to ``workers`` processes (default: the CPU count, at
    most 4); the result is the same as one after the other. A search whose first guess
    implies a utilisation below ``min_estimate`` gives up after that one xatlas call.
    ``starts`` (per layout) are first guesses from :func:`estimate_layouts` with the same
    options as every candidate: the searches start there instead of packing once more.
    """
    starts = starts or [None] * len(layouts)
    jobs = [(uv, faces, island, resolution, padding, opts, max_attempts, min_estimate, start)
            for (uv, faces, island), start in zip(layouts, starts) for opts in candidates]
    results = parallel_map(_coarse_search, jobs, workers)
    plans = []
    n = len(candidates)
    for li in range(len(layouts)):
        best, calls = None, 0
        for opts, r in zip(candidates, results[li * n:(li + 1) * n]):
            if r is None:
                continue
            util, tpu, placement, k = r
            calls += k
            if best is None or util > best.utilization:
                best = Plan(util, tpu, dict(opts), 0, placement)
        if best is not None:
            best.attempts = calls
        plans.append(best)
    return plans


def plan_packing(uv: np.ndarray, faces: np.ndarray, island: np.ndarray, *, resolution: int = 2048,
                 padding: int = 8, max_attempts: int = 16) -> Plan | None:
    """Search every ``PACK_CANDIDATES`` at ``resolution / COARSE`` (gutter scaled alike); the best.

    xatlas's time is mostly rasterising islands at the atlas resolution, so comparing
    candidates (or island layouts) at a quarter of it costs about a third. None if xatlas
    never gave a valid placement.
    """
    return plan_layouts([(uv, faces, island)], resolution=resolution, padding=padding,
                        max_attempts=max_attempts)[0]


def pack_islands(uv: np.ndarray, faces: np.ndarray, island: np.ndarray, *, resolution: int = 2048,
                 padding: int = 8, max_attempts: int = 16, options: dict | None = None,
                 plan: Plan | None = None) -> Packing:
    """Pack islands ``island (F,)`` of the UV mesh ``(uv (V,2), faces (F,3))``; see module docstring.

    Every vertex must belong to faces of a single island (true for split-vertex meshes).
    ``options`` overrides xatlas ``PackOptions`` fields (e.g. ``{"bruteForce": True}``) and
    is searched at full resolution. By default the candidates are compared by a coarse
    :func:`plan_packing` (or the given ``plan``) and only the best one is searched at full
    resolution, starting from the coarse scale. Never fails on valid arrays: folded,
    flipped, degenerate or oversized islands all pack.
    """
    t0 = time.perf_counter()
    isl = _Islands(np.asarray(uv, np.float64), np.asarray(faces, np.int64), np.asarray(island, np.int64))
    if isl.area <= 0:
        raise ValueError("pack_islands: all UV faces have zero area")
    best, attempts = None, 0  # (utilisation, tpu, texel positions, options)

    def search(opts, start=None, shrink=SHRINK):  # keeps the best valid placement found
        nonlocal best, attempts
        found = _search(isl, resolution, padding, opts, max_attempts, start, shrink)
        if found is None:
            return
        tpu, px, n = found
        attempts += n
        overlap, util = verify_packing(px / resolution, isl.faces, isl.island, resolution)
        if overlap == 0 and (best is None or util > best[0]):
            best = (util, tpu, px, opts)

    searches = [(options, None, SHRINK)] if options is not None else []
    if options is None:
        plan = plan or plan_packing(uv, faces, island, resolution=resolution, padding=padding,
                                    max_attempts=max_attempts)
        if plan is not None:
            attempts += plan.attempts
            # the coarse placement, scaled up, is the packing: its gutters scale with it, so
            # it only has to pass the overlap test at full resolution (a full-resolution
            # search from the coarse scale found less: xatlas's validity is not monotone)
            if plan.uv is not None and _inside(isl, plan.uv * resolution, resolution):
                overlap, util = verify_packing(plan.uv, isl.faces, isl.island, resolution)
                if overlap == 0:
                    best = (util, plan.texels_per_unit, plan.uv * resolution, plan.options)
            if best is None:
                searches = [(plan.options, plan.texels_per_unit, FINE_SHRINK)]
    for opts, start, shrink in searches:
        search(opts, start, shrink)
    if best is None and options is None:  # the coarse plan did not carry over: search every candidate
        for opts in PACK_CANDIDATES:
            search(opts)
    if best is not None and mirrored_islands(isl, best[2]):
        # the search lets xatlas's transposes mirror islands (cheap); the packing may not
        best = _without_mirrors(isl, resolution, padding, best, max_attempts)
    packer = "xatlas"
    if best is None:
        tpu, px = shelf_pack(isl, resolution, padding)
        overlap, util = verify_packing(px / resolution, isl.faces, isl.island, resolution)
        assert overlap == 0 and _inside(isl, px, resolution), "shelf packing is valid by construction"
        packer = "shelf"
    else:
        util, tpu, px, _ = best
    return Packing(px / resolution, tpu / resolution, tpu, resolution, padding, util, 0,
                   time.perf_counter() - t0, attempts, packer)


def _without_mirrors(isl: _Islands, resolution: int, padding: int, best: tuple, max_attempts: int) -> tuple | None:
    """The best packing's options again, islands kept the right way round (:func:`_attempt`
    with ``unmirror``), at its scale or a few ``FINE_SHRINK`` steps below; failing that, a
    search without xatlas's 90-degree turns (which never mirrors). None if neither packs.

    Like the plan, this runs at the coarse resolution and its placement is scaled up (its
    gutters scale with it): each xatlas call costs about a sixteenth of a full one.
    """
    _, tpu, _, opts = best
    res, pad = _coarse(resolution, padding)
    for step in range(UNMIRROR_STEPS):
        t = tpu * FINE_SHRINK ** step
        px = _attempt(isl, res, pad, t * res / resolution, opts, unmirror=True)
        if px is not None and _inside(isl, px * resolution / res, resolution):
            px = px * resolution / res
            overlap, util = verify_packing(px / resolution, isl.faces, isl.island, resolution)
            if overlap == 0:
                return util, t, px, opts
    plain = {**(opts or {}), "rotate_charts": False}
    found = _search(isl, resolution, padding, plain, max_attempts, None, SHRINK)
    if found is None:
        return None
    t, px, _ = found
    overlap, util = verify_packing(px / resolution, isl.faces, isl.island, resolution)
    return (util, t, px, plain) if overlap == 0 and not mirrored_islands(isl, px) else None


def shelf_pack(isl: _Islands, resolution: int, padding: int) -> tuple[float, np.ndarray]:
    """(tpu, texel positions): islands' bounding boxes, ``padding`` apart, on shelves.

    Boxes are sorted by height and laid left to right in rows; the scale is bisected to
    the largest that fits ``resolution^2``. Always succeeds (a small enough scale fits).
    """
    lo_uv = np.array([isl.uv[v].min(0) if len(v) else np.zeros(2) for v in isl.verts])
    ext = np.array([np.ptp(isl.uv[v], 0) if len(v) else np.zeros(2) for v in isl.verts])
    order = np.argsort(-ext[:, 1], kind="stable")

    def layout(tpu):
        size = ext * tpu + 2 * padding + 1  # one texel more: boxes never share a texel centre
        pos = np.zeros((isl.n, 2))
        x = y = row_h = 0.0
        for i in order:
            if x + size[i, 0] > resolution and x > 0:
                x, y, row_h = 0.0, y + row_h, 0.0
            pos[i] = x, y
            x += size[i, 0]
            row_h = max(row_h, size[i, 1])
        return pos, (y + row_h <= resolution and (size[:, 0] <= resolution).all())

    lo, hi = 0.0, (resolution - 2 * padding - 1) / max(ext.max(), 1e-12)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if layout(mid)[1] else (lo, mid)
    tpu = lo
    pos, _ = layout(tpu)
    px = np.zeros_like(isl.uv)
    for i, v in enumerate(isl.verts):
        px[v] = tpu * (isl.uv[v] - lo_uv[i]) + pos[i] + padding + 0.5
    return tpu, px


def verify_packing(uv: np.ndarray, faces: np.ndarray, island: np.ndarray, resolution: int) -> tuple[int, float]:
    """(texels hit by two different islands, covered fraction of [0,1]^2) at ``resolution``."""
    owner = np.full(resolution * resolution, -1, np.int64)
    clash = np.zeros(resolution * resolution, bool)
    for h in iter_hits(uv[faces], resolution, resolution, strict=True):
        idx = h.row * resolution + h.col
        isl = island[h.face]
        prev = owner[idx]
        clash[idx[(prev >= 0) & (prev != isl)]] = True
        owner[idx] = isl
        # two hits of the same texel inside one chunk: compare within the chunk too
        order = np.lexsort((isl, idx))
        same_texel = idx[order][1:] == idx[order][:-1]
        diff_isl = isl[order][1:] != isl[order][:-1]
        clash[idx[order][1:][same_texel & diff_isl]] = True
    return int(clash.sum()), float((owner >= 0).mean())
