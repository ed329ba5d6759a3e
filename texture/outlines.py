"""Island outlines for the packer: the region an island covers, in far fewer faces.

xatlas only needs the region an island covers, so it is handed each island's border loops,
without the vertices inside straight runs (cut lines), ear-clipped by mapbox_earcut (the
largest loop is the outer border, the others holes): the same region with about a
twentieth of the faces. An island whose border is not simple loops, or whose UVs overlap
themselves, is handed over whole.

For a guess (a ranking of layouts, :func:`texture.scale_search.estimate_layouts`) the loops
may also be simplified (Douglas-Peucker, scikit-image) to a ``tolerance`` below the packer's
texel: ear clipping fans long slivers across the island, and xatlas's conservative
rasteriser walks each sliver's bounding box, so its time grows with the square of a loop's
vertices (a 1000-vertex disk 31 ms, 4000 vertices 313 ms). The placement itself is always
made and checked on the exact outline.
"""
from __future__ import annotations

import numpy as np

from mnacore.triangles import triangle_areas

from .islands import edge_keys, edge_use_counts, half_edges


def _border_loops(faces: np.ndarray) -> list[np.ndarray] | None:
    """Closed border loops (vertex indices, in the faces' winding) of one island, or None
    where the border is not a set of simple loops (a vertex with two border edges out)."""
    he = half_edges(faces)
    border = he[edge_use_counts(edge_keys(np.arange(int(faces.max()) + 1), faces)) == 1]
    if len(border) == 0 or len(np.unique(border[:, 0])) != len(border):
        return None
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


def island_outlines(uv: np.ndarray, faces: np.ndarray, island: np.ndarray, tolerance: float = 0.0) -> np.ndarray:
    """(F', 3) faces over the same vertices covering the same UV region as ``faces``: per
    island, its border loops ear-clipped (mapbox_earcut; the largest loop is the outer
    border, the others holes). An island whose border is not simple loops, or whose
    outline's area differs from its own (UVs that overlap themselves), keeps its faces.

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
            areas = [abs(_loop_area(uv[loop])) for loop in loops]
            outer = int(np.argmax(areas))
            loops = [loops[outer]] + [loop for i, loop in enumerate(loops) if i != outer]
            loops = [_without_straight_runs(uv, loop) for loop in loops]
            tri = _ear_clipped(uv, loops)
            own = float(triangle_areas(uv, f).sum())
            if len(tri) == 0 or abs(float(triangle_areas(uv, tri).sum()) - own) > 1e-9 * own:
                tri = None
            elif tolerance > 0:
                simple = [_simplified(uv, loop, tolerance) for loop in loops]
                coarse = _ear_clipped(uv, simple)
                area = abs(_loop_area(uv[simple[0]])) - sum(abs(_loop_area(uv[loop])) for loop in simple[1:])
                if len(coarse) and area > 0 and abs(float(triangle_areas(uv, coarse).sum()) - area) <= 1e-9 * area:
                    tri = coarse
        out.append(f if tri is None else tri)
    return np.concatenate(out) if out else faces
