"""Vectorised rasterisation of UV triangles onto a texel grid (numpy only).

Texel ``(row r, col c)`` of an ``H x W`` image covers UV ``[c/W, (c+1)/W] x [1-(r+1)/H, 1-r/H]``
and is *hit* by a triangle when its centre ``((c+0.5)/W, 1-(r+0.5)/H)`` lies inside it
(row 0 is the top of the texture, v points up). Example: the triangle
``(0,0), (1,0), (0,1)`` on a 4 x 4 grid hits the 6 texels strictly below the
anti-diagonal; the 4 centres exactly on it are hit only with ``strict=False``.
"""
from __future__ import annotations

from typing import Iterator, NamedTuple

import numpy as np

#: candidates (texel, triangle) evaluated per chunk: bounds memory (~100 B each).
CHUNK = 2_000_000
#: barycentric tolerance; strict tests use +BARY_TOL, inclusive ones -BARY_TOL.
BARY_TOL = 1e-9
#: a row's candidate span is widened by this many texels each side: centres the barycentric
#: test keeps within BARY_TOL of an edge lie far closer to it than this
SPAN_PAD = 1e-3


class Hits(NamedTuple):
    """Texel hits: one row per (texel centre, triangle containing it)."""

    row: np.ndarray  # (N,) int64
    col: np.ndarray  # (N,) int64
    face: np.ndarray  # (N,) int64 index into the triangles
    bary: np.ndarray  # (N, 3) float64 barycentric coordinates of the texel centre


def uv_to_pixel(uv: np.ndarray, height: int, width: int) -> np.ndarray:
    """UV -> continuous (col, row) pixel coordinates where integer values are texel centres."""
    uv = np.asarray(uv, np.float64)
    return np.stack([uv[..., 0] * width - 0.5, height - 0.5 - uv[..., 1] * height], -1)


def _row_spans(a, b, c, rows, lo_col, hi_col) -> tuple[np.ndarray, np.ndarray]:
    """(first, last) candidate column of each (triangle, row) pair: where the row's line meets
    the triangle (its edges' crossings), widened by ``SPAN_PAD`` texels and kept inside the
    bounding box. A superset of the texel centres inside: the barycentric test decides."""
    xs = []
    for p, q in ((a, b), (b, c), (c, a)):
        dy = q[:, 1] - p[:, 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (rows - p[:, 1]) / dy
        ok = (dy != 0) & (t >= -1e-9) & (t <= 1 + 1e-9)
        x = p[:, 0] + np.clip(t, 0.0, 1.0) * (q[:, 0] - p[:, 0])
        xs.append(np.where(ok, x, np.nan))
        flat = dy == 0  # an edge along the row: both its ends
        xs.append(np.where(flat, p[:, 0], np.nan))
        xs.append(np.where(flat, q[:, 0], np.nan))
    xs = np.stack(xs, 1)
    seen = np.isfinite(xs).any(1)
    with np.errstate(all="ignore"):
        first = np.ceil(np.nanmin(np.where(seen[:, None], xs, 0.0), 1) - SPAN_PAD)
        last = np.floor(np.nanmax(np.where(seen[:, None], xs, -1.0), 1) + SPAN_PAD)
    first = np.maximum(np.where(seen, first, 1), lo_col).astype(np.int64)
    last = np.minimum(np.where(seen, last, 0), hi_col).astype(np.int64)
    return first, last


def iter_hits(tri_uv: np.ndarray, height: int, width: int, strict: bool = True,
              spans: bool = False) -> Iterator[Hits]:
    """Yield :class:`Hits` chunk by chunk for triangles ``tri_uv (F, 3, 2)``.

    ``strict=True`` keeps centres strictly inside (a centre on a shared edge is hit by
    neither triangle: no double counting); ``strict=False`` keeps the boundary too
    (no cracks, but shared-edge centres are hit twice). Degenerate triangles hit nothing.
    Candidates are the texels of each triangle's bounding box, or with ``spans`` of each row's
    span (:func:`_row_spans`): a long, thin triangle (a fan of an ear-clipped outline) then
    costs its area, not its box's, and a small one a few rows' overhead. Same hits either way.
    """
    px = uv_to_pixel(tri_uv, height, width)  # (F, 3, 2) (col, row)
    lo = np.ceil(px.min(1) - 1e-12).astype(np.int64)
    hi = np.floor(px.max(1) + 1e-12).astype(np.int64)
    lo = np.maximum(lo, 0)
    hi[:, 0] = np.minimum(hi[:, 0], width - 1)
    hi[:, 1] = np.minimum(hi[:, 1], height - 1)
    size = np.maximum(hi - lo + 1, 0)
    a, b, c = px[:, 0], px[:, 1], px[:, 2]
    e1, e2 = b - a, c - a
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    size[np.abs(det) < 1e-14] = 0
    tol = BARY_TOL if strict else -BARY_TOL
    rows = np.where(size[:, 0] > 0, size[:, 1], 0)
    # chunks bound the candidates: a box's texels, or a span bound (rows sampled at integers
    # sum to the area within one widest row, each span padded by at most a texel or two)
    work = (np.abs(det) / 2 + 2 * rows + size[:, 0]).astype(np.int64) * (rows > 0) if spans else rows * size[:, 0]
    cum = np.cumsum(work)
    start = 0
    while start < len(rows):
        base = cum[start - 1] if start else 0
        stop = max(int(np.searchsorted(cum, base + CHUNK, side="right")), start + 1)
        faces = np.arange(start, stop)
        start = stop
        nr = rows[faces]
        if nr.sum() == 0:
            continue
        f = np.repeat(faces, nr)
        row = lo[f, 1] + np.arange(int(nr.sum())) - np.repeat(np.cumsum(nr) - nr, nr)
        if spans:
            first, last = _row_spans(a[f], b[f], c[f], row, lo[f, 0], hi[f, 0])
        else:
            first, last = lo[f, 0], hi[f, 0]
        n = np.maximum(last - first + 1, 0)
        if n.sum() == 0:
            continue
        f, row, first = np.repeat(f, n), np.repeat(row, n), np.repeat(first, n)
        col = first + np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
        dx, dy = col - a[f, 0], row - a[f, 1]
        b1 = (dx * e2[f, 1] - dy * e2[f, 0]) / det[f]
        b2 = (e1[f, 0] * dy - e1[f, 1] * dx) / det[f]
        b0 = 1.0 - b1 - b2
        inside = (b0 > tol) & (b1 > tol) & (b2 > tol)
        yield Hits(row[inside], col[inside], f[inside], np.stack([b0, b1, b2], 1)[inside])


def coverage_count(tri_uv: np.ndarray, height: int, width: int) -> np.ndarray:
    """(H, W) int32: how many triangles strictly contain each texel centre."""
    out = np.zeros(height * width, np.int32)
    for h in iter_hits(tri_uv, height, width, strict=True):
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
