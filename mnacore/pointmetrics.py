"""Chamfer distance and F-score between point sets (numpy + scipy; torch-free, so ``texture`` uses it too).

DESIGN's definitions, in the unit-ball frame: ``chamfer = mean ||x -> Y||^2 + mean ||y -> X||^2``
(squared distances, both directions); ``fscore`` = harmonic mean of precision and recall at
0.02 (1 % of the unit ball's diameter), in percent.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from .tolerances import SURFACE_TOL

#: F-score threshold: 1 % of the unit ball's diameter.
FSCORE_THRESHOLD = SURFACE_TOL
#: points per side for Chamfer / F-score.
POINTS = 25000


class PointMetrics(NamedTuple):
    chamfer: float
    fscore: float
    precision: float
    recall: float


def chamfer_fscore(pred: np.ndarray, ref: np.ndarray, threshold: float = FSCORE_THRESHOLD) -> PointMetrics:
    """Chamfer (squared, both directions) and F-score (percent) of ``pred (P, 3)`` vs ``ref (R, 3)``."""
    if len(pred) == 0 or len(ref) == 0:
        return PointMetrics(float("inf"), 0.0, 0.0, 0.0)
    d_pr = cKDTree(ref).query(pred, workers=-1)[0]
    d_rp = cKDTree(pred).query(ref, workers=-1)[0]
    precision = float((d_pr < threshold).mean()) * 100
    recall = float((d_rp < threshold).mean()) * 100
    f = 0.0 if precision + recall == 0 else 2 * precision * recall / (precision + recall)
    return PointMetrics(float((d_pr**2).mean() + (d_rp**2).mean()), f, precision, recall)


def sample_mesh(vertices: np.ndarray, faces: np.ndarray, count: int, seed: int) -> np.ndarray:
    """``count`` points uniform by area on a triangle mesh (empty if it has no area)."""
    if len(faces) == 0:
        return np.zeros((0, 3))
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    if not mesh.area > 0:
        return np.zeros((0, 3))
    pts, _ = trimesh.sample.sample_surface(mesh, count, seed=seed)
    return np.asarray(pts)
