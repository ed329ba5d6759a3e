"""Checking a packing: texels covered by two islands, and the covered fraction of the square."""
from __future__ import annotations

import numpy as np

from .raster import iter_spans


def _covered(start: np.ndarray, stop: np.ndarray) -> int:
    """Length of the union of half-open integer intervals ``[start, stop)``."""
    if not len(start):
        return 0
    order = np.argsort(start, kind="stable")
    s, e = start[order], stop[order]
    reach = np.concatenate([[s[0]], np.maximum.accumulate(e)[:-1]])  # furthest end before each
    return int(np.maximum(e - np.maximum(s, reach), 0).sum())


def verify_packing(uv: np.ndarray, faces: np.ndarray, island: np.ndarray, resolution: int) -> tuple[int, float]:
    """(overlap, covered fraction of [0,1]^2) at ``resolution``: a texel centre strictly inside
    faces of k > 1 islands adds k - 1 to the overlap (0 exactly when no texel has two islands).

    Works on runs of texels (:func:`texture.raster.iter_spans`), not texels: rows of different
    islands' runs laid end to end, the overlap is the sum of every island's covered length
    less the length of all islands' union; overlaps inside one island (a fold) do not count."""
    runs = list(iter_spans(uv[faces], resolution, resolution, strict=True))
    if not runs:
        return 0, 0.0
    row = np.concatenate([r.row for r in runs])
    first = np.concatenate([r.first for r in runs])
    stop = np.concatenate([r.last for r in runs]) + 1
    isl = island[np.concatenate([r.face for r in runs])].astype(np.int64)
    line = row * (resolution + 1)  # rows apart: no run reaches the next row's offset
    union = _covered(line + first, line + stop)
    grid = resolution * (resolution + 1)
    own = _covered(isl * grid + line + first, isl * grid + line + stop)
    return own - union, union / resolution ** 2
