"""Distortion formulas of a map UV -> surface, written once for the loss and every metric.

These functions are array-agnostic: they take numpy arrays or torch tensors and use
only operators both support, so the fit loss (torch, differentiable), the fit
metrics (torch) and the mesh harness in ``texture`` (numpy, per face) share one
implementation. This module must not import torch.

Conventions
-----------
``J`` is the 3x2 Jacobian of the map ``phi: (u, v) -> R^3`` with columns
``J[..., :, 0] = d phi / du`` and ``J[..., :, 1] = d phi / dv``.
The metric tensor (first fundamental form) is ``g = J^T J = [[E, F], [F, G]]``;
we pass it around as its three components ``(E, F, G)``, shape ``(...,)`` each.

Example: the isometry ``phi(u, v) = (u, v, 0)`` has ``E = G = 1, F = 0``, so
``tr g = 2``, ``tr g^-1 = 2`` and every distortion below is 0. Scaling it by ``s``
gives ``tr g = 2 s^2``, ``tr g^-1 = 2 / s^2``: the scaled measures stay 0.
"""
from __future__ import annotations

from typing import NamedTuple

#: epsilon added to g before inversion in the SSDE (paper: g_hat = J^T J + eps I).
SSDE_EPS = 1e-4
#: floor added to det g (MIPS) and sqrt(det g) (area) so degenerate faces stay finite;
#: far below any real scale, so it never biases a non-degenerate map.
AREA_EPS = 1e-20


class MetricTensor(NamedTuple):
    """Components of ``g = [[E, F], [F, G]]``, each of shape ``(...,)``."""

    E: object
    F: object
    G: object


def metric_tensor(jac) -> MetricTensor:
    """``g = J^T J`` for ``jac`` of shape ``(..., 3, 2)`` (columns d/du, d/dv)."""
    ju = jac[..., :, 0]
    jv = jac[..., :, 1]
    return MetricTensor((ju * ju).sum(-1), (ju * jv).sum(-1), (jv * jv).sum(-1))


def trace(g: MetricTensor, eps: float = 0.0):
    """``tr(g + eps I) = E + G + 2 eps``."""
    return g.E + g.G + 2.0 * eps


def det(g: MetricTensor, eps: float = 0.0):
    """``det(g + eps I) = (E + eps)(G + eps) - F^2``."""
    return (g.E + eps) * (g.G + eps) - g.F * g.F


def trace_inverse(g: MetricTensor, eps: float = SSDE_EPS):
    """``tr((g + eps I)^-1) = tr(g + eps I) / det(g + eps I)`` (2x2 closed form)."""
    return trace(g, eps) / det(g, eps)


def weighted_mean(x, weights=None):
    """``sum(w x) / sum(w)``; plain mean when ``weights`` is None."""
    if weights is None:
        return x.mean()
    return (x * weights).sum() / weights.sum()


def scaled_symmetric_dirichlet(g: MetricTensor, eps: float = SSDE_EPS, weights=None):
    """Symmetric Dirichlet energy at the optimal global scale.

    ``min_s E[tr(s^2 g)] + E[tr((s^2 g)^-1)] = 2 sqrt(E[tr g_hat] E[tr g_hat^-1])`` with
    ``g_hat = g + eps I``. Equals 4 for any isometry at any uniform scale (eps -> 0).
    This is the paper's distortion loss L_dist; ``distortion_metric = this - 4``.
    """
    a = weighted_mean(trace(g, eps), weights)
    b = weighted_mean(trace_inverse(g, eps), weights)
    return 2.0 * (a * b) ** 0.5


def distortion_metric(g: MetricTensor, eps: float = SSDE_EPS, weights=None):
    """``2 sqrt(E[tr g_hat] E[tr g_hat^-1]) - 4``: 0 for an isometry up to scale."""
    return scaled_symmetric_dirichlet(g, eps, weights) - 4.0


def mips_per_sample(g: MetricTensor, eps: float = AREA_EPS):
    """MIPS energy ``tr g / sqrt(det g) - 2`` per sample (0 for a conformal map)."""
    return trace(g) / (det(g) + eps) ** 0.5 - 2.0


def distortion_conformal(g: MetricTensor, weights=None, eps: float = AREA_EPS):
    """``E[tr g / sqrt(det g)] - 2`` (MIPS): 0 for any conformal map."""
    return weighted_mean(mips_per_sample(g, eps), weights)


def area_factor(g: MetricTensor, eps: float = AREA_EPS):
    """Local area scale ``A = sqrt(det g) + eps``."""
    # clip: round-off can make det of a degenerate face slightly negative.
    return det(g).clip(0.0) ** 0.5 + eps


def distortion_area(g: MetricTensor, weights=None, eps: float = AREA_EPS):
    """``2 sqrt(E[A] E[1/A]) - 2`` with ``A = sqrt(det g) + eps``: 0 for an equiareal map up to scale."""
    a = area_factor(g, eps)
    return 2.0 * (weighted_mean(a, weights) * weighted_mean(1.0 / a, weights)) ** 0.5 - 2.0


class Distortions(NamedTuple):
    metric: float
    conformal: float
    area: float


def _at_least_zero(x: float) -> float:
    # each distortion is >= 0 exactly (Cauchy-Schwarz, AM-GM); on an isometry rounding leaves
    # about -4e-16 (a third of rotated isometries), which reports read as "-0.000"
    return 0.0 if x < 0 else x  # NaN stays NaN


def all_distortions(g: MetricTensor, weights=None, eps: float = SSDE_EPS) -> Distortions:
    """The three DESIGN distortions as floats (weights: e.g. UV or 3D area per sample)."""
    return Distortions(
        _at_least_zero(float(distortion_metric(g, eps, weights))),
        _at_least_zero(float(distortion_conformal(g, weights))),
        _at_least_zero(float(distortion_area(g, weights))),
    )
