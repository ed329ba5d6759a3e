"""The scale search: the largest texel density at which xatlas gives a valid placement.

xatlas packs once into an unbounded atlas at a guessed scale, the scale is set so its
larger side matches ``resolution`` (:func:`first_guess`), then it is lowered by ``SHRINK``
until a placement is valid (:func:`texture.placement.attempt`) and bisected between the
largest valid and smallest invalid scale (:func:`search`).

Speed: layouts and xatlas option sets are compared at ``resolution / COARSE`` with the
gutter scaled alike (:func:`plan_layouts`); xatlas's time is mostly rasterising islands at
the atlas resolution, so a coarse search costs about a third of a full one.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .islandset import IslandSet
from .parallel import parallel_map
from .placement import attempt, xatlas_pack

#: scale step while no placement is valid, and relative width at which bisection stops.
SHRINK, BISECT_TOL = 0.95, 0.005
#: candidates are compared at ``resolution / COARSE``; the full-resolution search then starts
#: from the coarse scale and steps by ``FINE_SHRINK``
COARSE, FINE_SHRINK = 4, 0.985
#: the coarse search stops at 1 %: the plan only has to rank layouts, and each step is an xatlas call
COARSE_BISECT_TOL = 0.01
#: utilisation the first guess's scale aims at (its pack is unbounded, so any value works)
GUESS_UTILIZATION = 0.6
#: seconds in which some job of a pool of xatlas packs must finish, or the pool is taken for
#: hung (:mod:`texture.parallel`: xatlas's shutdown can miss a wake-up). A guess takes
#: 7-20 ms, a coarse search (at most 16 packs) well under a second at 1M input faces: 20 s
#: leaves room for a loaded machine, and a job that does take longer only runs again here.
XATLAS_STALL_SECONDS = 20.0


@dataclass(frozen=True)
class Found:
    """A valid placement found by :func:`search`: scale (texels per unit), texel positions
    (V, 2), xatlas calls made."""

    tpu: float
    px: np.ndarray
    attempts: int


@dataclass
class Plan:
    """A coarse packing: which xatlas options, at what scale, for what utilisation."""

    utilization: float
    texels_per_unit: float  # at the full resolution
    options: dict
    attempts: int
    uv: np.ndarray | None = None  # (V, 2) the coarse placement in [0,1]^2 (same vertex order)


def coarse_size(resolution: int, padding: int) -> tuple[int, int]:
    """(resolution, padding) of the coarse search."""
    factor = COARSE if resolution >= COARSE * 128 else 1
    return resolution // factor, max(1, int(round(padding / factor)))


def first_guess(isl: IslandSet, resolution, padding, options) -> float:
    """Texels per unit at which xatlas's pack into an unbounded atlas just fits ``resolution``."""
    tpu = resolution * np.sqrt(GUESS_UTILIZATION / isl.area)
    o = isl.outline
    free = xatlas_pack(o.uv, o.faces, o.island, 0, padding, tpu, options)
    return tpu * (resolution - 1) / max(free.width, free.height, 1)


def largest_fit(fits, scale: float, shrink: float, tol: float, max_calls: int) -> tuple[tuple | None, int]:
    """((the largest scale found at which ``fits(scale)`` gave a result, that result) or None,
    the calls made). From ``scale``: lowered by ``shrink`` while nothing fits, raised by it
    while everything does (a start can be too cautious), then bisected (geometrically) between
    the largest fitting and the smallest failing scale until they are within ``tol``; at most
    ``max_calls`` calls. xatlas's validity is not monotone in the scale, so this is the largest
    found, not the largest there is."""
    calls = 0
    good = bad = None  # (scale, result) of the largest fitting / scale of the smallest failing
    while calls < max_calls:
        if good is not None and bad is not None and bad / good[0] - 1 < tol:
            break
        calls += 1
        got = fits(scale)
        if got is not None:
            good = (scale, got)
        else:
            bad = scale
        if good is None:
            scale *= shrink
        elif bad is None:
            scale /= shrink
        else:
            scale = np.sqrt(good[0] * bad)
    return good, calls


