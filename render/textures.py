"""Colour palettes for chart and island ids (the checker and UV grid live in :mod:`texture.textures`)."""
from __future__ import annotations

import colorsys

import numpy as np


def chart_colors(n: int, cmap: str = "tab20") -> np.ndarray:
    """``(n, 3)`` distinct sRGB colours for chart ids ``0 .. n-1`` (cycling a categorical map)."""
    from matplotlib import colormaps

    cm = colormaps[cmap]
    k = getattr(cm, "N", 20)
    return np.asarray([cm(i % k)[:3] for i in range(n)], np.float32)


def hue_palette(n: int) -> np.ndarray:
    """Golden-ratio hue palette ``(n, 3)`` sRGB: neighbours in id differ strongly in hue."""
    hues = (np.arange(n) * 0.618033988749895) % 1.0
    return np.asarray([colorsys.hsv_to_rgb(h, 0.65, 0.9) for h in hues], np.float32)
