"""The packer's fallback: islands' padded bounding boxes on shelves. Any input packs."""
from __future__ import annotations

import numpy as np

from .islandset import IslandSet


def _shelf_layout(ext: np.ndarray, order: np.ndarray, tpu: float, resolution: int,
                  padding: int) -> tuple[np.ndarray, bool]:
    """(box corner per island (n, 2) texels, whether all boxes fit) at ``tpu``."""
    size = ext * tpu + 2 * padding + 1  # one texel more: boxes never share a texel centre
    pos = np.zeros((len(ext), 2))
    x = y = row_h = 0.0
    for i in order:
        if x + size[i, 0] > resolution and x > 0:
            x, y, row_h = 0.0, y + row_h, 0.0
        pos[i] = x, y
        x += size[i, 0]
        row_h = max(row_h, size[i, 1])
    return pos, (y + row_h <= resolution and (size[:, 0] <= resolution).all())


def shelf_pack(isl: IslandSet, resolution: int, padding: int) -> tuple[float, np.ndarray]:
    """(tpu, texel positions): islands' bounding boxes, ``padding`` apart, on shelves.

    Boxes are sorted by height and laid left to right in rows; the scale is bisected to
    the largest that fits ``resolution^2``. Always succeeds (a small enough scale fits).
    """
    lo_uv = np.array([isl.uv[v].min(0) if len(v) else np.zeros(2) for v in isl.verts])
    ext = np.array([np.ptp(isl.uv[v], 0) if len(v) else np.zeros(2) for v in isl.verts])
    order = np.argsort(-ext[:, 1], kind="stable")
    lo, hi = 0.0, (resolution - 2 * padding - 1) / max(ext.max(), 1e-12)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _shelf_layout(ext, order, mid, resolution, padding)[1] else (lo, mid)
    tpu = lo
    pos, _ = _shelf_layout(ext, order, tpu, resolution, padding)
    px = np.zeros_like(isl.uv)
    for i, v in enumerate(isl.verts):
        px[v] = tpu * (isl.uv[v] - lo_uv[i]) + pos[i] + padding + 0.5
    return tpu, px
