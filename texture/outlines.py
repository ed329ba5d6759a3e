"""Island outlines for the packer: the region an island covers, in far fewer faces.

xatlas only needs the region an island covers, so it is handed each island's border loops,
without the vertices inside straight runs (cut lines), ear-clipped by mapbox_earcut (each
outer border with its holes, :func:`_pieces`): the same region with about a twentieth of
the faces. An island whose UVs overlap themselves is handed over whole.

For a guess (a ranking of layouts, :func:`texture.scale_search.estimate_layouts`) the loops
may also be simplified (Douglas-Peucker, scikit-image) to a ``tolerance`` below the packer's
texel: ear clipping fans long slivers across the island, and xatlas's conservative
rasteriser walks each sliver's bounding box, so its time grows with the square of a loop's
vertices (a 1000-vertex disk 31 ms, 4000 vertices 313 ms). The placement itself is always
made and checked on the exact outline.
"""
from __future__ import annotations

import numpy as np

from mnacore.triangles import signed_areas, triangle_areas

from .flatten import split_pinched
from .islands import edge_keys, edge_use_counts, half_edges


def _border_loops(faces: np.ndarray, split: bool = True) -> list[np.ndarray] | None:
    """Closed border loops (vertex indices, in the faces' winding) of one island, or None
    where the border is not a set of loops.

    A vertex the border passes twice (two fans of faces meeting at one point of the border:
    a disk whose cut or filled hole touches its border there) is split into one vertex per
    fan first (``split``), so each loop is followed through it along its own fan; the loops
    come back in the island's vertex ids, visiting that vertex twice (a polygon that touches
    itself at a point, which ear clipping takes: the caller checks the area)."""
    he = half_edges(faces)
    border = he[edge_use_counts(edge_keys(np.arange(int(faces.max()) + 1), faces)) == 1]
    if len(border) == 0:
        return None
    if len(np.unique(border[:, 0])) != len(border):
        if not split:
            return None
        fanned, src = split_pinched(faces)
        loops = _border_loops(fanned, split=False)
        return None if loops is None else [src[loop] for loop in loops]
    succ = dict(zip(border[:, 0].tolist(), border[:, 1].tolist()))
    loops, seen = [], set()
    for start in border[:, 0].tolist():
        if start in seen:
            continue
        loop, v = [], start
        while v is not None and v not in seen:
            seen.add(v)
            loop.append(v)
            v = succ.get(v)
        if v != start:
            return None
        loops.append(np.array(loop, np.int64))
    return loops


def _loop_area(p: np.ndarray) -> float:
    """Signed area of the closed polygon ``p (N, 2)`` (shoelace)."""
    return 0.5 * float(p[:, 0] @ np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) @ p[:, 1])


def _without_straight_runs(uv: np.ndarray, loop: np.ndarray, sin_tol: float = 1e-8) -> np.ndarray:
    """``loop`` without the vertices inside straight runs (e.g. along a cut line): ear clipping
    makes zero-area triangles there, and xatlas's conservative rasteriser (``bilinear``) spends
    up to 20x longer on such slivers than on the island's own faces."""
    if len(loop) <= 3:
        return loop
    p = uv[loop]
    a, b = p - np.roll(p, 1, axis=0), np.roll(p, -1, axis=0) - p
    cross = np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])  # |a| |b| sin(turn)
    straight = cross <= sin_tol * np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1)
    return loop if straight.sum() > len(loop) - 3 else loop[~straight]


def _simplified(uv: np.ndarray, loop: np.ndarray, tolerance: float) -> np.ndarray:
    """``loop`` with the vertices Douglas-Peucker drops at ``tolerance`` left out (the
    vertices kept are the loop's own, in order; at least three)."""
    from skimage.measure import approximate_polygon

    if len(loop) <= 4:
        return loop
    closed = np.append(loop, loop[0])
    kept = approximate_polygon(uv[closed], tolerance)[:-1]
    # map the kept points back to loop positions: they come in loop order, each an exact copy
    pos, at = [], 0
    for q in kept:
        while at < len(loop) and not (uv[loop[at]] == q).all():
            at += 1
        if at == len(loop):
            return loop
        pos.append(at)
        at += 1
    return loop[pos] if len(pos) >= 3 else loop


def _ear_clipped(uv: np.ndarray, loops: list[np.ndarray]) -> np.ndarray:
    """(T, 3) triangles of ``loops`` ear-clipped, the first loop the outer border."""
    import mapbox_earcut

    verts = np.concatenate(loops)
    ends = np.cumsum([len(loop) for loop in loops]).astype(np.uint32)
    return verts[mapbox_earcut.triangulate_float64(np.ascontiguousarray(uv[verts]), ends).astype(np.int64)].reshape(-1, 3)


