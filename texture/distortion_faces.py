"""Per-face Jacobians of the map UV -> 3D and DESIGN's distortions per face.

A triangle with UV corners ``t0, t1, t2`` and positions ``p0, p1, p2`` is mapped by the
affine map whose Jacobian ``J (3, 2)`` solves ``J [t1 - t0, t2 - t0] = [p1 - p0, p2 - p0]``,
i.e. ``J = P D^-1`` with ``D = [t1 - t0, t2 - t0]`` (2x2) and ``P = [p1 - p0, p2 - p0]`` (3x2).
The formulas themselves live in :mod:`mnacore.distortion` (shared with the fit loss).

Example: UVs ``(0,0), (1,0), (0,1)`` on positions ``(0,0,0), (2,0,0), (0,1,0)`` give
``J = [[2,0],[0,1],[0,0]]``, ``g = diag(4, 1)``: ``tr g = 5``, ``tr g^-1 = 1.25``, so
``distortion_metric = 2 sqrt(5 * 1.25) - 4 = 1``, ``conformal = 5/2 - 2 = 0.5``, ``area = 0``.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from mnacore import distortion as D

#: faces whose |UV area| is below this fraction of the mean |UV area| have no Jacobian.
DEGENERATE_UV_REL = 1e-10


class FaceGeometry(NamedTuple):
    """Per-face quantities, all shape ``(F, ...)``."""

    jac: np.ndarray  # (F, 3, 2) d xyz / d uv (NaN on degenerate UV faces)
    uv_area: np.ndarray  # (F,) signed UV area (positive = counter-clockwise in UV)
    area_3d: np.ndarray  # (F,) 3D area
    normal: np.ndarray  # (F, 3) unit 3D normal from the face winding (0 on degenerate faces)
    valid: np.ndarray  # (F,) bool: UV area large enough for a Jacobian


def face_geometry(vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray) -> FaceGeometry:
    """Jacobians, signed UV areas, 3D areas and normals of every face (float64)."""
    vertices = np.asarray(vertices, np.float64)
    uv = np.asarray(uv, np.float64)
    faces = np.asarray(faces, np.int64)
    p = vertices[faces]  # (F, 3, 3)
    t = uv[faces]  # (F, 3, 2)
    P = np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]], -1)  # (F, 3, 2)
    Dm = np.stack([t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]], -1)  # (F, 2, 2) columns = UV edges
    det = Dm[:, 0, 0] * Dm[:, 1, 1] - Dm[:, 0, 1] * Dm[:, 1, 0]
    uv_area = 0.5 * det
    cross = np.cross(P[:, :, 0], P[:, :, 1])
    norm = np.linalg.norm(cross, axis=1)
    area_3d = 0.5 * norm
    normal = np.divide(cross, norm[:, None], out=np.zeros_like(cross), where=norm[:, None] > 0)
    mean_abs = float(np.abs(uv_area).mean()) if len(uv_area) else 0.0
    valid = np.abs(uv_area) > DEGENERATE_UV_REL * mean_abs
    safe = np.where(valid, det, 1.0)
    inv = np.stack([np.stack([Dm[:, 1, 1], -Dm[:, 0, 1]], -1),
                    np.stack([-Dm[:, 1, 0], Dm[:, 0, 0]], -1)], 1) / safe[:, None, None]
    jac = P @ inv
    jac[~valid] = np.nan
    return FaceGeometry(jac, uv_area, area_3d, normal, valid)


def symmetric_dirichlet(geom: FaceGeometry) -> np.ndarray:
    """(F,) ``tr g + tr g^-1`` of the map UV -> 3D per face (the energy SLIM minimises; NaN on
    faces that are not ``valid``, inf on a face of no 3D area).

    ``tr g^-1 = tr g / det g``, and for a triangle's linear map ``det g = (A_3D / A_uv)^2``
    exactly: taken from the areas, not as ``E G - F^2``, which cancels to noise where the
    Jacobian's columns are nearly parallel (a 3D sliver on a fair UV triangle: 10 % off at a
    height of 2e-8, inf at 1e-9, and below zero elsewhere: a slit's map of an unseen scan
    measured -230 and was kept as the best)."""
    g = D.metric_tensor(geom.jac)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = geom.uv_area / geom.area_3d
        return D.trace(g) * (1.0 + ratio * ratio)


def metric_tensors(geom: FaceGeometry, uv_scale: float = 1.0) -> D.MetricTensor:
    """``g = J^T J`` per face, for UVs scaled by ``uv_scale`` (g scales by ``1/uv_scale^2``)."""
    return D.metric_tensor(geom.jac / uv_scale)


def equal_area_uv_scale(geom: FaceGeometry) -> float:
    """Global UV scale ``s`` with ``sum |s^2 uv_area| = sum area_3d`` (so ``E[sqrt det g] ~ 1``).

    The distortions are scale-free except for the SSDE's ``eps``; fixing this scale makes
    ``eps`` act the same on a packed [0,1]^2 atlas and on a neural chart's [-1,1]^2.
    """
    uv_total = float(np.abs(geom.uv_area[geom.valid]).sum())
    a3_total = float(geom.area_3d[geom.valid].sum())
    if uv_total <= 0 or a3_total <= 0:
        return 1.0
    return float(np.sqrt(a3_total / uv_total))


def per_face_from_geometry(geom: FaceGeometry, eps: float = D.SSDE_EPS) -> dict[str, np.ndarray]:
    """Per-face decomposition of the UV-area weighted DESIGN distortions (see ``per_face_distortions``)."""
    s = equal_area_uv_scale(geom)
    F = len(geom.valid)
    out = {k: np.full(F, np.nan) for k in ("metric", "conformal", "area")}
    if not geom.valid.any():
        return out
    v = geom.valid
    g = D.metric_tensor(geom.jac[v] * s)  # UVs multiplied by 1/s -> J multiplied by s
    w = np.abs(geom.uv_area[v])
    a, b = D.trace(g, eps), D.trace_inverse(g, eps)
    # optimal global scale of the SSDE: s2 = sqrt(E[tr g^-1] / E[tr g])
    s2 = np.sqrt(D.weighted_mean(b, w) / D.weighted_mean(a, w))
    out["metric"][v] = s2 * a + b / s2 - 4.0
    out["conformal"][v] = D.mips_per_sample(g)
    A = D.area_factor(g)
    t = np.sqrt(D.weighted_mean(1.0 / A, w) / D.weighted_mean(A, w))
    out["area"][v] = t * A + 1.0 / (t * A) - 2.0
    return out
