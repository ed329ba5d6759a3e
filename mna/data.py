"""Input surfaces: load a mesh or point cloud, validate it, normalise it to the unit ball, sample it.

A ``Surface`` holds the input in the **normalised** frame (``x_unit = (x - center) / scale``,
centre = bounding-box centre, max radius 1, DESIGN's metric frame) and remembers the
transform, so everything written goes back to the input frame with ``denormalize``.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from mnacore.errors import InputError
from mnacore.frame import Normalization, check_file_format, read_failure
from mnacore.triangles import consistent_winding, triangle_areas
from mnacore.uvmesh import weld_ids

MESH_EXTS = {".obj", ".ply", ".off", ".stl", ".glb", ".gltf"}
POINT_EXTS = {".xyz", ".npy", ".npz", ".txt"}
MIN_POINTS = 16


@dataclass
class Surface:
    """The target surface in the unit-ball frame: a mesh, or a point cloud when ``mesh`` is None."""

    points: np.ndarray  # (P, 3) float64: mesh vertices or the cloud's points, normalised
    mesh: trimesh.Trimesh | None  # normalised mesh (None for point clouds)
    normalization: Normalization
    path: str

    @property
    def is_mesh(self) -> bool:
        return self.mesh is not None

    @functools.cached_property
    def face_normals(self) -> np.ndarray | None:
        """(F, 3) unit face normals of the mesh, computed once (trimesh re-hashes the mesh on
        every access to its cache, which costs a fifth of a 1-chart step), each turned like
        its neighbours' where its face is wound against them (:func:`consistent_winding`):
        L_orient asks each chart to face one way, which scrambled normals cannot tell."""
        if self.mesh is None:
            return None
        faces = np.asarray(self.mesh.faces, np.int64)
        normals = np.array(self.mesh.face_normals, dtype=np.float64)
        normals[consistent_winding(weld_ids(self.mesh.vertices)[faces], triangle_areas(self.mesh.vertices, faces))] *= -1.0
        return normals

    def sample(self, count: int, rng: np.random.Generator) -> np.ndarray:
        """``count`` points on the surface: area-uniform on a mesh, a random subset of a cloud."""
        return self.sample_with_normals(count, rng)[0]

    def sample_with_normals(self, count: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray | None]:
        """Like :meth:`sample` (same draws), plus each point's unit face normal on a mesh (None on a cloud)."""
        pts, nrm, _ = self.sample_elements(count, rng)
        return pts, nrm

    @property
    def element_count(self) -> int:
        """What a draw picks from: faces of a mesh, points of a cloud."""
        return len(self.mesh.faces) if self.mesh is not None else len(self.points)

    def sample_elements(self, count: int, rng: np.random.Generator, weight: np.ndarray | None = None
                        ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
        """``count`` points, their normals (None on a cloud) and the element (face or point) each came from.

        ``weight`` (one per element, >= 0) replaces the default draw (area-uniform on a mesh,
        uniform over a cloud's points) by one proportional to ``area x weight`` (a mesh) or
        ``weight`` (a cloud); without it the draws are those of :meth:`sample`.
        """
        if self.mesh is not None:
            face_weight = None if weight is None else self.face_areas * weight
            pts, face = trimesh.sample.sample_surface(self.mesh, count, face_weight=face_weight,
                                                      seed=int(rng.integers(2**31 - 1)))
            return np.asarray(pts, dtype=np.float64), self.face_normals[face], np.asarray(face)
        replace = count > len(self.points)
        if weight is None:
            idx = rng.choice(len(self.points), size=count, replace=replace)
        else:
            idx = rng.choice(len(self.points), size=count, replace=True, p=weight / weight.sum())
        return self.points[idx], None, idx

    @functools.cached_property
    def face_areas(self) -> np.ndarray | None:
        """(F,) face areas in the unit-ball frame (computed once, like :attr:`face_normals`)."""
        return None if self.mesh is None else np.array(self.mesh.area_faces, dtype=np.float64)

    @functools.cached_property
    def element_centers(self) -> np.ndarray:
        """(E, 3): face centroids of a mesh, the points of a cloud (unit-ball frame)."""
        return self.points if self.mesh is None else np.array(self.mesh.triangles_center, dtype=np.float64)

    def area(self) -> float | None:
        return float(self.mesh.area) if self.mesh is not None else None


def load_surface(path: str | Path) -> Surface:
    """Load a mesh (.obj .ply .off .stl .glb) or point cloud (.ply without faces, .xyz, .npy/.npz)."""
    path = Path(path)
    if not path.exists():
        raise InputError(f"input file not found: {path}")
    if path.is_dir():
        raise InputError(f"input is a folder, expected a mesh or point-cloud file: {path}")
    ext = path.suffix.lower()
    if ext not in MESH_EXTS | POINT_EXTS:
        raise InputError(
            f"unknown input extension {ext or '(none)'!r} for {path.name}; "
            f"meshes: {' '.join(sorted(MESH_EXTS))}; point clouds: .ply .xyz .npy .npz"
        )
    if path.stat().st_size == 0:
        raise InputError(f"input file is empty: {path}")
    check_file_format(path)
    if ext in POINT_EXTS:
        points, faces = _read_points(path), None
    else:
        points, faces = _read_mesh(path)
    return make_surface(points, faces, str(path))


def make_surface(points: np.ndarray, faces: np.ndarray | None, path: str = "<memory>") -> Surface:
    """Validate raw geometry (input frame) and normalise it."""
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise InputError(f"expected points of shape (P, 3), got {points.shape} in {path}")
    # a mesh is sampled on its surface (any positive area will do: a cube has 8 vertices); a
    # cloud is all there is of the shape
    if faces is None and len(points) < MIN_POINTS:
        raise InputError(f"input has {len(points)} points; at least {MIN_POINTS} are needed: {path}")
    norm = Normalization.fit(points, f"input {path}")
    unit = norm.apply(points)
    mesh = None
    if faces is not None:
        faces = np.asarray(faces)
        if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
            raise InputError(f"mesh has no triangle faces: {path}")
        if faces.min() < 0 or faces.max() >= len(points):
            raise InputError(f"mesh faces index missing vertices: {path}")
        mesh = trimesh.Trimesh(unit, faces, process=False)
        if not mesh.area > 0:
            raise InputError(f"mesh has zero surface area: {path}")
    return Surface(unit, mesh, norm, path)


def _read_mesh(path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    try:
        loaded = trimesh.load(path, process=False)
        if isinstance(loaded, trimesh.Scene):
            loaded = loaded.to_geometry() if hasattr(loaded, "to_geometry") else loaded.dump(concatenate=True)
    except Exception as exc:  # trimesh raises many types on bad files
        raise InputError(read_failure(path, exc)) from None
    if isinstance(loaded, trimesh.PointCloud):
        if path.suffix.lower() == ".ply":
            return np.asarray(loaded.vertices), None  # a PLY without faces is a point cloud
        raise InputError(f"mesh has no faces: {path} (use .ply, .xyz, .npy or .npz for point clouds)")
    vertices = np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))))
    faces = np.asarray(getattr(loaded, "faces", np.zeros((0, 3), dtype=np.int64)))
    if len(vertices) == 0:
        raise InputError(f"no geometry found in {path}")
    if path.suffix.lower() == ".ply" and len(faces) == 0:
        return vertices, None  # a PLY without faces is a point cloud
    if len(faces) == 0:
        raise InputError(f"mesh has no faces: {path}")
    return vertices, faces


def _read_points(path: Path) -> np.ndarray:
    ext = path.suffix.lower()
    try:
        if ext == ".npy":
            arr = np.load(path, allow_pickle=False)
        elif ext == ".npz":
            with np.load(path, allow_pickle=False) as z:
                key = next((k for k in ("points", "pointcloud", "xyz", "vertices") if k in z), None)
                if key is None:
                    if len(z.files) != 1:
                        raise InputError(f"{path.name} has arrays {z.files}; expected one named 'points'")
                    key = z.files[0]
                arr = z[key]
        else:
            arr = np.loadtxt(path, ndmin=2)
    except InputError:
        raise
    except Exception as exc:
        raise InputError(f"cannot read {path.name}: {type(exc).__name__}") from None
    arr = np.asarray(arr, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] < 3:
        raise InputError(f"expected an (N, 3) array of points in {path.name}, got shape {arr.shape}")
    return arr[:, :3]
