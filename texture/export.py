"""Write a UV-mapped mesh with its texture: OBJ + MTL + PNG, and GLB with the texture embedded.

Meshes are built with ``trimesh.Trimesh(..., process=False)`` so the split vertices of
UV seams survive. UV conventions: our UVs have v up (origin bottom-left of the image).
OBJ stores them as they are; glTF stores ``v' = 1 - v`` (origin top-left), which trimesh
applies on export and undoes on load, so reading either file back with trimesh gives
our UVs (to float32 precision for GLB, 8 decimals for OBJ).

All files of one export are written under temporary names and renamed only after all
of them were written, so an interruption never leaves a half-written set.
"""
from __future__ import annotations

import contextlib
import os
from pathlib import Path

import numpy as np

from mna.atomic import atomic_path

from .uvmesh import UVMesh

MATERIAL = "material_0"


def _trimesh(mesh: UVMesh, image: np.ndarray | None):
    import PIL.Image
    import trimesh

    tm = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False, validate=False)
    pil = None
    if image is not None:
        pil = PIL.Image.fromarray(np.round(np.clip(image[..., :3], 0, 1) * 255).astype(np.uint8))
    material = trimesh.visual.material.SimpleMaterial(image=pil, diffuse=[255, 255, 255, 255],
                                                      ambient=[255, 255, 255, 255], specular=[0, 0, 0, 255])
    material.name = MATERIAL
    tm.visual = trimesh.visual.TextureVisuals(uv=mesh.uv, material=material)
    return tm


def obj_text(mesh: UVMesh, mtl_name: str) -> str:
    """OBJ text (positions, UVs, faces, ``mtllib``/``usemtl``) written by trimesh."""
    import trimesh

    text, _ = trimesh.exchange.obj.export_obj(_trimesh(mesh, None), include_normals=False, include_color=False,
                                              include_texture=True, return_texture=True, mtl_name=mtl_name,
                                              digits=10)
    return text


def mtl_text(texture_name: str) -> str:
    return (f"newmtl {MATERIAL}\nKa 1.0 1.0 1.0\nKd 1.0 1.0 1.0\nKs 0.0 0.0 0.0\nNs 1.0\nillum 1\n"
            f"map_Kd {texture_name}\n")


def glb_bytes(mesh: UVMesh, image: np.ndarray) -> bytes:
    """glTF binary with the texture embedded as PNG (trimesh)."""
    import trimesh

    return trimesh.exchange.gltf.export_glb(trimesh.Scene(_trimesh(mesh, image)), include_normals=False)


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
    obj = obj_text(mesh, paths["mtl"].name)
    glb = glb_bytes(mesh, image)
    with contextlib.ExitStack() as stack:
        tmp = {k: stack.enter_context(atomic_path(p)) for k, p in paths.items() if k != "texture"}
        tmp["obj"].write_text(obj)
        tmp["mtl"].write_text(mtl_text(paths["texture"].name))
        tmp["glb"].write_bytes(glb)
        write_image(paths["texture"], image)  # itself atomic; renamed before the others
    return {k: str(p) for k, p in paths.items()}


def read_back(path: str | os.PathLike) -> UVMesh:
    """Load an exported OBJ/GLB with trimesh (no processing) as a :class:`UVMesh`."""
    from .uvmesh import load_uv_mesh

    mesh, _ = load_uv_mesh(path)
    return mesh
