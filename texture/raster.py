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


def iter_hits(tri_uv: np.ndarray, height: int, width: int, strict: bool = True) -> Iterator[Hits]:
    """Yield :class:`Hits` chunk by chunk for triangles ``tri_uv (F, 3, 2)``.

    ``strict=True`` keeps centres strictly inside (a centre on a shared edge is hit by
    neither triangle: no double counting); ``strict=False`` keeps the boundary too
    (no cracks, but shared-edge centres are hit twice). Degenerate triangles hit nothing.
    """
    px = uv_to_pixel(tri_uv, height, width)  # (F, 3, 2) (col, row)
    lo = np.ceil(px.min(1) - 1e-12).astype(np.int64)
    hi = np.floor(px.max(1) + 1e-12).astype(np.int64)
    lo = np.maximum(lo, 0)
    hi[:, 0] = np.minimum(hi[:, 0], width - 1)
    hi[:, 1] = np.minimum(hi[:, 1], height - 1)
    size = np.maximum(hi - lo + 1, 0)
    count = size[:, 0] * size[:, 1]
    a, b, c = px[:, 0], px[:, 1], px[:, 2]
    e1, e2 = b - a, c - a
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    count[np.abs(det) < 1e-14] = 0
    tol = BARY_TOL if strict else -BARY_TOL
    cum = np.cumsum(count)
    start = 0
    while start < len(count):
        base = cum[start - 1] if start else 0
        stop = int(np.searchsorted(cum, base + CHUNK, side="right"))
        stop = max(stop, start + 1)
        faces = np.arange(start, stop)
        n = count[faces]
        if n.sum() > 0:
            f = np.repeat(faces, n)
            k = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
            w = size[f, 0]
            col = lo[f, 0] + k % w
            row = lo[f, 1] + k // w
            dx, dy = col - a[f, 0], row - a[f, 1]
            b1 = (dx * e2[f, 1] - dy * e2[f, 0]) / det[f]
            b2 = (e1[f, 0] * dy - e1[f, 1] * dx) / det[f]
            b0 = 1.0 - b1 - b2
            inside = (b0 > tol) & (b1 > tol) & (b2 > tol)
            yield Hits(row[inside], col[inside], f[inside], np.stack([b0, b1, b2], 1)[inside])
        start = stop


def coverage_count(tri_uv: np.ndarray, height: int, width: int) -> np.ndarray:
    """(H, W) int32: how many triangles strictly contain each texel centre."""
    out = np.zeros(height * width, np.int32)
    for h in iter_hits(tri_uv, height, width, strict=True):
        np.add.at(out, h.row * width + h.col, 1)
    return out.reshape(height, width)


def face_id_image(tri_uv: np.ndarray, height: int, width: int):
    """Per texel the face covering its centre (-1 for none) and its barycentrics.

    Returns ``(face (H, W) int64, bary (H, W, 3) float64)``; where several faces cover a
    texel the one with the larger index wins (deterministic).
    """
    face = np.full(height * width, -1, np.int64)
    bary = np.zeros((height * width, 3))
    for h in iter_hits(tri_uv, height, width, strict=False):
        idx = h.row * width + h.col
        face[idx] = h.face
        bary[idx] = h.bary
    return face.reshape(height, width), bary.reshape(height, width, 3)