def _pieces(uv: np.ndarray, loops: list[np.ndarray]) -> list[list[np.ndarray]]:
    """``loops`` grouped as ear clipping takes them: each outer border first, then its holes.

    The largest loop (by area) is the island's outer border; loops wound the same way are
    outer borders too (a piece joined to the island at one point of its border: the border
    passes that vertex twice), loops wound the other way are holes, each in the smallest
    outer border that holds most of its vertices."""
    from skimage.measure import points_in_poly

    areas = np.array([_loop_area(uv[loop]) for loop in loops])
    sign = np.sign(areas[int(np.argmax(np.abs(areas)))])
    outers = sorted(np.flatnonzero(np.sign(areas) == sign), key=lambda i: -abs(areas[i]))
    groups = {int(i): [loops[i]] for i in outers}
    for h in np.flatnonzero(np.sign(areas) != sign):
        owner = outers[0]
        if len(outers) > 1:
            holding = [i for i in outers if points_in_poly(uv[loops[h]], uv[loops[i]]).mean() > 0.5]
            owner = min(holding, key=lambda i: abs(areas[i])) if holding else owner
        groups[int(owner)].append(loops[h])
    return [groups[int(i)] for i in outers]


def _region_area(uv: np.ndarray, pieces: list[list[np.ndarray]]) -> float:
    """Area inside the outer borders and outside their holes (:func:`_pieces`)."""
    return sum(abs(_loop_area(uv[g[0]])) - sum(abs(_loop_area(uv[h])) for h in g[1:]) for g in pieces)


def _clipped(uv: np.ndarray, pieces: list[list[np.ndarray]]) -> np.ndarray:
    return np.concatenate([_ear_clipped(uv, g) for g in pieces])


def island_outlines(uv: np.ndarray, faces: np.ndarray, island: np.ndarray, tolerance: float = 0.0) -> np.ndarray:
    """(F', 3) faces over the same vertices covering the same UV region as ``faces``: per
    island, its border loops ear-clipped (mapbox_earcut; each outer border with its holes,
    :func:`_pieces`). An island whose border is not loops, or whose outline's area differs
    from its own (UVs that overlap themselves), keeps its faces.

    ``tolerance`` > 0: each loop simplified within it first (a region within ``tolerance``
    of the island's, for guesses only; see the module docstring); an island whose simplified
    loops do not ear-clip to their own area (they cross) keeps its exact outline."""
    out = []
    order = np.argsort(island, kind="stable")
    for f in np.split(faces[order], np.cumsum(np.bincount(island, minlength=int(island.max()) + 1))[:-1]):
        if len(f) == 0:
            continue
        loops = _border_loops(f)
        tri = None
        if loops is not None:
            pieces = [[_without_straight_runs(uv, loop) for loop in g] for g in _pieces(uv, loops)]
            tri = _clipped(uv, pieces)
            own = float(triangle_areas(uv, f).sum())
            if len(tri) == 0 or abs(float(triangle_areas(uv, tri).sum()) - own) > 1e-9 * own:
                tri = None
            elif tolerance > 0:
                simple = [[_simplified(uv, loop, tolerance) for loop in g] for g in pieces]
                coarse = _clipped(uv, simple)
                area = _region_area(uv, simple)
                if len(coarse) and area > 0 and abs(float(triangle_areas(uv, coarse).sum()) - area) <= 1e-9 * area:
                    tri = coarse
        out.append(f if tri is None else tri)
    return np.concatenate(out) if out else faces


#: an island's outline is re-triangulated (:func:`refine_slivers`) where the UV bounding
#: boxes of its triangles cover more than this many times its area. xatlas's conservative
#: rasteriser walks each triangle's bounding box, so that sum is what an island costs it
#: beyond a fixed cost per call (about 0.18 s at 2048 texels here, whatever the outline).
#: A fat triangulation covers 2-3 times its area; ear clipping a long convex or round loop
#: (a cap or a cone unrolled, rims of hundreds to thousands of vertices) fans slivers from
#: one vertex across the island, and the sum grows with the loop's vertices: a cone of 3,000
#: sections, ratios 60-610, took 1.2-1.5 s per xatlas call, 0.08-0.2 s refined. Islands of
#: irregular outline stay at 7-30 (a scan's islands at 111k faces, 460-700 border vertices:
#: 0.18 s per call either way), so below this they keep their ear clipping.
SLIVER_BBOX_RATIO = 50.0
#: Steiner vertices Triangle may add per outline vertex (a graded quality mesh of a round
#: loop of n vertices needs a few times n; see :func:`refine_slivers`)
STEINER_PER_VERTEX = 4


