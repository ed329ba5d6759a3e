"""Vectorised rasterisation of UV triangles onto a texel grid (numpy only).

Texel ``(row r, col c)`` of an ``H x W`` image covers UV ``[c/W, (c+1)/W] x [1-(r+1)/H, 1-r/H]``
and is *hit* by a triangle when its centre ``((c+0.5)/W, 1-(r+0.5)/H)`` lies inside it
(row 0 is the top of the texture, v points up). Example: the triangle
``(0,0), (1,0), (0,1)`` on a 4 x 4 grid hits the 6 texels strictly below the
anti-diagonal; the 4 centres exactly on it are hit only with ``strict=False``.

A triangle is convex, so the centres it hits on one row are a run of columns:
:func:`iter_spans` yields those runs (a few per triangle, however many texels it covers),
:func:`iter_hits` the texels themselves.
"""
from __future__ import annotations

from typing import Iterator, NamedTuple

import numpy as np

#: candidates (texel, triangle) evaluated per chunk: bounds memory (~100 B each).
CHUNK = 2_000_000
#: barycentric tolerance; strict tests use +BARY_TOL, inclusive ones -BARY_TOL.
BARY_TOL = 1e-9


class Hits(NamedTuple):
    """Texel hits: one row per (texel centre, triangle containing it)."""

    row: np.ndarray  # (N,) int64
    col: np.ndarray  # (N,) int64
    face: np.ndarray  # (N,) int64 index into the triangles
    bary: np.ndarray  # (N, 3) float64 barycentric coordinates of the texel centre


class Spans(NamedTuple):
    """Runs of hit texels: triangle ``face`` hits columns ``first..last`` (inclusive) of ``row``."""

    row: np.ndarray  # (N,) int64
    first: np.ndarray  # (N,) int64
    last: np.ndarray  # (N,) int64, >= first
    face: np.ndarray  # (N,) int64 index into the triangles


def uv_to_pixel(uv: np.ndarray, height: int, width: int) -> np.ndarray:
    """UV -> continuous (col, row) pixel coordinates where integer values are texel centres."""
    uv = np.asarray(uv, np.float64)
    return np.stack([uv[..., 0] * width - 0.5, height - 0.5 - uv[..., 1] * height], -1)


class _Setup(NamedTuple):
    a: np.ndarray  # (F, 2) first corner, pixels
    e1: np.ndarray  # (F, 2) b - a
    e2: np.ndarray  # (F, 2) c - a
    det: np.ndarray  # (F,)
    lo: np.ndarray  # (F, 2) bounding box in texels (col, row), clipped to the grid
    hi: np.ndarray
    rows: np.ndarray  # (F,) rows of the box (0: hits nothing)


def _setup(tri_uv: np.ndarray, height: int, width: int) -> _Setup:
    px = uv_to_pixel(tri_uv, height, width)  # (F, 3, 2) (col, row)
    lo = np.maximum(np.ceil(px.min(1) - 1e-12).astype(np.int64), 0)
    hi = np.floor(px.max(1) + 1e-12).astype(np.int64)
    hi[:, 0] = np.minimum(hi[:, 0], width - 1)
    hi[:, 1] = np.minimum(hi[:, 1], height - 1)
    size = np.maximum(hi - lo + 1, 0)
    a = px[:, 0]
    e1, e2 = px[:, 1] - a, px[:, 2] - a
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    rows = np.where((size[:, 0] > 0) & (np.abs(det) >= 1e-14), size[:, 1], 0)
    return _Setup(a, e1, e2, det, lo, hi, rows)


