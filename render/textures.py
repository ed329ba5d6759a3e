"""Generated textures (checkerboard, UV grid) at a chosen 3D square size.

UV convention (OBJ / glTF-as-OBJ): ``u`` to the right, ``v`` up, ``(0, 0)`` at the
*bottom-left* of the image. Pixel ``(row i, col j)`` of an ``S x S`` texture covers
``u in [j, j+1] / S`` and ``v in [S-1-i, S-i] / S``; texel centres sit at half-integers.
Example: with 2 squares per UV unit the square ``u < 0.5, v < 0.5`` is the bottom-left
quarter of the image and has colour 0.

3D square size: a UV-mapped mesh with 3D area ``A3`` and UV area ``Auv`` has mean
length scale ``s = sqrt(A3 / Auv)`` (3D length per UV unit). A checker with ``n``
squares per UV unit has squares of mean 3D side ``s / n``; so for side ``L`` we use
``n = s / L``. Two meshes of one shape (ours, xatlas) textured with the same ``L``
show squares of the same size in 3D and can be compared side by side.
"""
from __future__ import annotations

import colorsys

import numpy as np

from texture.geometry import triangle_areas

#: a generated texture must give each square at least this many texels
MIN_TEXELS_PER_SQUARE = 4


def uv_length_scale(vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray) -> float:
    """``s = sqrt(A3 / Auv)``: mean 3D length per UV unit of a UV-mapped mesh."""
    a3 = triangle_areas(vertices, faces).sum()
    auv = triangle_areas(uv, faces).sum()
    if not auv > 0:
        raise ValueError("uv: the mesh's UV triangles have zero total area")
    return float(np.sqrt(a3 / auv))


def squares_per_uv_unit(vertices, faces, uv, square_size: float) -> float:
    """Checker frequency ``n = s / L`` giving squares of mean 3D side ``square_size``."""
    if not square_size > 0:
        raise ValueError(f"square_size: expected > 0, got {square_size}")
    return uv_length_scale(vertices, faces, uv) / square_size


def _texel_uv(size: int) -> tuple[np.ndarray, np.ndarray]:
    centres = (np.arange(size) + 0.5) / size
    u = np.broadcast_to(centres[None, :], (size, size))
    v = np.broadcast_to(centres[::-1, None], (size, size))
    return u, v


def _check_frequency(frequency: float, size: int) -> None:
    if not frequency > 0:
        raise ValueError(f"checker frequency must be > 0, got {frequency}")
    if size / frequency < MIN_TEXELS_PER_SQUARE:
        raise ValueError(f"a {size}px texture cannot hold {frequency:.1f} squares per UV unit "
                         f"(< {MIN_TEXELS_PER_SQUARE} texels each); raise material.texture_size "
                         "or lower material.checker_squares, or use --texture procedural")


def checker_image(frequency: float, size: int = 2048,
                  colors=((0.85, 0.85, 0.85), (0.12, 0.12, 0.12))) -> np.ndarray:
    """Checkerboard ``(size, size, 3)`` sRGB in [0, 1] with ``frequency`` squares per UV unit.

    Colour 0 where ``floor(n u) + floor(n v)`` is even (the square at UV origin).
    """
    _check_frequency(frequency, size)
    u, v = _texel_uv(size)
    parity = (np.floor(frequency * u) + np.floor(frequency * v)).astype(np.int64) % 2
    c = np.asarray(colors, np.float32)
    return c[parity]


def uv_grid_image(frequency: float, size: int = 2048) -> np.ndarray:
    """UV-grid texture ``(size, size, 3)`` sRGB: hue follows ``u``, brightness alternates, dark lines.

    Cells have the checker's size; the hue ramp (red at u=0 through the spectrum) and a
    lightness ramp in ``v`` make orientation and flips visible, thin lines the cell edges.
    """
    _check_frequency(frequency, size)
    from matplotlib.colors import hsv_to_rgb

    u, v = _texel_uv(size)
    iu, iv = np.floor(frequency * u), np.floor(frequency * v)
    hue = (u * 0.8) % 1.0
    value = 0.55 + 0.3 * v + 0.1 * ((iu + iv) % 2)
    rgb = hsv_to_rgb(np.stack([hue, np.full_like(hue, 0.55), np.clip(value, 0, 1)], -1))
    fu, fv = frequency * u - iu, frequency * v - iv
    width = 0.06  # line half-width, in cells
    edge = (fu < width) | (fu > 1 - width) | (fv < width) | (fv > 1 - width)
    rgb[edge] = 0.1
    return rgb.astype(np.float32)


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
