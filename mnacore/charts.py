"""Read and validate ``RUN/charts.npz`` (format: docs/run_folder.md).

Chart-local UV lies in ``[-1, 1]^2``; grid vertex ``(k, i, j)`` has
``uv = (-1 + 2 j / (G - 1), -1 + 2 i / (G - 1))`` (j = column = u, i = row = v, up).
"""
from __future__ import annotations

import os
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .errors import InputError
from .frame import Normalization

REQUIRED = ("uv", "xyz", "occ", "tau", "center", "scale")


@dataclass(frozen=True)
class ChartGrids:
    """The chart grids of a run.

    Attributes:
        uv: (K, G, G, 2) chart-local UV of each grid vertex.
        xyz: (K, G, G, 3) ``phi_k(uv)`` in the input frame.
        occ: (K, G, G) occupancy ``o_k``; in-domain iff ``occ > tau``.
        tau: domain threshold.
        normalization: input frame -> unit ball.
        kept_vertices, kept_faces: the run's own kept mesh (whole grid cells), input frame.
    """

    uv: np.ndarray
    xyz: np.ndarray
    occ: np.ndarray
    tau: float
    normalization: Normalization
    kept_vertices: np.ndarray | None = None
    kept_faces: np.ndarray | None = None

    @property
    def n_charts(self) -> int:
        return int(self.uv.shape[0])

    @property
    def grid(self) -> int:
        return int(self.uv.shape[1])


def load_charts(path: str | os.PathLike) -> ChartGrids:
    """Load ``charts.npz``; raises ``InputError`` naming the problem (missing key, bad shape, NaN)."""
    path = Path(path)
    if path.is_dir():
        path = path / "charts.npz"
    if not path.is_file():
        raise InputError(f"charts file not found: {path} (run `mna fit` or `mna extract` first)")
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise InputError(f"cannot read {path}: {exc}") from exc
    missing = [k for k in REQUIRED if k not in data]
    if missing:
        raise InputError(f"{path.name} lacks key(s) {', '.join(missing)}")
    uv, xyz, occ = (np.asarray(data[k], np.float64) for k in ("uv", "xyz", "occ"))
    if uv.ndim != 4 or uv.shape[-1] != 2 or uv.shape[1] != uv.shape[2] or uv.shape[1] < 2:
        raise InputError(f"{path.name}: uv must have shape (K, G, G, 2), got {uv.shape}")
    K, G = uv.shape[:2]
    if xyz.shape != (K, G, G, 3):
        raise InputError(f"{path.name}: xyz must have shape {(K, G, G, 3)}, got {xyz.shape}")
    if occ.shape != (K, G, G):
        raise InputError(f"{path.name}: occ must have shape {(K, G, G)}, got {occ.shape}")
    for name, arr in (("uv", uv), ("xyz", xyz), ("occ", occ)):
        if not np.isfinite(arr).all():
            raise InputError(f"{path.name}: {name} contains NaN or inf")
    center = np.asarray(data["center"], np.float64).reshape(-1)
    scale = float(np.asarray(data["scale"]).reshape(()))
    if center.shape != (3,) or not np.isfinite(center).all() or not (np.isfinite(scale) and scale > 0):
        raise InputError(f"{path.name}: bad normalisation center={center} scale={scale}")
    kv, kf = data.get("vertices"), data.get("faces")
    return ChartGrids(uv, xyz, occ, float(data["tau"]), Normalization(center, scale),
                      None if kv is None else np.asarray(kv, np.float64),
                      None if kf is None else np.asarray(kf, np.int64))


class KeptMesh(NamedTuple):
    """The run's kept mesh: whole grid cells whose three vertices are all in-domain."""

    grid_index: np.ndarray  # (V,) flat index ``k * G * G + i * G + j`` of each kept vertex, ascending
    faces: np.ndarray  # (F, 3) into the kept vertices; chart by chart, grid_faces order within a chart
    face_chart: np.ndarray  # (F,) chart of each face


def kept_mesh(occ: np.ndarray, tau: float) -> KeptMesh:
    """The kept mesh of occupancy grids ``occ (K, G, G)``: triangles of :func:`grid_faces` whose
    three vertices have ``occ > tau`` (the paper's mesh extraction), vertices renumbered.

    Example: one chart on a 3 x 3 grid, all inside: 9 vertices, 8 faces.
    """
    from .grid import grid_faces

    K, G = occ.shape[:2]
    tri = grid_faces(G)
    inside = (np.asarray(occ).reshape(K, -1) > tau).reshape(-1)
    all_faces = (tri[None] + (np.arange(K) * G * G)[:, None, None]).reshape(-1, 3)
    keep = inside[all_faces].all(1)
    faces = all_faces[keep]
    used = np.unique(faces)
    remap = np.full(K * G * G, -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return KeptMesh(used, remap[faces], np.repeat(np.arange(K), len(tri))[keep])


def save_charts(path: str | os.PathLike, uv: np.ndarray, xyz: np.ndarray, occ: np.ndarray, tau: float,
                normalization: Normalization, dtype=np.float32) -> None:
    """Write ``charts.npz`` in the documented format (docs/run_folder.md), atomically.

    ``xyz (K, G, G, 3)`` in the input frame; the kept mesh is derived by :func:`kept_mesh`.
    Positions are stored as ``dtype`` (float64 where float32 cannot hold the input's scale).
    The one writer: the fit stage and synthetic charts in tests both use it.
    """
    from .atomic import atomic_path

    K, G = uv.shape[:2]
    kept = kept_mesh(occ, tau)
    flat_uv, flat_xyz = uv.reshape(-1, 2), xyz.reshape(-1, 3)
    arrays = dict(
        uv=uv.astype(np.float32), xyz=xyz.astype(dtype), occ=occ.astype(np.float32),
        tau=np.float64(tau), center=np.asarray(normalization.center, np.float64),
        scale=np.float64(normalization.scale),
        vertices=flat_xyz[kept.grid_index].astype(dtype), faces=kept.faces.astype(np.int64),
        vertex_uv=flat_uv[kept.grid_index].astype(np.float32),
        vertex_chart=(kept.grid_index // (G * G)).astype(np.int64),
        face_chart=kept.face_chart.astype(np.int64), grid_index=kept.grid_index.astype(np.int64),
    )
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, **arrays)
