"""Write a UV-mapped mesh with its texture: OBJ + MTL + PNG, and GLB with the texture embedded.

What every export carries, so it opens right in Blender and glTF viewers:

- positions and UVs rounded to float32 once, so the OBJ (written with 9 significant
  digits, which round-trip float32 exactly, at any scale) and the GLB (float32) hold the
  same numbers and measure identically; a mesh far from the origin for its size (a scan in
  map coordinates) is rounded relative to its centre instead (:func:`asset_origin`), which
  the GLB stores as its node's translation and the OBJ adds back (17 digits, exact);
- smooth shading normals (:mod:`texture.normals`): seam copies share a normal, vertices
  are split only where a crease runs through them;
- a PBR material: base colour = the texture, ``metallicFactor`` 0 (glTF's default is 1, a
  mirror-like metal), roughness ``ROUGHNESS``, ``doubleSided`` when the surface is open
  (its back faces are visible). The MTL says the same (``Pm``/``Pr``, read by Blender).

UV conventions: our UVs have v up (origin bottom-left of the image). OBJ stores them as
they are; glTF stores ``v' = 1 - v`` (origin top-left), which trimesh applies on export
and undoes on load, so reading either file back gives our UVs.

All files of one export are written under temporary names and renamed only after all
of them were written, so an interruption never leaves a half-written set.
"""
from __future__ import annotations

import contextlib
import io
import os
from pathlib import Path

import numpy as np

from mnacore.atomic import atomic_path
from mnacore.errors import InputError
from mnacore.frame import far_from_origin
from mnacore.uvmesh import UVMesh, weld_ids

from .normals import Shading, open_surface, shading_normals

MATERIAL = "material_0"
#: the glTF sampler of every atlas texture: clamped to the edge, filtered trilinearly. The
#: packer keeps its gutters between islands, not along the atlas's border (the nearest island
#: lies 0.25-3.1 texels from it on the 19 benchmark meshes at padding 8), and glTF's default
#: wrap, REPEAT, would blend the opposite edge of the atlas into them wherever a viewer
#: filters or mip-maps; nothing of an atlas lies outside [0, 1], so clamping loses nothing.
ATLAS_SAMPLER = {"magFilter": 9729, "minFilter": 9987, "wrapS": 33071, "wrapT": 33071}
#: a matte, plastic-like finish: the checker reads the same from every view.
ROUGHNESS = 0.8


def asset_origin(vertices: np.ndarray) -> np.ndarray:
    """(3,) point the exported float32 positions are measured from: the origin, or the
    bounding-box centre where the mesh is far from the origin for its size
    (:func:`mnacore.frame.far_from_origin`)."""
    lo, hi = vertices.min(0), vertices.max(0)
    if not far_from_origin(float(np.abs(vertices).max()), float(np.max(hi - lo))):
        return np.zeros(3)
    return lo / 2 + hi / 2


def asset_mesh(mesh: UVMesh, origin: np.ndarray | None = None) -> UVMesh:
    """``mesh`` with positions and UVs rounded to what the GLB stores (float32 positions
    relative to ``origin``, default 0; float32 UVs, v flipped).

    Raises ``InputError`` when a coordinate exceeds float32's range (about 3.4e38).
    """
    origin = np.zeros(3) if origin is None else origin
    local = mesh.vertices - origin
    limit = float(np.finfo(np.float32).max)
    if np.abs(local).max() > limit or np.abs(mesh.uv).max() > limit:
        raise InputError("coordinates exceed the float32 range glTF stores (about 3.4e38): scale the mesh down")
    # UVs on multiples of 2^-24: then v and glTF's 1 - v are both exact in float32 (in [0, 1])
    uv = (np.round(mesh.uv * 2.0 ** 24) / 2.0 ** 24).astype(np.float32).astype(np.float64)
    # origin + a float32 is exact in float64 unless the extent is below 2^-29 of the offset
    return UVMesh(origin + local.astype(np.float32).astype(np.float64), mesh.faces, uv)


