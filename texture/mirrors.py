"""Islands placed mirrored by the packer, and turning them back inside the box xatlas gave them.

xatlas's 90-degree chart "rotation" is a transpose (``swap(u, v)``), a reflection: a texture
reads mirrored there. :mod:`texture.pack` first hands such islands to xatlas mirrored (a
transpose of a reflection is a rotation); what stays mirrored is reflected back here,
where the gutter allows.
"""
from __future__ import annotations

import numpy as np

from mnacore.triangles import signed_areas


def reflect_in_box(px: np.ndarray, axis: int = 0) -> np.ndarray:
    """``px`` reflected across the line through its bounding box's centre, normal to ``axis``.

    xatlas's 90-degree chart "rotation" is a transpose, a reflection: a texture would read
    mirrored there. Reflecting once more turns the island into a proper rotation of itself
    with the same bounding box, so it stays in the box xatlas reserved for it; only its
    gutter to the neighbours has to be checked again (:func:`_gutter_clashes`).
    """
    out = px.copy()
    out[:, axis] = px[:, axis].min() + px[:, axis].max() - px[:, axis]
    return out


def gutter_clashes(isl, px: np.ndarray, islands: list[int], resolution: int, gap: int) -> list[int]:
    """Those of ``islands`` with a texel of another island within ``gap`` texels (a square
    window), at ``resolution``."""
    from scipy import ndimage

    from .raster import face_id_image

    o = isl.outline  # the same region per island as its faces, far fewer triangles (long fans: spans)
    face, _ = face_id_image(o.at(px)[o.faces] / resolution, resolution, resolution, spans=True)
    label = np.where(face >= 0, o.island[np.maximum(face, 0)], -1)
    size, top = 2 * gap + 1, np.iinfo(np.int64).max
    high = ndimage.maximum_filter(label, size=size, mode="constant", cval=-1)
    low = ndimage.minimum_filter(np.where(label < 0, top, label), size=size, mode="constant", cval=top)
    near = (label >= 0) & ((high != label) | (low != label))
    return sorted(set(np.unique(label[near]).tolist()) & set(islands))


def turn_back(isl, px: np.ndarray, mirrored: list[int], resolution: int, padding: int) -> np.ndarray | None:
    """``px`` with the mirrored islands turned back inside their boxes, keeping half the
    gutter (each reflected across its box's vertical line, or where that comes too close,
    its horizontal one), or None."""
    gap = max(1, padding // 2)
    px = px.copy()
    for k in mirrored:
        px[isl.verts[k]] = reflect_in_box(px[isl.verts[k]], 0)
    clash = gutter_clashes(isl, px, mirrored, resolution, gap)
    for k in clash:  # back to xatlas's outline, then reflected across the other axis
        v = isl.verts[k]
        px[v] = reflect_in_box(reflect_in_box(px[v], 0), 1)
    return None if clash and gutter_clashes(isl, px, clash, resolution, gap) else px


def mirrored_islands(isl, px: np.ndarray) -> list[int]:
    """Islands whose placement ``px`` (V, 2) reverses their UVs' orientation (a reflection)."""
    before = np.bincount(isl.island, weights=signed_areas(isl.uv, isl.faces), minlength=isl.n)
    after = np.bincount(isl.island, weights=signed_areas(px, isl.faces), minlength=isl.n)
    return np.flatnonzero(before * after < 0).tolist()
