"""The unit-ball frame of every metric (DESIGN) and the checks that come with reading coordinates.

``x_unit = (x_input - center) / scale``: centre = bounding-box centre, scale = the largest
distance to it, so the shape fits the unit ball. Judged relative to the shape's own size, so
a shape at 1e-30 or 1e200 units normalises like one at 1.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError

#: below this extent *relative to the coordinates' magnitude* the geometry is one point: its
#: size is then lost in the float64 rounding of the positions themselves (eps 2.2e-16 with room
#: to spare). Relative, so a shape at 1e-30 or at 1e200 units normalises like one at 1.
REL_MIN_EXTENT = 1e-12

#: a shape whose coordinates exceed this many times its size is "far from the origin":
#: float32 keeps 24 bits of a coordinate, so there the offset, not the shape, sets the
#: precision (a unit sphere at UTM coordinates, 5e6, moved by up to 0.24). Such shapes are
#: stored relative to their centre (exports) or in float64 (run folders).
FAR_FROM_ORIGIN = 16.0


def far_from_origin(coordinate: float, size: float) -> bool:
    """``coordinate`` (the largest |coordinate|) is beyond ``FAR_FROM_ORIGIN`` x ``size`` (extent)."""
    return coordinate > FAR_FROM_ORIGIN * size


#: the first bytes of binary or self-describing formats: a file renamed to the wrong
#: extension (a text file called .ply) is named as such instead of failing deep in a parser
MAGIC = {".ply": b"ply", ".glb": b"glTF", ".npy": b"\x93NUMPY", ".npz": b"PK"}


def read_failure(path: Path, exc: BaseException) -> str:
    """One line for a reader's exception on ``path``: trimesh names only the file a glTF or
    OBJ refers to and cannot find (``gltf_buffer_0.bin``), so say that it is missing."""
    detail = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    if isinstance(exc, FileNotFoundError):
        return f"cannot read {path.name}: a file it refers to is missing: {detail}"
    return f"cannot read {path.name}: {detail}"


def check_file_format(path: Path) -> None:
    """Raise ``InputError`` when ``path``'s first bytes do not match its extension (see
    ``MAGIC``), or a ``.gltf`` is not JSON with an ``asset`` (trimesh reports a broken one as
    a missing ``model.gltf``)."""
    if path.suffix.lower() == ".gltf":
        try:
            tree = json.loads(path.read_bytes())
        except (ValueError, UnicodeDecodeError) as exc:
            raise InputError(f"cannot read {path.name}: not glTF JSON ({str(exc).splitlines()[0]})") from None
        if not isinstance(tree, dict) or "asset" not in tree:
            raise InputError(f"cannot read {path.name}: not glTF (no \"asset\" in its JSON)")
        return
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

    The one implementation: ``mnacore.uvmesh`` re-exports it.
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


def unit_ball_normalization(points: np.ndarray) -> Normalization:
    """:class:`Normalization` of a mesh's points (see :func:`unit_ball` for what is refused)."""
    return Normalization.fit(points, "mesh")
