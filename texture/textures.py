"""Textures for a UV atlas: checkerboard, UV grid, baking from the input, gutter dilation, image I/O.

Images are float arrays ``(H, W, C)`` in [0, 1], row 0 at the *top* (v = 1); texel
``(r, c)`` has its centre at ``uv = ((c + 0.5) / W, 1 - (r + 0.5) / H)`` (see
``texture.raster``). Files are read and written with OpenImageIO: PNG as 8-bit,
EXR as 32-bit float.

Same-size checker squares on every method (exports and renders use these functions):
the checker is drawn in UV with ``n = s / L`` squares per UV unit, where
``s = sqrt(sum 3D area / sum |UV area|)`` is the mean 3D length per UV unit and ``L`` the
square's side on the surface (unit-ball frame). A square then covers ``L`` of surface
length on average, whatever the atlas's UV scale, so our atlas and xatlas show squares
of the same 3D size.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from scipy import ndimage

from mnacore.atomic import atomic_path
from mnacore.errors import InputError
from mnacore.triangles import triangle_areas
from mnacore.uvmesh import UVMesh, weld_ids

from .islands import unique_rows
from .raster import face_id_image

#: default checker square: 0.1 of the unit ball (20 squares across the diameter).
SQUARE_SIZE = 0.1
#: a generated texture must give each square at least this many texels (finer aliases).
MIN_TEXELS_PER_SQUARE = 4
#: a source texture smaller than this (texels a side) carries no image to bake
MIN_SOURCE_TEXELS = 4
#: default checker colours (light, dark), sRGB; square (0, 0) at the UV origin is the light one.
CHECKER_COLORS = ((0.92, 0.92, 0.92), (0.25, 0.32, 0.45))


def check_size(size) -> int:
    """Validate a texture size: a positive integer (int or digit string), at most 16384."""
    if isinstance(size, (int, np.integer)) and not isinstance(size, bool):
        value = int(size)
    elif isinstance(size, str) and size.strip().lstrip("+-").isdigit():
        value = int(size.strip())
    else:
        raise InputError(f"texture size must be a positive integer, got {size!r}")
    if value <= 0:
        raise InputError(f"texture size must be a positive integer, got {size!r}")
    if value > 16384:
        raise InputError(f"texture size {value} is too large (max 16384)")
    return value


def uv_length_scale(vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray) -> float:
    """``s = sqrt(A3 / Auv)``: mean 3D length per UV unit of a UV-mapped mesh.

    Example: a 2 x 2 square mapped onto the unit UV square has ``s = 2``.
    """
    a3 = triangle_areas(np.asarray(vertices, np.float64), faces).sum()
    auv = triangle_areas(np.asarray(uv, np.float64), faces).sum()
    if not (np.isfinite(auv) and auv > 0):
        raise InputError("the mesh's UV triangles have zero total area (or non-finite UVs)")
    if not (np.isfinite(a3) and a3 > 0):
        raise InputError("the mesh's triangles have zero total 3D area (or non-finite positions)")
    return float(np.sqrt(a3 / auv))


def squares_per_uv_unit(vertices, faces, uv, square_size: float = SQUARE_SIZE) -> float:
    """Checker frequency ``n = s / L`` (squares per UV unit) for squares of mean 3D side ``L``.

    A square spans ``1 / n`` UV units, i.e. ``s / n = L`` units of surface length. Example:
    a 2 x 2 square on the unit UV square (``s = 2``) with ``L = 0.25`` gets ``n = 8``.
    Positions in the frame ``L`` is given in (the unit-ball frame for ``--square-size``).
    """
    if not (isinstance(square_size, (int, float, np.floating)) and np.isfinite(square_size) and square_size > 0):
        raise InputError(f"checker square size must be a finite number > 0, got {square_size!r}")
    return uv_length_scale(vertices, faces, uv) / float(square_size)


def check_frequency(frequency: float, size: int) -> None:
    """Refuse a checker too fine for ``size`` texels: each square needs ``MIN_TEXELS_PER_SQUARE``."""
    if not (np.isfinite(frequency) and frequency > 0):
        raise InputError(f"checker frequency must be a finite number > 0, got {frequency}")
    if size / frequency < MIN_TEXELS_PER_SQUARE:
        raise InputError(f"a {size}-texel texture cannot hold {frequency:.1f} checker squares per UV unit "
                         f"(< {MIN_TEXELS_PER_SQUARE} texels each): use a larger texture size or a larger "
                         "square size")


def texel_centers(height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """(H, W) arrays ``u``, ``v`` of texel centres (row 0 = top = v near 1)."""
    u = (np.arange(width) + 0.5) / width
    v = 1.0 - (np.arange(height) + 0.5) / height
    return np.meshgrid(u, v, indexing="xy")


def checker_image(frequency: float, size: int = 2048, colors=CHECKER_COLORS) -> np.ndarray:
    """``(size, size, 3)`` checkerboard with ``frequency`` squares per UV unit, sRGB in [0, 1].

    Colour 0 where ``floor(n u) + floor(n v)`` is even (the square at the UV origin, the
    image's bottom-left corner). Example: ``n = 2`` on 8 texels gives 4-texel squares.
    """
    check_frequency(frequency, size)
    u, v = texel_centers(size, size)
    parity = (np.floor(frequency * u) + np.floor(frequency * v)).astype(np.int64) % 2
    return np.asarray(colors, np.float32)[parity]


def uv_grid_image(frequency: float, size: int = 2048) -> np.ndarray:
    """UV-grid texture ``(size, size, 3)`` sRGB: hue follows ``u``, brightness ``v``, dark cell edges.

    Cells have the checker's size; the hue ramp (red at u = 0 through the spectrum) and the
    lightness ramp in ``v`` make orientation and mirroring visible, the lines the cell edges.
    """
    check_frequency(frequency, size)
    from matplotlib.colors import hsv_to_rgb

    u, v = texel_centers(size, size)
    iu, iv = np.floor(frequency * u), np.floor(frequency * v)
    hue = (u * 0.8) % 1.0
    value = 0.55 + 0.3 * v + 0.1 * ((iu + iv) % 2)
    rgb = hsv_to_rgb(np.stack([hue, np.full_like(hue, 0.55), np.clip(value, 0, 1)], -1))
    fu, fv = frequency * u - iu, frequency * v - iv
    width = 0.06  # line half-width, in cells
    edge = (fu < width) | (fu > 1 - width) | (fv < width) | (fv > 1 - width)
    rgb[edge] = 0.1
    return rgb.astype(np.float32)


def dilate(image: np.ndarray, mask: np.ndarray, iterations: int) -> tuple[np.ndarray, np.ndarray]:
    """Grow ``image`` from ``mask`` into empty texels, ``iterations`` rings (mean of set 8-neighbours).

    Bilinear lookups near an island border then read the island's colours, not the
    background. Returns ``(image, grown mask)``.
    """
    img = np.where(mask[..., None], image, 0.0).astype(np.float64)
    m = mask.astype(np.float64)
    kernel = np.ones((3, 3))
    for _ in range(int(iterations)):
        if m.all():
            break
        count = ndimage.convolve(m, kernel, mode="constant")
        acc = np.stack([ndimage.convolve(img[..., c] * m, kernel, mode="constant") for c in range(img.shape[-1])], -1)
        grow = (m == 0) & (count > 0)
        img[grow] = acc[grow] / count[grow][:, None]
        m[grow] = 1.0
    return img, m > 0


def coverage_mask(mesh: UVMesh, size: int) -> np.ndarray:
    """(size, size) bool: texel centres inside some face of ``mesh`` (boundary inclusive)."""
    face, _ = face_id_image(mesh.uv[mesh.faces], size, size)
    return face >= 0


def bake(mesh_unit: UVMesh, source, size: int, padding: int = 8, background=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Transfer the colour of ``source`` (trimesh, same frame) onto the atlas of ``mesh_unit``.

    Each covered texel maps through its face's barycentrics to a 3D point, which is
    projected on ``source``; the colour there is the barycentric blend of the source's
    vertex colours, or a bilinear lookup of its texture through its own UVs. The result
    is dilated ``padding`` texels into the gutters. Returns (size, size, 3) float.
    """
    from .geometry import MeshProjector

    colors, uv_src, image = source_colors(source)
    face, bary = face_id_image(mesh_unit.uv[mesh_unit.faces], size, size)
    mask = face >= 0
    src_faces = np.asarray(source.faces)
    # a face that is a source triangle (an unwrap writes the input's faces) reads that
    # triangle at its own barycentrics, where the closest point can land on another (a
    # double-sided card's other side, two parts that touch); the others are projected
    match, perm = same_triangles(mesh_unit.vertices, mesh_unit.faces, np.asarray(source.vertices), src_faces)
    f, w = face[mask], bary[mask]
    src_face = match[f]
    src_bary = np.zeros_like(w)
    np.put_along_axis(src_bary, perm[f], w, axis=1)
    far = src_face < 0
    if far.any():
        pts = (w[far][:, :, None] * mesh_unit.vertices[mesh_unit.faces[f[far]]]).sum(1)
        proj = MeshProjector(np.asarray(source.vertices), src_faces).project(pts)
        src_face[far], src_bary[far] = proj.face, proj.bary
    corners = src_faces[src_face]
    if colors is not None:
        rgb = (src_bary[:, :, None] * colors[corners]).sum(1)
    else:
        st = (src_bary[:, :, None] * uv_src[corners]).sum(1)
        rgb = sample_bilinear(image, st)
    out = np.zeros((size, size, 3))
    out[:] = background
    out[mask] = rgb[:, :3]
    out, _ = dilate(out, mask, padding)
    return np.clip(out, 0.0, 1.0)


def _cyclic_keys(ids: np.ndarray) -> np.ndarray:
    """(F, 3) each triangle's point ids turned (cyclically: the winding kept) to start at its least."""
    k = np.argmin(ids, axis=1)
    return np.take_along_axis(ids, (k[:, None] + np.arange(3)) % 3, axis=1)


def _lookup(keys: np.ndarray, table: np.ndarray) -> np.ndarray:
    """(N,) the first row of ``table (M, 3)`` equal to each row of ``keys (N, 3)``, -1 where none is."""
    first, ids = unique_rows(np.vstack([table, keys]))
    row = first[ids[len(table):]]  # the table's rows come first: a key in it finds its first row there
    return np.where(row < len(table), row, -1)


def same_triangles(vertices: np.ndarray, faces: np.ndarray, src_vertices: np.ndarray,
                   src_faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """((F,) the source face whose triangle each face of ``(vertices, faces)`` is, -1 where
    none is; (F, 3) the source corner of each of its corners).

    Face ``f`` is first compared with source face ``f`` (an unwrap writes the input's faces
    in their order, a face wound against its neighbours turned: its corners in any order);
    the rest are looked up by their points in winding order, then reversed (a reader that
    regroups faces by material). Points are welded as the rest of mna welds them
    (:func:`mnacore.uvmesh.weld_ids`)."""
    faces, src_faces = np.asarray(faces, np.int64), np.asarray(src_faces, np.int64)
    ids = weld_ids(np.vstack([np.asarray(vertices, np.float64), np.asarray(src_vertices, np.float64)]))
    a, b = ids[:len(vertices)][faces], ids[len(vertices):][src_faces]
    src = np.full(len(faces), -1, np.int64)
    n = min(len(faces), len(src_faces))
    same = (np.sort(a[:n], axis=1) == np.sort(b[:n], axis=1)).all(1)
    src[:n][same] = np.flatnonzero(same)
    rest = np.flatnonzero(src < 0)
    if len(rest):
        table = _cyclic_keys(b)
        for keys in (_cyclic_keys(a[rest]), _cyclic_keys(a[rest][:, ::-1])):
            todo = src[rest] < 0
            src[rest[todo]] = _lookup(keys[todo], table)
    perm = np.zeros((len(faces), 3), np.int64)
    hit = src >= 0
    eq = a[hit][:, :, None] == b[src[hit]][:, None, :]  # (H, 3, 3): output corner k is source corner k'
    perm[hit] = eq.argmax(2)
    return src, perm


def source_colors(source):
    """(vertex colours (V, 3) float | None, uv (V, 2) | None, image | None) of a trimesh."""
    visual = source.visual
    if getattr(visual, "kind", None) == "texture" and getattr(visual, "uv", None) is not None:
        img = getattr(visual.material, "image", None) or getattr(visual.material, "baseColorTexture", None)
        if img is not None and min(img.size) < MIN_SOURCE_TEXELS:
            # trimesh stands a 2 x 2 placeholder in for a texture it could not find
            raise InputError(f"the input mesh's texture is a {img.size[0]} x {img.size[1]} placeholder: its material "
                             "file or image is missing (check the .mtl beside the .obj and the image it names)")
        if img is not None:
            arr = np.asarray(img.convert("RGB"), np.float64) / 255.0
            return None, np.asarray(visual.uv, np.float64), arr
    if getattr(visual, "kind", None) == "vertex":
        return np.asarray(visual.vertex_colors, np.float64)[:, :3] / 255.0, None, None
    raise InputError("the input mesh has neither vertex colours nor a texture to bake; use --texture checker or uvgrid")


def sample_bilinear(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear lookup of ``image (H, W, C)`` at ``uv (N, 2)`` (texel centres, clamp to edge)."""
    H, W = image.shape[:2]
    x = np.clip(uv[:, 0] * W - 0.5, 0, W - 1)
    y = np.clip((1.0 - uv[:, 1]) * H - 0.5, 0, H - 1)
    x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    x1, y1 = np.minimum(x0 + 1, W - 1), np.minimum(y0 + 1, H - 1)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    top = image[y0, x0] * (1 - fx) + image[y0, x1] * fx
    bottom = image[y1, x0] * (1 - fx) + image[y1, x1] * fx
    return top * (1 - fy) + bottom * fy


def write_image(path: str | os.PathLike, image: np.ndarray) -> None:
    """Write ``image (H, W, C)`` float [0,1] atomically: 8-bit for PNG/JPEG, float32 for EXR."""
    import OpenImageIO as oiio

    path = Path(path)
    image = np.ascontiguousarray(image)
    is_float = path.suffix.lower() in (".exr", ".hdr", ".tif", ".tiff")
    data = image.astype(np.float32) if is_float else np.round(np.clip(image, 0, 1) * 255).astype(np.uint8)
    fmt = oiio.FLOAT if is_float else oiio.UINT8
    with atomic_path(path) as tmp:
        out = oiio.ImageOutput.create(str(tmp))
        if out is None:
            raise InputError(f"cannot write image {path}: {oiio.geterror()}")
        spec = oiio.ImageSpec(data.shape[1], data.shape[0], data.shape[2], fmt)
        ok = out.open(str(tmp), spec) and out.write_image(data)
        out.close()
        if not ok:
            raise InputError(f"cannot write image {path}: {out.geterror()}")


def read_image(path: str | os.PathLike) -> np.ndarray:
    """Read an image as float (H, W, C) in [0, 1] (8-bit scaled by 1/255, float as stored)."""
    import OpenImageIO as oiio

    path = Path(path)
    if not path.is_file():
        raise InputError(f"image not found: {path}")
    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise InputError(f"cannot read image {path}: {oiio.geterror().strip() or 'unknown format'}")
    try:
        data = inp.read_image(oiio.FLOAT)
    finally:
        inp.close()
    if data is None or not isinstance(data, np.ndarray) or data.size == 0:
        raise InputError(f"cannot read image {path}: no pixel data")
    data = np.asarray(data, np.float64)
    return data if data.ndim == 3 else data[..., None]
