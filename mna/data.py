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

from mna.errors import InputError

MESH_EXTS = {".obj", ".ply", ".off", ".stl", ".glb", ".gltf"}
POINT_EXTS = {".xyz", ".npy", ".npz", ".txt"}
#: below this extent *relative to the coordinates' magnitude* the geometry is one point: its
#: size is then lost in the float64 rounding of the positions themselves (eps 2.2e-16 with room
#: to spare). Relative, so a shape at 1e-30 or at 1e200 units normalises like one at 1.
REL_MIN_EXTENT = 1e-12
MIN_POINTS = 16


#: the first bytes of binary or self-describing formats: a file renamed to the wrong
#: extension (a text file called .ply) is named as such instead of failing deep in a parser
MAGIC = {".ply": b"ply", ".glb": b"glTF", ".npy": b"\x93NUMPY", ".npz": b"PK"}


def check_file_format(path: Path) -> None:
    """Raise ``InputError`` when ``path``'s first bytes do not match its extension (see ``MAGIC``)."""
    magic = MAGIC.get(path.suffix.lower())
    if magic is None:
        return
    with open(path, "rb") as fh:
        head = fh.read(len(magic))
    if head != magic:
        kind = path.suffix.lower().lstrip(".").upper()
        raise InputError(f"cannot read {path.name}: not a {kind} file (it does not start with {magic!r}); "
                         f"is the extension right?")


def check_coordinates(points: np.ndarray, where: str) -> None:
    """Raise ``InputError`` for NaN coordinates, or "coordinates overflow" for infinite ones."""
    points = np.asarray(points)
    if np.isnan(points).any():
        n = int(np.isnan(points.reshape(len(points), -1)).any(1).sum())
        raise InputError(f"{where} has NaN coordinates ({n} point(s))")
    if not np.isfinite(points).all():
        raise InputError(f"{where}: coordinates overflow (infinite values after reading)")


def unit_ball(points: np.ndarray, where: str = "input") -> tuple[np.ndarray, float]:
    """``(center, scale)`` of the unit-ball frame: bounding-box centre, max distance to it.

    Overflow-safe for any finite float64 input: the centre is ``lo/2 + hi/2`` (``lo + hi`` can
    overflow) and the radius is taken of ``d / max|d|`` (squaring 1e200 overflows, 1e-200
    underflows). Example: the points ``(0,0,0)`` and ``(2,0,0)`` give ``((1,0,0), 1.0)``.

    Raises ``InputError``: NaN coordinates; "coordinates overflow" for infinite ones (e.g.
    ``1e400`` in a text file) or an extent beyond float64; "zero extent" when the extent is
    below ``REL_MIN_EXTENT`` of the coordinates' magnitude (all points coincide).
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(points) == 0:
        raise InputError(f"{where} has no points")
    check_coordinates(points, where)
    lo, hi = points.min(0), points.max(0)
    center = lo / 2 + hi / 2
    with np.errstate(over="ignore", invalid="ignore"):
        d = points - center
        big = float(np.abs(d).max())
        scale = big * float(np.linalg.norm(d / big, axis=1).max()) if big > 0 else 0.0
    if not np.isfinite(scale):
        raise InputError(f"{where}: coordinates overflow (the shape's extent exceeds float64's range)")
    magnitude = float(np.abs(points).max())
    if scale == 0 or scale <= REL_MIN_EXTENT * magnitude:
        raise InputError(f"{where} has zero extent (all points coincide)")
    return center, scale


@dataclass(frozen=True)
class Normalization:
    """``x_unit = (x_input - center) / scale``: the unit-ball frame of DESIGN's metrics.

    The one implementation: ``texture.uvmesh`` re-exports it.
    """

    center: np.ndarray  # (3,)
    scale: float

    def apply(self, x: np.ndarray) -> np.ndarray:
        return (np.asarray(x, np.float64) - self.center) / self.scale

    def invert(self, x: np.ndarray) -> np.ndarray:
        return np.asarray(x, np.float64) * self.scale + self.center

    def to_dict(self) -> dict:
        return {"center": [float(c) for c in self.center], "scale": float(self.scale)}

    to_json = to_dict

    @classmethod
    def from_dict(cls, d: dict) -> "Normalization":
        return cls(np.asarray(d["center"], dtype=np.float64), float(d["scale"]))

    @classmethod
    def fit(cls, points: np.ndarray, where: str = "input") -> "Normalization":
        """The unit-ball frame of ``points`` (see :func:`unit_ball` for what is refused)."""
        return cls(*unit_ball(points, where))


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
        every access to its cache, which costs a fifth of a 1-chart step)."""
        return None if self.mesh is None else np.array(self.mesh.face_normals, dtype=np.float64)

    def sample(self, count: int, rng: np.random.Generator) -> np.ndarray:
        """``count`` points on the surface: area-uniform on a mesh, a random subset of a cloud."""
        return self.sample_with_normals(count, rng)[0]

    def sample_with_normals(self, count: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray | None]:
        """Like :meth:`sample` (same draws), plus each point's unit face normal on a mesh (None on a cloud)."""
        if self.mesh is not None:
            pts, face = trimesh.sample.sample_surface(self.mesh, count, seed=int(rng.integers(2**31 - 1)))
            return np.asarray(pts, dtype=np.float64), self.face_normals[face]
        replace = count > len(self.points)
        idx = rng.choice(len(self.points), size=count, replace=replace)
        return self.points[idx], None

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
    if len(points) < MIN_POINTS:
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
        detail = str(exc).splitlines()[0] if str(exc) else ""
        raise InputError(f"cannot read {path.name}: {type(exc).__name__}: {detail}") from None
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
