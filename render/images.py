"""Image I/O through OpenImageIO, sRGB encoding, and image-difference measures.

Arrays are ``(H, W, C)`` float32, row 0 at the top. Radiance is linear; PNGs are
8-bit sRGB. Every write is atomic (``mnacore.atomic.atomic_path``).
"""
from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np

from mnacore.atomic import atomic_path


def _oiio():
    import OpenImageIO as oiio

    return oiio


def read_image(path: str | Path) -> np.ndarray:
    """Read any image OpenImageIO knows as float32 ``(H, W, C)`` (8-bit data scaled to 0..1).

    One reader for the project: :func:`texture.textures.read_image` (its errors are ValueErrors).
    """
    from texture.textures import read_image as _read

    return _read(path).astype(np.float32)


def _write(path: Path, pixels: np.ndarray, fmt: str, attrs: dict) -> None:
    oiio = _oiio()
    h, w, c = pixels.shape
    spec = oiio.ImageSpec(w, h, c, fmt)
    for k, v in attrs.items():
        spec.attribute(k, v)
    with atomic_path(path) as tmp:
        out = oiio.ImageOutput.create(str(tmp))
        if out is None or not out.open(str(tmp), spec):
            raise OSError(f"cannot write image {path}: {oiio.geterror()}")
        ok = out.write_image(pixels)
        out.close()
        if not ok:
            raise OSError(f"cannot write image {path}: {oiio.geterror()}")


def write_png(path: str | Path, srgb: np.ndarray) -> None:
    """Write sRGB values in [0, 1] ``(H, W, C)`` as an 8-bit PNG."""
    srgb = np.asarray(srgb, np.float32)
    srgb = srgb[..., None] if srgb.ndim == 2 else srgb
    data = np.round(np.clip(srgb, 0, 1) * 255).astype(np.uint8)
    _write(Path(path), data, "uint8", {})


def write_exr(path: str | Path, linear: np.ndarray, half: bool = True) -> None:
    """Write linear float data ``(H, W, C)`` as a ZIP-compressed OpenEXR (half floats by default)."""
    data = np.ascontiguousarray(np.asarray(linear, np.float32))
    data = data[..., None] if data.ndim == 2 else data
    _write(Path(path), data, "half" if half else "float", {"compression": "zip"})


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 sRGB transfer function (clips to [0, 1])."""
    x = np.clip(np.asarray(x, np.float32), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    """Inverse of ``linear_to_srgb``."""
    x = np.asarray(x, np.float32)
    return np.where(x <= 0.04045, x / 12.92, np.power((x + 0.055) / 1.055, 2.4))


def to_display(rgba: np.ndarray, background: tuple[float, float, float] | None) -> np.ndarray:
    """Linear RGBA radiance -> sRGB RGB for a PNG, composited over ``background`` (sRGB) by alpha.

    With ``background=None`` the RGB radiance is shown as rendered (environment visible).
    """
    rgb = np.asarray(rgba[..., :3], np.float32)
    if background is None or rgba.shape[-1] < 4:
        return linear_to_srgb(rgb)
    alpha = np.clip(rgba[..., 3:4], 0.0, 1.0)
    bg = srgb_to_linear(np.asarray(background, np.float32))
    # Mitsuba's RGBA film stores premultiplied colour: rgb already carries alpha.
    return linear_to_srgb(rgb + (1.0 - alpha) * bg)


class ImageError(NamedTuple):
    mean: float
    """mean over pixels and channels of the relative error."""
    max: float
    """max of the relative error after ``block`` x ``block`` box averaging (noise-robust)."""
    error: np.ndarray
    """(H, W) per-pixel relative error (mean over channels), for an error image."""


def box_downsample(img: np.ndarray, block: int) -> np.ndarray:
    """Average non-overlapping ``block`` x ``block`` tiles (crops to a multiple of ``block``)."""
    h, w = img.shape[0] // block * block, img.shape[1] // block * block
    img = img[:h, :w]
    return img.reshape(h // block, block, w // block, block, -1).mean((1, 3))


def relative_error(image: np.ndarray, reference: np.ndarray, floor: float = 0.05,
                   block: int = 4) -> ImageError:
    """``|image - reference| / (|reference| + floor)`` with a mean and a (block-averaged) max.

    The floor keeps near-black pixels from dominating; block averaging before the max
    keeps Monte Carlo noise in single pixels from failing a correct render.
    """
    a, b = np.asarray(image, np.float64), np.asarray(reference, np.float64)
    if a.shape != b.shape:
        raise ValueError(f"image shape {a.shape} differs from reference shape {b.shape}")
    rel = np.abs(a - b) / (np.abs(b) + floor)
    coarse = np.abs(box_downsample(a, block) - box_downsample(b, block)) / (
        np.abs(box_downsample(b, block)) + floor)
    return ImageError(float(rel.mean()), float(coarse.max()), rel.mean(-1).astype(np.float32))