def shading(mesh: UVMesh, weld: np.ndarray | None = None) -> Shading:
    """Shading normals of ``mesh`` (see :mod:`texture.normals`); ``weld``: its ``weld_ids`` if known."""
    return shading_normals(mesh.vertices, mesh.faces, weld_ids(mesh.vertices) if weld is None else weld)


def _fmt_rows(prefix: str, rows: np.ndarray, fmt: str = "%.9g") -> str:
    """One ``prefix`` line per row; ``%.9g`` keeps 9 significant digits (exact for float32)."""
    if len(rows) == 0:
        return ""
    buf = io.StringIO()
    row_fmt = fmt if "%" in fmt and fmt.count("%") > 1 else " ".join([fmt] * rows.shape[1])
    np.savetxt(buf, rows, fmt=f"{prefix} {row_fmt}")
    return buf.getvalue()


def obj_text(mesh: UVMesh, mtl_name: str, shade: Shading | None = None, exact: bool = False) -> str:
    """OBJ text: ``mtllib``/``usemtl``, ``v``, ``vt``, ``vn`` (9 significant digits), ``f v/vt/vn``.

    ``exact``: positions with 17 digits (float64 round-trip), for a mesh rounded relative
    to an origin (:func:`asset_mesh`): its coordinates are float64 sums, not float32s.

    Positions and UVs are indexed by ``mesh``'s vertices (seam copies stay separate ``v``
    lines, so every face keeps its own corners); normals by the shading's output vertices.
    """
    shade = shade or shading(mesh)
    f = mesh.faces + 1
    n = shade.faces + 1
    corners = np.stack([f, f, n], -1).reshape(len(f), 9)
    face_lines = _fmt_rows("f", corners, "%d/%d/%d %d/%d/%d %d/%d/%d")
    return (f"# mna export: {len(mesh.vertices)} vertices, {len(mesh.faces)} faces\n"
            f"mtllib {mtl_name}\nusemtl {MATERIAL}\n"
            + _fmt_rows("v", mesh.vertices, "%.17g" if exact else "%.9g") + _fmt_rows("vt", mesh.uv)
            + _fmt_rows("vn", shade.normals.astype(np.float32)) + face_lines)


def mtl_text(texture_name: str) -> str:
    """The material for OBJ readers: white diffuse times the texture, no specular, metallic 0."""
    return (f"newmtl {MATERIAL}\nKa 0.0 0.0 0.0\nKd 1.0 1.0 1.0\nKs 0.0 0.0 0.0\nNs 10.0\nillum 1\n"
            f"Pr {ROUGHNESS}\nPm 0.0\nmap_Kd {texture_name}\n")


def glb_bytes(mesh: UVMesh, image: np.ndarray, shade: Shading | None = None, double_sided: bool | None = None,
              origin: np.ndarray | None = None) -> bytes:
    """glTF binary: the mesh on the shading's vertices, normals, PBR material with the texture as PNG.
    ``origin``: the node's translation, positions stored relative to it (:func:`asset_origin`)."""
    import PIL.Image
    import trimesh

    shade = shade or shading(mesh)
    if double_sided is None:
        double_sided = open_surface(mesh.faces, weld_ids(mesh.vertices))
    origin = np.zeros(3) if origin is None else origin
    tm = trimesh.Trimesh((mesh.vertices - origin)[shade.source], shade.faces, process=False, validate=False)
    pil = PIL.Image.fromarray(np.round(np.clip(image[..., :3], 0, 1) * 255).astype(np.uint8))
    material = trimesh.visual.material.PBRMaterial(
        name=MATERIAL, baseColorTexture=pil, baseColorFactor=[255, 255, 255, 255],
        metallicFactor=0.0, roughnessFactor=ROUGHNESS, doubleSided=bool(double_sided))
    tm.visual = trimesh.visual.TextureVisuals(uv=mesh.uv[shade.source], material=material)
    tm.vertex_normals = shade.normals
    scene = trimesh.Scene()
    scene.add_geometry(tm, transform=trimesh.transformations.translation_matrix(origin) if origin.any() else None)
    return trimesh.exchange.gltf.export_glb(scene, include_normals=True, buffer_postprocessor=_own_views,
                                            tree_postprocessor=_finish_tree)


