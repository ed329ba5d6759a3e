"""A triangle mesh with UVs, in one vocabulary for every stage of ``texture``.

``UVMesh`` stores *per-vertex* UVs: ``vertices (V, 3)``, ``faces (F, 3)`` and
``uv (V, 2)``. A UV seam is therefore two vertices at the same 3D position with
different UVs (what xatlas, glTF and trimesh's OBJ loader produce). Meshes whose UVs
come per corner (OBJ ``f v/vt``: separate ``uv_faces``) are converted by
:func:`from_corners`, which makes one vertex per distinct ``(v, vt)`` pair.

UV convention (same as OBJ/glTF-after-flip/trimesh): origin at the bottom-left of
the texture, ``u`` to the right, ``v`` up. Image row 0 is the *top* of the texture,
so texel ``(row r, col c)`` of an ``H x W`` image has its centre at
``uv = ((c + 0.5) / W, 1 - (r + 0.5) / H)``.
"""
from __future__ import annotations

import io
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError
from .frame import Normalization, check_coordinates, check_file_format, read_failure

#: relative tolerance (of the bounding-box diagonal) below which two positions are one point.
WELD_TOL = 1e-9


@dataclass(frozen=True)
class UVMesh:
    """Triangle mesh with per-vertex UVs (see module docstring for conventions).

    Attributes:
        vertices: (V, 3) float64 positions (frame of the caller: input or unit ball).
        faces: (F, 3) int64 vertex indices, counter-clockwise seen from outside.
        uv: (V, 2) float64 texture coordinates.
    """

    vertices: np.ndarray
    faces: np.ndarray
    uv: np.ndarray

    @property
    def n_faces(self) -> int:
        return int(len(self.faces))

    def transformed(self, norm: Normalization) -> "UVMesh":
        """The same mesh with positions mapped by ``norm.apply`` (UVs unchanged)."""
        return UVMesh(norm.apply(self.vertices), self.faces, self.uv)


def from_corners(vertices, faces, uv, uv_faces) -> UVMesh:
    """Per-corner UVs (``uv (T, 2)`` indexed by ``uv_faces (F, 3)``) -> per-vertex ``UVMesh``.

    One output vertex per distinct ``(faces[f, c], uv_faces[f, c])`` pair, so a 3D vertex
    on a seam becomes several vertices with the same position. Example: a quad
    ``v0..v3`` whose two triangles use disjoint UV corners becomes 6 vertices.
    """
    faces = np.asarray(faces, np.int64)
    uv_faces = np.asarray(uv_faces, np.int64)
    if faces.shape != uv_faces.shape:
        raise InputError(f"faces {faces.shape} and uv_faces {uv_faces.shape} differ in shape")
    pairs = np.stack([faces.ravel(), uv_faces.ravel()], 1)
    uniq, inverse = np.unique(pairs, axis=0, return_inverse=True)
    vertices = np.asarray(vertices, np.float64)[uniq[:, 0]]
    uv = np.asarray(uv, np.float64)[uniq[:, 1]]
    return make_uv_mesh(vertices, inverse.reshape(-1, 3), uv)


def validate_mesh(vertices, faces, name: str = "mesh") -> tuple[np.ndarray, np.ndarray]:
    """``(vertices float64 (V, 3), faces int64 (F, 3))``, or ``InputError`` naming what is wrong.

    Rejected: wrong shapes, no faces, non-integer or out-of-range indices, NaN or infinite
    positions of vertices that faces use (unused vertices are not looked at).
    """
    vertices = np.asarray(vertices, np.float64)
    faces = np.asarray(faces)
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise InputError(f"{name}: vertices must have shape (V, 3), got {vertices.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
        raise InputError(f"{name} has no triangle faces (faces shape {faces.shape})")
    if not np.issubdtype(faces.dtype, np.integer):
        raise InputError(f"{name}: faces must be integers, got {faces.dtype}")
    faces = faces.astype(np.int64)
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise InputError(f"{name}: face indices out of range [0, {len(vertices)})")
    if not np.isfinite(vertices[np.unique(faces)]).all():
        raise InputError(f"{name}: vertex positions contain NaN or inf")
    return vertices, faces


def make_uv_mesh(vertices, faces, uv, *, name: str = "mesh") -> UVMesh:
    """Validate and build a :class:`UVMesh`; raises ``InputError`` naming what is wrong.

    Rejected: what :func:`validate_mesh` rejects, UVs of the wrong shape or not finite,
    faces repeating a vertex.
    """
    if uv is None:
        raise InputError(f"{name} has no UVs (texture coordinates); UV-map it first, e.g. `mna uv`")
    vertices, faces = validate_mesh(vertices, faces, name)
    uv = np.asarray(uv, dtype=np.float64)
    if uv.shape != (len(vertices), 2):
        raise InputError(f"{name}: uv must have shape ({len(vertices)}, 2) (one per vertex), got {uv.shape}")
    if not np.isfinite(uv).all():
        raise InputError(f"{name}: UVs contain NaN or inf ({int((~np.isfinite(uv)).any(1).sum())} vertices)")
    repeated = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 0] == faces[:, 2])
    if repeated.any():
        raise InputError(f"{name}: {int(repeated.sum())} degenerate faces repeat a vertex "
                         f"(first: face {int(np.argmax(repeated))})")
    return UVMesh(vertices, faces, uv)


