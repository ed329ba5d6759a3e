"""UV-mapped meshes for rendering: load (OBJ/PLY/GLB/OFF via trimesh), find the texture, write PLY.

A ``UVMesh`` holds per-vertex UVs (vertices are split at UV seams, as trimesh does
when loading an OBJ), so ``(vertices, faces, uv)`` is everything a renderer needs.
UVs follow the OBJ convention (``v`` up, ``(0, 0)`` at the image's bottom-left).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from dataclasses import replace as dataclass_replace
from pathlib import Path

import numpy as np

from mnacore.atomic import atomic_path
from mnacore.triangles import face_normals


@dataclass(frozen=True)
class UVMesh:
    vertices: np.ndarray
    """(V, 3) float64."""
    faces: np.ndarray
    """(F, 3) int64, counter-clockwise seen from outside."""
    uv: np.ndarray | None
    """(V, 2) float64 per-vertex UVs, or None for a mesh without UVs."""
    texture: Path | None = None
    """image file of the mesh's own texture (``map_Kd`` of the OBJ's MTL), if any."""
    name: str = "mesh"


def _mtl_texture(obj_path: Path) -> Path | None:
    """The ``map_Kd`` image named by the first ``mtllib`` of an OBJ, if both files exist."""
    text = obj_path.read_text(errors="replace")
    m = re.search(r"^\s*mtllib\s+(.+?)\s*$", text, re.MULTILINE)
    if not m:
        return None
    mtl = obj_path.parent / m.group(1)
    if not mtl.is_file():
        return None
    k = re.search(r"^\s*map_Kd\s+(?:-\S+\s+\S+\s+)*(.+?)\s*$", mtl.read_text(errors="replace"), re.MULTILINE)
    return (mtl.parent / k.group(1)) if k else None


def load_uv_mesh(path: str | Path) -> UVMesh:
    """Load a triangle mesh with (optional) per-vertex UVs and its texture file, if named."""
    from mnacore.uvmesh import read_mesh

    path = Path(path)
    mesh = read_mesh(path)
    uv = getattr(mesh.visual, "uv", None)
    if uv is not None and len(uv) != len(mesh.vertices):
        uv = None
    if uv is not None and not np.isfinite(uv[np.unique(mesh.faces)]).all():
        bad = int((~np.isfinite(np.asarray(uv))).any(1).sum())
        raise ValueError(f"{path.name}: UVs contain NaN or inf ({bad} vertices)")
    texture = _mtl_texture(path) if path.suffix.lower() == ".obj" else None
    return UVMesh(np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64),
                  None if uv is None else np.asarray(uv, np.float64), texture, path.stem)


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(V, 3) area-weighted vertex normals, averaged across UV seams.

    Vertices at the same position (split at seams) share one normal, so the shading is
    smooth across seams and the seams are invisible in renders.
    """
    v = np.asarray(vertices, np.float64)
    _, weld = np.unique(np.round(v, 9), axis=0, return_inverse=True)
    weld = weld.reshape(-1)
    fn = face_normals(v, faces, unit=False)
    acc = np.zeros((weld.max() + 1, 3))
    for k in range(3):
        np.add.at(acc, weld[faces[:, k]], fn)
    n = acc[weld]
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return n / np.where(norm > 0, norm, 1.0)


