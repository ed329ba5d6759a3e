"""Pack UV islands into [0,1]^2 with xatlas's packer, at one texel density for all islands.

xatlas (``Atlas.add_uv_mesh`` + ``generate``) places the islands; each island gets its
own material id (``face_materials``) so islands that share UV positions (charts are all
parametrised over [-1,1]^2) are never merged. xatlas may rotate or transpose an island
and stretches it by up to one texel to align its extents to whole texels; we undo the
stretch by fitting, per island, the rigid motion (rotation or reflection + translation)
that maps its input UVs onto xatlas's at xatlas's single scale ``texels_per_unit``, and
apply that exactly. So every island keeps its shape and all share one scale.

The atlas is square: xatlas first packs at a guessed scale into an unbounded atlas,
the scale is set so that atlas's larger side matches ``resolution``, and the islands are
packed again into the fixed ``resolution^2`` square, shrinking by 3 % until they fit and
then growing by 3 % while they still fit (at most ``max_grow`` times).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .raster import iter_hits

#: largest allowed mismatch (texels) between xatlas's placement and the rigid fit.
MAX_FIT_RESIDUAL = 2.0
#: faces below this fraction of the median UV area are ignored when fitting the placement.
SOLID_FACE_REL = 1e-2
#: scale steps of the fixed-square search.
SHRINK, GROW = 0.97, 1.03


@dataclass
class Packing:
    """Result of :func:`pack_islands`.

    Attributes:
        uv: (V, 2) packed UVs in [0,1]^2 (same vertex order as the input).
        scale: packed UV per input UV unit (one value for every island).
        utilization: fraction of [0,1]^2 covered (texel centres at ``resolution``).
        overlap_texels: texels covered by two different islands (0 when valid).
        seconds: packing time.
    """

    uv: np.ndarray
    scale: float
    texels_per_unit: float
    resolution: int
    padding: int
    utilization: float
    overlap_texels: int
    seconds: float
    attempts: int


def _xatlas_pack(uv, faces, island, resolution, padding, tpu):
    import xatlas

    atlas = xatlas.Atlas()
    atlas.add_uv_mesh(uv.astype(np.float32), faces.astype(np.uint32), island.astype(np.uint32).reshape(-1, 1))
    po = xatlas.PackOptions()
    po.resolution = int(resolution)
    po.padding = int(padding)
    po.texels_per_unit = float(tpu)
    po.bilinear = True
    po.bruteForce = False
    atlas.generate(pack_options=po)
    return atlas


def _rigid_fit(src: np.ndarray, dst: np.ndarray, scale: float):
    """Orthogonal ``R`` (2x2, det +-1) and ``t`` minimising ``|scale * src @ R.T + t - dst|``."""
    cs, cd = src.mean(0), dst.mean(0)
    H = (src - cs).T @ (dst - cd)
    U, _, Vt = np.linalg.svd(H)
    R = (U @ Vt).T
    t = cd - scale * cs @ R.T
    return R, t


def pack_islands(uv: np.ndarray, faces: np.ndarray, island: np.ndarray, *, resolution: int = 2048,
                 padding: int = 8, max_attempts: int = 14, max_grow: int = 4) -> Packing:
    """Pack islands ``island (F,)`` of the UV mesh ``(uv (V,2), faces (F,3))``; see module docstring.

    Every vertex must belong to faces of a single island (true for split-vertex meshes).
    """
    t0 = time.perf_counter()
    uv = np.asarray(uv, np.float64)
    faces = np.asarray(faces, np.int64)
    island = np.asarray(island, np.int64)
    n_isl = int(island.max()) + 1
    vert_island = np.full(len(uv), -1)
    vert_island[faces.ravel()] = np.repeat(island, 3)
    tri = uv[faces]
    face_area = 0.5 * np.abs((tri[:, 1, 0] - tri[:, 0, 0]) * (tri[:, 2, 1] - tri[:, 0, 1])
                             - (tri[:, 1, 1] - tri[:, 0, 1]) * (tri[:, 2, 0] - tri[:, 0, 0]))
    uv_area = face_area.sum()
    # 1) let the atlas grow freely at a guess of the scale, 2) rescale so its larger side
    # fits the resolution, 3) pack into the fixed square, shrinking 3 % until it fits
    tpu = resolution * np.sqrt(0.6 / uv_area)
    free = _xatlas_pack(uv, faces, island, 0, padding, tpu)
    tpu *= (resolution - 1) / max(free.width, free.height, 1)
    best, attempts = None, 1
    while attempts < max_attempts:
        attempts += 1
        atlas = _xatlas_pack(uv, faces, island, resolution, padding, tpu)
        fits = atlas.atlas_count == 1 and atlas.width <= resolution and atlas.height <= resolution
        if fits:
            best = (atlas, tpu)
        elif best is not None:
            break  # grew past the limit: keep the last fit
        # shrink until it fits, then grow while it still fits (the square packs tighter than the free atlas)
        tpu *= GROW if fits else SHRINK
        if fits and attempts >= max_grow + 2:
            break
    if best is None:
        raise RuntimeError(f"xatlas could not pack {n_isl} islands into one {resolution}^2 atlas")
    atlas, tpu = best
    vmap, idx, out_uv = atlas[0]
    px = out_uv.astype(np.float64) * np.array([atlas.width, atlas.height])  # xatlas normalises by w, h
    # output vertex -> input vertex; islands' vertices are never shared, so each input vertex has one copy
    packed = np.zeros_like(uv)
    out_faces = idx.reshape(-1, 3)
    # xatlas skips near-zero-area faces and leaves their vertices unplaced: fit on the rest
    solid = face_area > SOLID_FACE_REL * np.median(face_area)
    for i in range(n_isl):
        out_v = np.unique(out_faces[(island == i) & solid])
        if len(out_v) < 3:
            out_v = np.unique(out_faces[island == i])
        src = uv[vmap[out_v]]
        R, t = _rigid_fit(src, px[out_v], tpu)
        residual = float(np.abs(tpu * src @ R.T + t - px[out_v]).max())
        if residual > MAX_FIT_RESIDUAL:
            raise RuntimeError(f"packed island {i} is not a rigid copy of its input (residual {residual:.2f} texels)")
        verts = np.flatnonzero(vert_island == i)
        packed[verts] = tpu * uv[verts] @ R.T + t
    packed /= resolution
    overlap, util = verify_packing(packed, faces, island, resolution)
    if overlap:
        raise RuntimeError(f"packed islands overlap on {overlap} texels")
    if packed.min() < 0 or packed.max() > 1:
        raise RuntimeError("packed UVs leave [0,1]^2")
    return Packing(packed, tpu / resolution, tpu, resolution, padding, util, overlap,
                   time.perf_counter() - t0, attempts)


def verify_packing(uv: np.ndarray, faces: np.ndarray, island: np.ndarray, resolution: int) -> tuple[int, float]:
    """(texels hit by two different islands, covered fraction of [0,1]^2) at ``resolution``."""
    owner = np.full(resolution * resolution, -1, np.int64)
    clash = np.zeros(resolution * resolution, bool)
    for h in iter_hits(uv[faces], resolution, resolution, strict=True):
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
