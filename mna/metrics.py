"""DESIGN's metrics for a fitted atlas, in the unit-ball frame (one implementation for all methods).

Point metrics (Chamfer, F-score) live in the torch-free :mod:`mnacore.pointmetrics` and are
re-exported here; this module adds the analytic distortions of a neural atlas.
"""
from __future__ import annotations

from typing import NamedTuple

import torch

from mna.inference import evaluate, uniform_uv
from mna.model import NeuralAtlas
from mnacore import distortion
from mnacore.pointmetrics import FSCORE_THRESHOLD, PointMetrics, chamfer_fscore, sample_mesh  # noqa: F401

#: a chart whose domain covers less than this percentage of its square counts as degenerate.
DEGENERATE_OCCUPANCY = 0.5


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