def bbox_ratios(uv: np.ndarray, faces: np.ndarray, island: np.ndarray) -> np.ndarray:
    """Per island, the UV bounding boxes of its faces summed over their area
    (:data:`SLIVER_BBOX_RATIO`; inf for an island of no area)."""
    q = uv[faces]
    boxes = np.bincount(island, np.ptp(q[:, :, 0], axis=1) * np.ptp(q[:, :, 1], axis=1))
    areas = np.bincount(island, triangle_areas(uv, faces), minlength=len(boxes))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(areas > 0, boxes / np.where(areas > 0, areas, 1.0), np.inf)


def refine_slivers(uv: np.ndarray, faces: np.ndarray, island: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(faces, island, frame, weights): the outline ``(uv, faces, island)`` with each island
    over :data:`SLIVER_BBOX_RATIO` re-triangulated with quality (Shewchuk's Triangle through
    libigl, ``igl.triangle.refine``: angles of at least 25 degrees, no new vertex on the
    border, so the region is the same), and its new interior vertices. New vertex ``j`` is
    ``uv`` index ``len(uv) + j`` in the returned faces; it lies at ``weights[j] @
    uv[frame[j]]``: an affine combination of three of its island's vertices (its largest
    triangle's), so it follows every turn, move, scale or mirror of them exactly. An island
    whose refinement does not keep its area, border or winding keeps its faces."""
    import igl.triangle

    from .islands import edge_keys, edge_use_counts, half_edges

    new_faces, new_island, frames, weights = [faces], [island], [], []
    keep = np.ones(len(faces), bool)
    count = len(uv)
    for k in np.flatnonzero(bbox_ratios(uv, faces, island) > SLIVER_BBOX_RATIO):
        sel = np.flatnonzero(island == k)
        vid, inv = np.unique(faces[sel], return_inverse=True)
        f = inv.reshape(-1, 3)
        v = uv[vid]
        area = signed_areas(v, f)
        # Triangle takes a planar triangulation: faces of one winding, none flat, no two
        # vertices at one point (an island handed over whole may be none of these)
        if not ((area > 0).all() or (area < 0).all()) or len(np.unique(v, axis=0)) < len(v):
            continue
        border = half_edges(f)[edge_use_counts(edge_keys(np.arange(len(v)), f)) == 1]
        # at most STEINER_PER_VERTEX new vertices per outline vertex: Triangle's quality
        # refinement near small input angles can add vertices without end (a sliver-pole
        # sphere's outline ran it out of memory and it exits); capped, the rest stay slivers
        cap = STEINER_PER_VERTEX * len(v)
        try:
            v2, f2 = igl.triangle.refine(v, border.astype(np.int64), f.astype(np.int64), f"rq25YQS{cap}")
        except RuntimeError:  # Triangle gave up (its own exit): keep the ear clipping
            continue
        sign = np.sign(area[0])
        f2 = f2 if sign > 0 else f2[:, ::-1]  # Triangle winds counter-clockwise
        same_border = not (half_edges(f2)[edge_use_counts(edge_keys(np.arange(len(v2)), f2)) == 1] >= len(v)).any()
        area2 = signed_areas(v2, f2)
        if (len(v2) < len(v) or not np.array_equal(v2[:len(v)], v) or not same_border
                or (np.sign(area2) != sign).any() or abs(area2.sum() - area.sum()) > 1e-9 * abs(area.sum())):
            continue
        a, b, c = f[int(np.argmax(np.abs(area)))]
        basis = np.column_stack([v[b] - v[a], v[c] - v[a]])
        st = np.linalg.solve(basis, (v2[len(v):] - v[a]).T).T  # p = a + s (b - a) + t (c - a)
        frames.append(np.tile(vid[[a, b, c]], (len(st), 1)))
        weights.append(np.column_stack([1.0 - st.sum(1), st]))
        local = np.concatenate([vid, count + np.arange(len(v2) - len(v))])
        count += len(v2) - len(v)
        keep[sel] = False
        new_faces.append(local[f2])
        new_island.append(np.full(len(f2), k))
    if not frames:
        return faces, island, np.zeros((0, 3), np.int64), np.zeros((0, 3))
    new_faces[0], new_island[0] = faces[keep], island[keep]
    return np.concatenate(new_faces), np.concatenate(new_island), np.concatenate(frames), np.concatenate(weights)
