"""DESIGN's metrics for a fitted atlas, in the unit-ball frame (one implementation for all methods).

``chamfer`` = mean ||x -> Y||^2 + mean ||y -> X||^2 (squared, both directions);
``fscore`` = harmonic mean of precision and recall at distance 0.02, in percent.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import torch
import trimesh

from mna import distortion
from mna.inference import evaluate, uniform_uv
from mna.model import NeuralAtlas
from mna.neighbors import nearest_numpy

#: F-score threshold: 1 % of the unit ball's diameter.
FSCORE_THRESHOLD = 0.02
#: a chart whose domain covers less than this percentage of its square counts as degenerate.
DEGENERATE_OCCUPANCY = 0.5


class PointMetrics(NamedTuple):
    chamfer: float
    fscore: float
    precision: float
    recall: float


def chamfer_fscore(pred: np.ndarray, ref: np.ndarray, threshold: float = FSCORE_THRESHOLD) -> PointMetrics:
    """Chamfer (squared, both directions) and F-score (percent) of ``pred (P, 3)`` vs ``ref (R, 3)``."""
    if len(pred) == 0:
        return PointMetrics(float("inf"), 0.0, 0.0, 0.0)
    d_pr, _ = nearest_numpy(pred, ref)
    d_rp, _ = nearest_numpy(ref, pred)
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


class AtlasDistortion(NamedTuple):
    distortion_metric: float
    distortion_conformal: float
    distortion_area: float
    occupancy_rate: list[float]
    degenerate_charts: int


@torch.no_grad()
def atlas_distortion(model: NeuralAtlas, samples: int, generator: torch.Generator, tau: float = 0.5,
                     eps: float = distortion.SSDE_EPS, z: torch.Tensor | None = None) -> AtlasDistortion:
    """Analytic distortions over in-domain UV samples of all charts (UV-area weighted), one shape."""
    device = next(model.parameters()).device
    uv = uniform_uv(model.charts, samples, generator, 1, device)
    ev = evaluate(model, uv, z, jacobian=True)
    inside = ev.occ[:, 0] > tau  # (K, N)
    rates = (inside.double().mean(1) * 100).cpu().tolist()
    degenerate = sum(r < DEGENERATE_OCCUPANCY for r in rates)
    if not inside.any():
        nan = float("nan")
        return AtlasDistortion(nan, nan, nan, rates, degenerate)
    g = distortion.metric_tensor(ev.jac[:, 0][inside].double())
    d = distortion.all_distortions(g, eps=eps)
    return AtlasDistortion(d.metric, d.conformal, d.area, rates, degenerate)
