"""One xatlas placement at a given scale, re-placed so every island keeps its exact shape.

xatlas (``Atlas.add_uv_mesh`` + ``generate``) places the islands; each island gets its
own material id (``face_materials``) so islands that share UV positions (charts are all
parametrised over [-1,1]^2) are never merged. xatlas does not promise to keep an island's
shape: it rotates islands by any angle (``rotate_charts_to_axis``), stretches them by up to
a texel to align their extents to whole texels, and silently *shrinks* an island that is
larger than the atlas. So we never use xatlas's UVs directly: per island we fit the
similarity ``x -> s R x + t`` (weighted Procrustes, :func:`texture.similarity.similarity_fit`;
all islands at once, :func:`texture.similarity.similarity_rotations`) from its input UVs to
xatlas's, keep only the rotation ``R``, and re-place the island at the one shared scale
``tpu`` (texels per unit) around xatlas's centroid.

A placement is accepted only when it is *valid*: every island lies within
``MAX_FIT_RESIDUAL`` texels of where xatlas put it (so xatlas's gutters still hold), all
UVs are inside the square, and no texel centre is covered by two islands (rasterised).
An island that xatlas shrank, split or re-parametrised fails the first test.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from mnacore.triangles import triangle_areas

from .islandset import IslandSet
from .mirrors import turn_back
from .similarity import similarity_rotations

#: largest allowed distance (texels) between xatlas's placement and the re-placed island.
MAX_FIT_RESIDUAL = 2.0
#: UVs handed to xatlas are scaled so the median face is UV_UNIT on a side (see xatlas_pack)
UV_UNIT = 100.0

#: xatlas atlases kept alive after their call (see :func:`xatlas_pack`)
KEPT_ATLASES = 8
_kept: deque = deque(maxlen=KEPT_ATLASES)


def xatlas_pack(uv, faces, island, resolution, padding, tpu, options: dict | None = None):
    """xatlas's packer on the islands ``(uv, faces, island)`` at ``tpu`` texels per UV unit."""
    import xatlas

    # xatlas drops faces whose UV area is below a fixed float epsilon (~1e-7) and then splits
    # an island where only such slivers held it together: hand it UVs in units where the
    # median face is UV_UNIT on a side (the placement in texels does not change). At a unit
    # of 1 a genus-2 surface's 6 islands came back as 7 charts and a torus's 8 islands as 44
    # (at 10: 11); at 100 both are whole. Moving the islands apart in UV as well kept them
    # whole too but changed xatlas's layouts (utilisation fell by 0.08 on a 3-chart fit).
    area = triangle_areas(uv, faces)
    median = float(np.median(area[area > 0])) if (area > 0).any() else 1.0
    unit = UV_UNIT / np.sqrt(median)
    atlas = xatlas.Atlas()
    atlas.add_uv_mesh((uv * unit).astype(np.float32), faces.astype(np.uint32), island.astype(np.uint32).reshape(-1, 1))
    po = xatlas.PackOptions()
    po.resolution = int(resolution)
    po.padding = int(padding)
    po.texels_per_unit = float(tpu / unit)
    po.bilinear = True
    po.bruteForce = False
    for k, v in (options or {}).items():
        setattr(po, k, v)
    atlas.generate(pack_options=po)
    # Destroying an atlas joins xatlas's worker threads, and a worker that is going back to
    # sleep right then can miss the wake-up (xatlas sets the flag and notifies without the
    # worker's mutex): the join waits forever (seen in a worker of texture.parallel, and once
    # in a test process). Each atlas is therefore destroyed only KEPT_ATLASES calls later,
    # when its workers have long been asleep; the outlines packed here are small.
    _kept.append(atlas)
    return atlas


@dataclass(frozen=True)
class Placed:
    """Islands re-placed rigidly after one xatlas call.

    Attributes:
        px: (V, 2) texel positions.
        residual: largest distance (texels) of a re-placed vertex from xatlas's.
        mirrored: islands xatlas placed mirrored (a reflection of their UVs fits best).
    """

    px: np.ndarray
    residual: float
    mirrored: list[int]


