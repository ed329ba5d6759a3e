"""Read and validate ``RUN/charts.npz`` (format: docs/run_folder.md).

Chart-local UV lies in ``[-1, 1]^2``; grid vertex ``(k, i, j)`` has
``uv = (-1 + 2 j / (G - 1), -1 + 2 i / (G - 1))`` (j = column = u, i = row = v, up).
"""
from __future__ import annotations

import os
import zipfile
from dataclasses import dataclass
from pathlib import Path

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


def save_charts(path: str | os.PathLike, uv: np.ndarray, xyz: np.ndarray, occ: np.ndarray, tau: float,
                center: np.ndarray, scale: float) -> None:
    """Write a ``charts.npz`` in the documented format (kept mesh derived from ``occ > tau``).

    Used for synthetic charts in tests and demos; the fit stage writes its own.
    """
    from .atomic import atomic_path
    from .grid import grid_faces

    K, G = uv.shape[:2]
    tri = grid_faces(G)
    inside = occ.reshape(K, -1) > tau
    verts, faces, vuv, vchart, fchart, gidx = [], [], [], [], [], []
    offset = 0
    for k in range(K):
        keep = inside[k][tri].all(1)
        used = np.unique(tri[keep])
        remap = np.full(G * G, -1)
        remap[used] = np.arange(len(used)) + offset
        verts.append(xyz[k].reshape(-1, 3)[used])
        vuv.append(uv[k].reshape(-1, 2)[used])
        faces.append(remap[tri[keep]])
        vchart.append(np.full(len(used), k))
        fchart.append(np.full(int(keep.sum()), k))
        gidx.append(k * G * G + used)
        offset += len(used)
    arrays = dict(
        uv=uv.astype(np.float32), xyz=xyz.astype(np.float32), occ=occ.astype(np.float32),
        tau=np.float64(tau), center=np.asarray(center, np.float64), scale=np.float64(scale),
        vertices=np.concatenate(verts).astype(np.float32), faces=np.concatenate(faces).astype(np.int64),
        vertex_uv=np.concatenate(vuv).astype(np.float32), vertex_chart=np.concatenate(vchart).astype(np.int64),
        face_chart=np.concatenate(fchart).astype(np.int64), grid_index=np.concatenate(gidx).astype(np.int64),
    )
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, **arrays)