def _finish_tree(tree: dict) -> None:
    """What trimesh's glTF tree lacks (its ``tree_postprocessor`` hook, once the buffer views
    exist): the atlas sampler (:data:`ATLAS_SAMPLER`) on every texture, and each vertex or
    index view's ``target`` (the validator hints at every view without one)."""
    if tree.get("textures"):
        tree["samplers"] = [dict(ATLAS_SAMPLER)]
        for tex in tree["textures"]:
            tex["sampler"] = 0
    views, accessors = tree.get("bufferViews", []), tree.get("accessors", [])
    for mesh in tree.get("meshes", []):
        for prim in mesh.get("primitives", []):
            used = [(a, 34962) for a in prim.get("attributes", {}).values()]  # ARRAY_BUFFER
            if "indices" in prim:
                used.append((prim["indices"], 34963))  # ELEMENT_ARRAY_BUFFER
            for acc, target in used:
                view = accessors[acc].get("bufferView")
                if view is not None:
                    views[view]["target"] = target


def _own_views(buffer_items, tree: dict) -> None:
    """Give every accessor its own bufferView (trimesh's ``buffer_postprocessor`` hook).

    trimesh stores equal bytes once, so accessors with equal data share a view: on a mesh
    whose vertices lie on the unit sphere the normals can equal the positions to the bit (an
    icosahedron's do), and a view shared by two vertex attributes needs a ``byteStride``
    the validator reports as missing (MESH_PRIMITIVE_ACCESSOR_WITHOUT_BYTESTRIDE, an error).
    """
    seen: set[int] = set()
    for blob in tree["accessors"].values():
        view = blob.get("bufferView")
        if view is None:
            continue
        if view in seen:
            key = ("own view", len(buffer_items))
            buffer_items[key] = list(buffer_items.values())[view]
            blob["bufferView"] = buffer_items.index(key)
        seen.add(blob["bufferView"])


def export_textured(folder: str | os.PathLike, mesh: UVMesh, image: np.ndarray, stem: str = "mesh") -> dict:
    """Write ``stem.obj``, ``stem.mtl``, ``stem_texture.png`` and ``stem.glb`` into ``folder``.

    ``mesh`` is in the frame the files should have (the input's); ``image`` (H, W, 3) float.
    Returns the written paths by kind.
    """
    from .textures import write_image

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = {"obj": folder / f"{stem}.obj", "mtl": folder / f"{stem}.mtl",
             "texture": folder / f"{stem}_texture.png", "glb": folder / f"{stem}.glb"}
    origin = asset_origin(mesh.vertices)
    mesh = asset_mesh(mesh, origin)
    weld = weld_ids(mesh.vertices)  # once, for the normals and for the open-surface test
    shade = shading(mesh, weld)
    obj = obj_text(mesh, paths["mtl"].name, shade, exact=bool(origin.any()))
    glb = glb_bytes(mesh, image, shade, open_surface(mesh.faces, weld), origin)
    with contextlib.ExitStack() as stack:
        tmp = {k: stack.enter_context(atomic_path(p)) for k, p in paths.items() if k != "texture"}
        tmp["obj"].write_text(obj)
        tmp["mtl"].write_text(mtl_text(paths["texture"].name))
        tmp["glb"].write_bytes(glb)
        write_image(paths["texture"], image)  # itself atomic; renamed before the others
    return {k: str(p) for k, p in paths.items()}


def read_back(path: str | os.PathLike) -> UVMesh:
    """Load an exported OBJ/GLB with trimesh (no processing) as a :class:`UVMesh`."""
    from mnacore.uvmesh import load_uv_mesh

    mesh, _ = load_uv_mesh(path)
    return mesh
