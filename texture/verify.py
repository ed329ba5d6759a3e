"""Checking a packing: texels covered by two islands, and the covered fraction of the square."""
from __future__ import annotations

import numpy as np

from .raster import iter_hits


def verify_packing(uv: np.ndarray, faces: np.ndarray, island: np.ndarray, resolution: int,
                   spans: bool = False) -> tuple[int, float]:
    """(texels hit by two different islands, covered fraction of [0,1]^2) at ``resolution``
    (``spans``: see :func:`texture.raster.iter_hits`)."""
    owner = np.full(resolution * resolution, -1, np.int64)
    clash = np.zeros(resolution * resolution, bool)
    for h in iter_hits(uv[faces], resolution, resolution, strict=True, spans=spans):
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