def _cloud_hint(path: Path) -> str:
    """What to say of a file with no faces: a point cloud (read as a mesh it is empty) is
    what `mna fit` takes, not a mesh to unwrap."""
    import trimesh

    try:
        cloud = trimesh.load(path, process=False)
    except Exception:  # unreadable as anything: nothing to add
        return ""
    n = len(cloud.vertices) if isinstance(cloud, trimesh.PointCloud) else 0
    return f" (a point cloud of {n} points: `mna fit` reconstructs it)" if n else ""


def read_mesh(path: str | os.PathLike, keep_vertex_order: bool = False):
    """Read a triangle mesh file with trimesh (no processing): ``trimesh.Trimesh``, or ``InputError``
    for a missing file, a wrong format (the first bytes), no faces or NaN / overflowing positions.

    ``keep_vertex_order``: an OBJ keeps its own ``v`` list and order (trimesh otherwise makes
    one vertex per distinct ``v/vt`` pair, which is what UV readers want), and its faces
    their order in the file; its texture visuals are then not read. trimesh splits an OBJ
    at every ``usemtl`` and joins the pieces again grouped (a sphere whose faces alternate
    between two materials every ten came back with its faces reordered, and the unwrap's
    face ``i`` was not the file's), so those lines are left out of what it reads here.
    """
    import trimesh

    path = Path(path)
    if not path.is_file():
        raise InputError(f"mesh file not found: {path}")
    check_file_format(path)
    source, kw = path, {}
    if keep_vertex_order and path.suffix.lower() == ".obj":  # read once, without its usemtl lines
        source = io.StringIO(re.sub(r"^\s*usemtl\b.*$", "", path.read_text(errors="replace"), flags=re.MULTILINE))
        kw = {"maintain_order": True, "file_type": "obj"}
    try:
        mesh = trimesh.load(source, force="mesh", process=False, **kw)
    except Exception as exc:  # trimesh raises many types on unreadable files
        raise InputError(read_failure(path, exc)) from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise InputError(f"{path} holds no triangle faces{_cloud_hint(path)}")
    check_coordinates(mesh.vertices[np.unique(mesh.faces)], path.name)
    return mesh


def weld_ids(vertices: np.ndarray, tol: float = WELD_TOL) -> np.ndarray:
    """(V,) id of the 3D point each vertex sits on: seam copies of one point share an id.

    Positions are compared after rounding to ``tol`` times the bounding-box diagonal.
    """
    vertices = np.asarray(vertices, np.float64)
    diag = float(np.linalg.norm(vertices.max(0) - vertices.min(0))) or 1.0
    key = np.round(vertices / (tol * diag)).astype(np.int64)
    _, ids = np.unique(key, axis=0, return_inverse=True)
    return ids.reshape(-1)


def load_uv_mesh(path: str | os.PathLike, *, require_uv: bool = True):
    """Read a mesh file (OBJ/GLB/PLY/OFF/...) with trimesh; returns ``(UVMesh | None, trimesh.Trimesh)``.

    The ``UVMesh`` is ``None`` when the file has no UVs and ``require_uv`` is False.
    """
    path = Path(path)
    mesh = read_mesh(path)
    uv = getattr(mesh.visual, "uv", None)
    if uv is None or len(uv) != len(mesh.vertices):
        if require_uv:
            raise InputError(f"{path.name} has no UVs (texture coordinates); UV-map it first, e.g. `mna uv`")
        return None, mesh
    return make_uv_mesh(mesh.vertices, mesh.faces, uv, name=path.name), mesh
