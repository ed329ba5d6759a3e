"""Pack UV islands into [0,1]^2 at one texel density for all islands: the export's last stage.

Every island keeps its exact shape and all share one scale (:mod:`texture.placement`).
The stages, each deciding once:

1. the coarse plan (:func:`texture.scale_search.plan_layouts` over the policy's xatlas
   option sets, or the plan the layout search already made) scaled up is the packing when
   it passes the overlap test at full resolution (its gutters scale with it);
2. otherwise a full-resolution search from the plan's scale, then from fresh guesses with
   every option set;
3. a packing that mirrors an island is redone with islands kept the right way round
   (:func:`_without_mirrors`);
4. the packing's scale is grown by the largest of ``GROW_STEPS`` (0.75, 0.5, 0.25 %) at
   which xatlas still places the islands (:func:`_grown`): the searches stop within 1 % of
   the largest scale they bracket (a coarse search's tolerance), which left up to 2 % of
   utilisation unused;
5. xatlas's exhaustive placement (``bruteForce``) is used at the coarse resolution only
   (:func:`full_options`): its cost grows with the atlas's texels times each island's, so a
   full-resolution call costs about 250x a coarse one (a 5-island outline of 3,334 faces:
   0.08 s at 512, 6-7 s at 2048, 41 s unbounded), and a full-resolution search (stage 2, or
   keeping islands unmirrored) took 80 s where the coarse plan took 3 s; such a search runs
   with xatlas's ordinary placement instead;
6. if xatlas never gave a valid placement (e.g. an island it always splits), a shelf packer
   of padded bounding boxes (:func:`texture.shelf.shelf_pack`) places the islands: any
   input packs.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .islandset import IslandSet
from .mirrors import mirrored_islands
from .placement import attempt
from .policy import DEFAULT_POLICY, SearchPolicy
from .scale_search import FINE_SHRINK, SHRINK, Plan, coarse_size, plan_layouts, search
from .shelf import shelf_pack

#: relative scale steps tried above the packing's scale, largest first (:func:`_grown`): they
#: cover the coarse search's 1 % bracket, where the next invalid scale may lie anywhere
GROW_STEPS = (1.0075, 1.005, 1.0025)


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


@dataclass(frozen=True)
class Candidate:
    """A valid full-resolution placement: utilisation, texels per unit, texel positions (V, 2),
    the xatlas options that made it."""

    utilization: float
    tpu: float
    px: np.ndarray
    options: dict | None


def _checked(isl: IslandSet, tpu: float, px: np.ndarray, options, resolution: int) -> Candidate | None:
    """The placement as a :class:`Candidate` if no texel is covered twice, else None."""
    overlap, util = isl.verify(px / resolution, resolution)
    return Candidate(util, tpu, px, options) if overlap == 0 else None


def full_options(options: dict | None) -> dict | None:
    """``options`` for a full-resolution xatlas call: without ``bruteForce`` (stage 5 of the
    module docstring)."""
    if not options or "bruteForce" not in options:
        return options
    return {k: v for k, v in options.items() if k != "bruteForce"}


def _better(a: Candidate | None, b: Candidate | None) -> Candidate | None:
    return b if b is not None and (a is None or b.utilization > a.utilization) else a


def _from_plan(isl: IslandSet, plan: Plan, resolution: int) -> Candidate | None:
    """The coarse placement, scaled up: its gutters scale with it, so it only has to pass the
    overlap test at full resolution (a full-resolution search from the coarse scale found
    less: xatlas's validity is not monotone in the scale)."""
    if plan.uv is None or not isl.inside(plan.uv * resolution, resolution):
        return None
    return _checked(isl, plan.texels_per_unit, plan.uv * resolution, plan.options, resolution)


def _search_all(isl: IslandSet, resolution: int, padding: int, searches: list, max_attempts: int) -> tuple:
    """(best valid :class:`Candidate` or None, xatlas calls) over ``searches`` (options, start, shrink)."""
    best, attempts = None, 0
    for opts, start, shrink in searches:
        opts = full_options(opts)
        found = search(isl, resolution, padding, opts, max_attempts, start, shrink)
        if found is not None:
            attempts += found.attempts
            best = _better(best, _checked(isl, found.tpu, found.px, opts, resolution))
    return best, attempts


def _xatlas_packing(isl: IslandSet, resolution: int, padding: int, options: dict | None, plan: Plan | None,
                    policy: SearchPolicy) -> tuple[Candidate | None, int]:
    """The best xatlas packing (stages 1-2 of the module docstring) and its xatlas calls."""
    if options is not None:
        return _search_all(isl, resolution, padding, [(options, None, SHRINK)], policy.max_attempts)
    attempts = 0
    if plan is None:
        plan = plan_layouts([(isl.uv, isl.faces, isl.island)], candidates=policy.pack_candidates,
                            resolution=resolution, padding=padding, max_attempts=policy.max_attempts)[0]
    if plan is not None:
        attempts += plan.attempts
        best = _from_plan(isl, plan, resolution)
        if best is not None:
            return best, attempts
        best, n = _search_all(isl, resolution, padding, [(plan.options, plan.texels_per_unit, FINE_SHRINK)],
                              policy.max_attempts)
        attempts += n
        if best is not None:
            return best, attempts
    # the coarse plan did not carry over: search every candidate
    best, n = _search_all(isl, resolution, padding, [(o, None, SHRINK) for o in policy.pack_candidates],
                          policy.max_attempts)
    return best, attempts + n


def pack_islands(uv: np.ndarray, faces: np.ndarray, island: np.ndarray, *, resolution: int = 2048,
                 padding: int = 8, options: dict | None = None, plan: Plan | None = None,
                 policy: SearchPolicy = DEFAULT_POLICY, floor: float = 0.0) -> Packing:
    """Pack islands ``island (F,)`` of the UV mesh ``(uv (V,2), faces (F,3))``; see module docstring.

    Every vertex must belong to faces of a single island (true for split-vertex meshes).
    ``options`` overrides xatlas ``PackOptions`` fields (e.g. ``{"rotate_charts": False}``) and
    is searched at full resolution (``bruteForce`` is dropped there: :func:`full_options`). By default the policy's option sets are compared by a
    coarse search (or the given ``plan``) and only the best is used. Never fails on valid
    arrays: folded, flipped, degenerate or oversized islands all pack, no island overlaps
    another or comes back mirrored, and all stay inside the unit square.

    ``floor``: the utilisation a caller keeps this packing only above (it has one that good):
    keeping islands unmirrored skips what cannot pass it (:func:`_without_mirrors`); what is
    returned may still be below it.
    """
    t0 = time.perf_counter()
    isl = IslandSet.of(uv, faces, island)
    if isl.area <= 0:
        raise ValueError("pack_islands: all UV faces have zero area")
    best, attempts = _xatlas_packing(isl, resolution, padding, options, plan, policy)
    if best is not None and mirrored_islands(isl, best.px):
        # the search lets xatlas's transposes mirror islands (cheap); the packing may not
        best = _without_mirrors(isl, resolution, padding, best, policy, floor)
    if best is not None:
        best = _grown(isl, resolution, padding, best, policy)
    packer = "xatlas"
    if best is None:
        tpu, px = shelf_pack(isl, resolution, padding)
        overlap, util = isl.verify(px / resolution, resolution)
        assert overlap == 0 and isl.inside(px, resolution), "shelf packing is valid by construction"
        best, packer = Candidate(util, tpu, px, None), "shelf"
    return Packing(best.px / resolution, best.tpu / resolution, best.tpu, resolution, padding, best.utilization, 0,
                   time.perf_counter() - t0, attempts, packer)


def _without_mirrors(isl: IslandSet, resolution: int, padding: int, best: Candidate,
                     policy: SearchPolicy, floor: float = 0.0) -> Candidate | None:
    """The best packing's options again, islands kept the right way round
    (:func:`texture.placement.attempt` with mirror tries), at its scale or a few
    ``FINE_SHRINK`` steps below; failing that, a search without xatlas's 90-degree turns
    (which never mirrors). None if neither packs.

    Like the plan, this runs at the coarse resolution and its placement is scaled up (its
    gutters scale with it): each xatlas call costs about a sixteenth of a full one. The
    search without turns runs at full resolution. With a ``floor`` (:func:`pack_islands`),
    a scale step whose utilisation (the packing's times the scale ratio squared: the same
    islands' texels) cannot pass it is not tried, and the search without turns is first
    planned coarse and runs only where that plan packs above the floor, as
    :func:`texture.layout_packing.best_packed` packs a plan only then: xatlas's exhaustive
    re-pack of a 1,501-island layout, whose turns mirrored islands, spent 21 s in eight
    failing tries here and packed below the layout it was to beat.
    """
    res, pad = coarse_size(resolution, padding)
    for step in range(policy.unmirror_steps):
        t = best.tpu * FINE_SHRINK ** step
        if floor > 0 and best.utilization * (t / best.tpu * GROW_STEPS[0]) ** 2 <= floor:
            break  # the islands' texels grow with the scale squared: this one, grown, cannot pass the floor
        px = attempt(isl, res, pad, t * res / resolution, best.options, mirror_tries=policy.mirror_tries)
        if px is not None and isl.inside(px * resolution / res, resolution):
            found = _checked(isl, t, px * resolution / res, best.options, resolution)
            if found is not None:
                return found
    plain = {**full_options(best.options or {}), "rotate_charts": False}
    if floor > 0:
        coarse = plan_layouts([(isl.uv, isl.faces, isl.island)], candidates=(plain,), resolution=resolution,
                              padding=padding, max_attempts=policy.max_attempts)[0]
        if coarse is None or coarse.utilization <= floor:
            return None
    found = search(isl, resolution, padding, plain, policy.max_attempts, None, SHRINK)
    if found is None:
        return None
    got = _checked(isl, found.tpu, found.px, plain, resolution)
    return got if got is not None and not mirrored_islands(isl, found.px) else None


def _grown(isl: IslandSet, resolution: int, padding: int, best: Candidate, policy: SearchPolicy) -> Candidate:
    """``best`` at the largest of ``GROW_STEPS`` times its scale where xatlas (its options, at
    the coarse resolution, islands kept the right way round, the placement scaled up as the
    plan's is) places every island validly and no island is mirrored; else ``best``. xatlas's
    validity is not monotone in the scale, so each step is tried, largest first."""
    res, pad = coarse_size(resolution, padding)
    for step in GROW_STEPS:
        t = best.tpu * step
        px = attempt(isl, res, pad, t * res / resolution, best.options, mirror_tries=policy.mirror_tries)
        if px is None:
            continue
        px = px * resolution / res
        if not isl.inside(px, resolution) or mirrored_islands(isl, px):
            continue
        got = _checked(isl, t, px, best.options, resolution)
        if got is not None and got.utilization > best.utilization:
            return got
    return best