def reversed_twins(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F,) bool: faces with a copy wound the other way on the same three points (a
    double-sided surface, as some exporters write one): a face whose reversal repeats one of
    the faces (:func:`texture.meshprep.copied_faces` over the faces, then them reversed)."""
    from mnacore.uvmesh import weld_ids
    from texture.meshprep import copied_faces

    w = weld_ids(vertices)[faces]
    first = copied_faces(np.vstack([w, w[:, ::-1]]))[len(w):]
    return (first >= 0) & (first < len(w))  # the first repeat is a face, not another reversal


def double_sided_render_mesh(mesh: UVMesh, twins: np.ndarray, gap: float) -> tuple[UVMesh, np.ndarray]:
    """(every face on three vertices of its own, (3F, 3) normals) for rendering a mesh whose
    ``twins`` (:func:`reversed_twins`) lie on each other.

    The two sides of a double-sided surface occupy the same place: a ray hits either, so a
    render showed the far side's texture (and, with normals averaged across both sides,
    which cancel, black) in a random half of the pixels. Each twin face is moved ``gap``
    along its own normal, so the side that faces the camera is the nearer one, and each
    corner's normal is averaged only over the faces on its side at that point (those whose
    normals agree with the corner's face), not across the two sides."""
    v = np.asarray(mesh.vertices, np.float64)
    f = mesh.faces
    flat = unshare(mesh)
    fn = face_normals(v, f, unit=False)
    unit = fn / np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)
    from mnacore.uvmesh import weld_ids

    point = weld_ids(v)[f].reshape(-1)  # (3F,) point of each corner (the project's weld)
    corner_face = np.repeat(np.arange(len(f)), 3)
    # a corner's normal: the face normals (area-weighted) at its point that agree with its own
    # face's, summed over the faces at that point: one pass per face of the largest fan
    order = np.argsort(point, kind="stable")
    starts = np.r_[0, np.flatnonzero(np.diff(point[order])) + 1]
    normals = np.zeros((len(point), 3))
    for s, e in zip(starts, np.r_[starts[1:], len(order)]):
        c = order[s:e]
        n_at = fn[corner_face[c]]
        agree = (unit[corner_face[c]] @ unit[corner_face[c]].T) > 0
        normals[c] = agree.astype(float) @ n_at
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
    shift = np.repeat(np.where(twins[:, None], gap * unit, 0.0), 3, axis=0)
    return dataclass_replace(flat, vertices=flat.vertices + shift), normals


def unshare(mesh: UVMesh) -> UVMesh:
    """Give every face its own three vertices (for flat per-face colours)."""
    idx = mesh.faces.reshape(-1)
    faces = np.arange(len(idx), dtype=np.int64).reshape(-1, 3)
    uv = None if mesh.uv is None else mesh.uv[idx]
    return UVMesh(mesh.vertices[idx], faces, uv, mesh.texture, mesh.name)


def write_ply(path: str | Path, vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray | None = None,
              normals: np.ndarray | None = None, colors: np.ndarray | None = None) -> None:
    """Binary little-endian PLY that Mitsuba and trimesh read.

    ``uv`` (V, 2) in OBJ convention is written flipped (``v_ply = 1 - v``) because
    Mitsuba's PLY loader, unlike its OBJ loader, takes ``v`` as image rows from the top.
    ``colors`` (V, 3) linear RGB become Mitsuba's ``vertex_color`` attribute.
    """
    v = np.asarray(vertices, np.float32)
    cols, props = [v], ["x", "y", "z"]
    if normals is not None:
        cols.append(np.asarray(normals, np.float32))
        props += ["nx", "ny", "nz"]
    if uv is not None:
        uvf = np.asarray(uv, np.float32).copy()
        uvf[:, 1] = 1.0 - uvf[:, 1]
        cols.append(uvf)
        props += ["u", "v"]
    if colors is not None:
        cols.append(np.asarray(colors, np.float32))
        props += ["r", "g", "b"]
    data = np.ascontiguousarray(np.concatenate(cols, 1), dtype="<f4")
    f = np.zeros(len(faces), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    f["n"], f["i"] = 3, np.asarray(faces)
    header = ["ply", "format binary_little_endian 1.0", "comment written by mna render",
              f"element vertex {len(v)}", *[f"property float {p}" for p in props],
              f"element face {len(f)}", "property list uchar int vertex_indices", "end_header", ""]
    with atomic_path(path) as tmp:
        tmp.write_bytes("\n".join(header).encode() + data.tobytes() + f.tobytes())