def search(isl: IslandSet, resolution, padding, options, max_attempts, tpu: float | None = None,
           shrink: float = SHRINK, tol: float = BISECT_TOL) -> Found | None:
    """The largest valid xatlas placement found (:func:`largest_fit`), or None.

    Without a starting ``tpu`` the first guess comes from a pack into an unbounded atlas.
    """
    attempts = 0
    if tpu is None:
        tpu = first_guess(isl, resolution, padding, options)
        attempts = 1
    good, calls = largest_fit(lambda t: attempt(isl, resolution, padding, t, options), tpu, shrink, tol,
                              max_attempts - attempts)
    return None if good is None else Found(good[0], good[1], attempts + calls)


@dataclass(frozen=True)
class SearchJob:
    """One layout x one xatlas option set, searched at the coarse resolution (a worker's job)."""

    uv: np.ndarray
    faces: np.ndarray
    island: np.ndarray
    resolution: int
    padding: int
    options: dict = field(default_factory=dict)
    max_attempts: int = 16
    start: float | None = None

    def islands(self) -> IslandSet:
        return IslandSet.of(self.uv, self.faces, self.island)


@dataclass(frozen=True)
class Estimate:
    """The utilisation a layout's first guess implies, and that guess (coarse texels per unit)."""

    utilization: float
    tpu: float


def _coarse_search(job: SearchJob, _shared=None) -> Plan | None:
    res, pad = coarse_size(job.resolution, job.padding)
    isl = job.islands()
    if isl.area <= 0:
        return None
    found = search(isl, res, pad, job.options, job.max_attempts, job.start, tol=COARSE_BISECT_TOL)
    if found is None:
        return None
    util = isl.verify(found.px / res, res)[1]
    return Plan(util, found.tpu * job.resolution / res, dict(job.options),
                found.attempts + (job.start is not None), found.px / res)


def _estimate_job(job: SearchJob, _shared=None) -> Estimate | None:
    res, pad = coarse_size(job.resolution, job.padding)
    isl = job.islands()
    if isl.area <= 0:
        return None
    tpu = first_guess(isl, res, pad, job.options)
    return Estimate(isl.area * tpu**2 / res**2, tpu)


Layout = tuple[np.ndarray, np.ndarray, np.ndarray]  # (uv (V,2), faces (F,3), island (F,))


def estimate_layouts(layouts: list[Layout], *, resolution: int = 2048, padding: int = 8,
                     options: dict | None = None, workers: int | None = None) -> list[Estimate | None]:
    """Per layout, one xatlas call: the utilisation its first guess implies and the guess (a
    ``start`` for :func:`plan_layouts`), or None. The bounded search ends near it: a rough
    way to rank layouts."""
    jobs = [SearchJob(uv, faces, island, resolution, padding, dict(options or {})) for uv, faces, island in layouts]
    return parallel_map(_estimate_job, jobs, workers, stall_seconds=XATLAS_STALL_SECONDS)


def plan_layouts(layouts: list[Layout], *, candidates: tuple[dict, ...], resolution: int = 2048,
                 padding: int = 8, max_attempts: int = 16, workers: int | None = None,
                 starts: list[float | None] | None = None) -> list[Plan | None]:
    """The best coarse :class:`Plan` of each layout over the xatlas option sets ``candidates``.

    Every layout x candidate search is independent and xatlas holds the GIL, so they run in
    up to ``workers`` processes; the result is the same as one after the other. ``starts`` (per layout) are first guesses from :func:`estimate_layouts` with
    the same options as every candidate: the searches start there instead of packing once more.
    """
    starts = starts or [None] * len(layouts)
    jobs = [SearchJob(uv, faces, island, resolution, padding, opts, max_attempts, start)
            for (uv, faces, island), start in zip(layouts, starts) for opts in candidates]
    results = parallel_map(_coarse_search, jobs, workers, stall_seconds=XATLAS_STALL_SECONDS)
    n = len(candidates)
    return [_best_plan(results[li * n:(li + 1) * n]) for li in range(len(layouts))]


def _best_plan(found: list[Plan | None]) -> Plan | None:
    """The highest utilisation of one layout's candidates (the first on a tie), charged with
    every candidate's xatlas calls."""
    best, calls = None, 0
    for p in found:
        if p is None:
            continue
        calls += p.attempts
        if best is None or p.utilization > best.utilization:
            best = p
    if best is not None:
        best.attempts = calls
    return best