def _bary(s: _Setup, f: np.ndarray, row: np.ndarray, col: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Barycentric coordinates of texel centres (row, col) in triangles ``f``: the one formula
    every hit test uses, so spans and texels agree to the last bit."""
    dx, dy = col - s.a[f, 0], row - s.a[f, 1]
    b1 = (dx * s.e2[f, 1] - dy * s.e2[f, 0]) / s.det[f]
    b2 = (s.e1[f, 0] * dy - s.e1[f, 1] * dx) / s.det[f]
    return 1.0 - b1 - b2, b1, b2


def _inside(s: _Setup, f, row, col, tol: float) -> np.ndarray:
    b0, b1, b2 = _bary(s, f, row, col)
    return (b0 > tol) & (b1 > tol) & (b2 > tol)


def _row_runs(s: _Setup, f: np.ndarray, row: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """(first, last) hit column of each (triangle, row) pair (first > last: none).

    Each barycentric coordinate is linear along the row, so ``b > tol`` bounds the column on
    one side: the run is solved in closed form, then its ends are moved a column at a time
    until :func:`_inside` agrees (rounding moves a bound by one column at most; the loop is
    a guard, not a search)."""
    lo_col, hi_col = s.lo[f, 0], s.hi[f, 0]
    det, dy = s.det[f], row - s.a[f, 1]
    ax = s.a[f, 0]
    slope = [None, s.e2[f, 1] / det, -s.e1[f, 1] / det]
    const = [None, (-ax * s.e2[f, 1] - dy * s.e2[f, 0]) / det, (s.e1[f, 0] * dy + s.e1[f, 1] * ax) / det]
    slope[0], const[0] = -(slope[1] + slope[2]), 1.0 - const[1] - const[2]
    first, last = lo_col.astype(np.float64), hi_col.astype(np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        for k in range(3):
            edge = (tol - const[k]) / slope[k]  # b_k(edge) = tol
            first = np.where(slope[k] > 0, np.maximum(first, np.floor(edge) + 1), first)
            last = np.where(slope[k] < 0, np.minimum(last, np.ceil(edge) - 1), last)
            never = (slope[k] == 0) & ~(const[k] > tol)
            first = np.where(never, hi_col + 1, first)
    first = np.clip(np.nan_to_num(first, nan=hi_col + 1), lo_col, hi_col + 1).astype(np.int64)
    last = np.clip(np.nan_to_num(last, nan=lo_col - 1), lo_col - 1, hi_col).astype(np.int64)
    for _ in range(8):
        grow_l = (first > lo_col) & _inside(s, f, row, first - 1, tol)
        shrink_l = ~grow_l & (first <= last) & ~_inside(s, f, row, first, tol)
        grow_r = (last < hi_col) & _inside(s, f, row, last + 1, tol)
        shrink_r = ~grow_r & (last >= first) & ~_inside(s, f, row, last, tol)
        if not (grow_l.any() or shrink_l.any() or grow_r.any() or shrink_r.any()):
            break
        first = first - grow_l + shrink_l
        last = last + grow_r - shrink_r
    return first, last


def iter_spans(tri_uv: np.ndarray, height: int, width: int, strict: bool = True) -> Iterator[Spans]:
    """Yield :class:`Spans` chunk by chunk for triangles ``tri_uv (F, 3, 2)``: every run of
    texel centres a triangle hits on a row (``strict`` as in :func:`iter_hits`). The cost is
    one run per (triangle, row), not per texel."""
    return _iter_spans(_setup(tri_uv, height, width), BARY_TOL if strict else -BARY_TOL)


def _ramp(start: np.ndarray, count: np.ndarray) -> np.ndarray:
    """``start[i], start[i] + 1, ..., start[i] + count[i] - 1`` for every ``i``, concatenated."""
    return np.repeat(start, count) + np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)


def _chunks(cost: np.ndarray, budget: int) -> Iterator[slice]:
    """Consecutive slices of items whose ``cost`` sums to about ``budget`` (one item at least)."""
    cum = np.cumsum(cost)
    start = 0
    while start < len(cost):
        stop = max(int(np.searchsorted(cum, (cum[start - 1] if start else 0) + budget, side="right")), start + 1)
        yield slice(start, stop)
        start = stop


def _face_rows(s: _Setup, cost: np.ndarray, budget: int) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """(triangle, row) of every row of every triangle's box, in chunks of about ``budget``
    ``cost`` (per triangle; a chunk holds one triangle at least)."""
    for sl in _chunks(cost, budget):
        faces = np.arange(sl.start, sl.stop)
        nr = s.rows[faces]
        if nr.sum() == 0:
            continue
        f = np.repeat(faces, nr)
        yield f, _ramp(s.lo[faces, 1], nr)


def _iter_spans(s: _Setup, tol: float) -> Iterator[Spans]:
    for f, row in _face_rows(s, s.rows, CHUNK // 8):
        first, last = _row_runs(s, f, row, tol)
        keep = first <= last
        yield Spans(row[keep], first[keep], last[keep], f[keep])


def iter_hits(tri_uv: np.ndarray, height: int, width: int, strict: bool = True,
              spans: bool = False) -> Iterator[Hits]:
    """Yield :class:`Hits` chunk by chunk for triangles ``tri_uv (F, 3, 2)``.

    ``strict=True`` keeps centres strictly inside (a centre on a shared edge is hit by
    neither triangle: no double counting); ``strict=False`` keeps the boundary too
    (no cracks, but shared-edge centres are hit twice). Degenerate triangles hit nothing.
    Candidates are the texels of each triangle's bounding box, or with ``spans`` only the
    texels of its runs (:func:`iter_spans`): a long, thin triangle (a fan of an ear-clipped
    outline) then costs its area, not its box's. Same hits either way.
    """
    s = _setup(tri_uv, height, width)
    tol = BARY_TOL if strict else -BARY_TOL
    if spans:
        for run in _iter_spans(s, tol):
            n = run.last - run.first + 1
            for sl in _chunks(n, CHUNK):  # runs of about CHUNK texels (or one run)
                f, row = np.repeat(run.face[sl], n[sl]), np.repeat(run.row[sl], n[sl])
                col = _ramp(run.first[sl], n[sl])
                yield Hits(row, col, f, np.stack(_bary(s, f, row, col), 1))
        return
    width_ = np.maximum(s.hi[:, 0] - s.lo[:, 0] + 1, 0)
    for f, row in _face_rows(s, s.rows * width_, CHUNK):
        n = width_[f]
        col = _ramp(s.lo[f, 0], n)
        f, row = np.repeat(f, n), np.repeat(row, n)
        b0, b1, b2 = _bary(s, f, row, col)
        inside = (b0 > tol) & (b1 > tol) & (b2 > tol)
        yield Hits(row[inside], col[inside], f[inside], np.stack([b0, b1, b2], 1)[inside])


def coverage_count(tri_uv: np.ndarray, height: int, width: int) -> np.ndarray:
    """(H, W) int32: how many triangles strictly contain each texel centre.

    By row spans (:func:`iter_spans`; the same hits): a fan of long, thin faces (a cap of
    3,000 sections) cost its faces' boxes, 54 s at 2048 texels against 0.8 s by spans, and
    spans were faster on ordinary meshes too (a 111k-face unwrap 0.87 -> 0.47 s)."""
    out = np.zeros(height * width, np.int32)
    for h in iter_hits(tri_uv, height, width, strict=True, spans=True):
        np.add.at(out, h.row * width + h.col, 1)
    return out.reshape(height, width)


def face_id_image(tri_uv: np.ndarray, height: int, width: int, spans: bool = False):
    """Per texel the face covering its centre (-1 for none) and its barycentrics.

    Returns ``(face (H, W) int64, bary (H, W, 3) float64)``; where several faces cover a
    texel the one with the larger index wins (deterministic).
    """
    face = np.full(height * width, -1, np.int64)
    bary = np.zeros((height * width, 3))
    for h in iter_hits(tri_uv, height, width, strict=False, spans=spans):
        idx = h.row * width + h.col
        face[idx] = h.face
        bary[idx] = h.bary
    return face.reshape(height, width), bary.reshape(height, width, 3)