def place(isl: IslandSet, atlas, tpu: float) -> Placed:
    """xatlas's placement ``atlas`` re-placed rigidly at ``tpu``, island by island."""
    vmap, _, out_uv = atlas[0]
    src = isl.outline.src
    dst = np.zeros_like(isl.uv)
    seen = np.zeros(len(isl.uv), bool)
    # xatlas normalises by w, h; its vertices are the outlines' (src -> ours), then the
    # vertices inside re-triangulated outlines (none of ours: they follow the others)
    real = vmap < len(src)
    dst[src[vmap[real]]] = out_uv[real].astype(np.float64) * np.array([atlas.width, atlas.height])
    seen[src[vmap[real]]] = True
    vi = isl.vert_island
    used = vi >= 0
    w = np.where(used, isl.outline.weight * seen, 0.0)
    rot = similarity_rotations(isl.uv, dst, w, np.where(used, vi, 0), isl.n)  # every island at once
    placed = np.zeros_like(isl.uv)
    k = vi[used]
    placed[used] = tpu * np.einsum("pij,pj->pi", rot.rotation[k], isl.uv[used] - rot.mean_src[k]) + rot.mean_dst[k]
    on = w > 0
    worst = float(np.abs(placed[on] - dst[on]).max()) if on.any() else 0.0
    for k in np.flatnonzero(rot.weight <= 0):  # zero UV area: covers no texel, xatlas ignores it; keep it inside the square
        verts = isl.verts[k]
        placed[verts] = _inside_square(isl.uv[verts] * tpu, dst[verts][seen[verts]], atlas)
    turned = np.flatnonzero((np.linalg.det(rot.rotation) < 0) & (rot.weight > 0)).tolist()
    return Placed(placed, worst, turned)


def _inside_square(px: np.ndarray, near: np.ndarray, atlas) -> np.ndarray:
    """``px`` translated to centre on ``near``'s centroid (or the atlas centre), then into the atlas."""
    size = np.array([atlas.width, atlas.height], np.float64)
    centre = near.mean(0) if len(near) else size / 2
    px = px - 0.5 * (px.min(0) + px.max(0)) + centre
    px -= np.minimum(px.min(0), 0)
    return px - np.maximum(px.max(0) - size, 0)


def attempt(isl: IslandSet, resolution, padding, tpu, options, mirror_tries: int = 0) -> np.ndarray | None:
    """Texel positions of a valid xatlas placement at ``tpu`` (with ``mirror_tries`` > 0:
    with no island mirrored), or None.

    xatlas's 90-degree chart "rotation" is a transpose: the island it turns comes back
    mirrored. Such islands are handed to xatlas mirrored on the next try, so that the
    transpose turns them the right way round (a transpose of a reflection is a rotation);
    an island xatlas then leaves alone is handed over unmirrored again. After
    ``mirror_tries`` xatlas calls the islands still mirrored are turned back inside the box
    xatlas gave them (:func:`texture.mirrors.turn_back`), if half the gutter remains.
    """
    unmirror = mirror_tries > 0
    flip = np.zeros(isl.n, bool)
    for _ in range(mirror_tries if unmirror else 1):
        atlas = xatlas_pack(*isl.outline_mirrored(flip), resolution, padding, tpu, options)
        if atlas.atlas_count != 1 or atlas.width > resolution or atlas.height > resolution:
            return None
        got = place(isl, atlas, tpu)
        if got.residual > MAX_FIT_RESIDUAL or not isl.inside(got.px, resolution):
            return None
        if not got.mirrored or not unmirror:
            px = got.px
            break
        flip[got.mirrored] ^= True
    else:
        px = turn_back(isl, got.px, got.mirrored, resolution, padding)
        if px is None:
            return None
    # xatlas keeps charts `padding` texels apart and each island moved <= residual: if two
    # moves cannot close the gutter, skip the (slow) rasterised check; pack_islands runs it
    # on the packing it returns anyway
    if 2 * got.residual + 1 >= padding and isl.verify(px / resolution, resolution)[0]:
        return None
    return px
