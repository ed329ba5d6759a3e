"""The fit losses (paper Sec. 4): L_rec, L_occ, L_dist, and the PU positive-label rule.

One formula each. ``L_dist`` is :func:`mna.distortion.scaled_symmetric_dirichlet`, the
same function the ``distortion_metric`` reports.
"""
from __future__ import annotations

import torch
from torch.nn import functional as F

from mna import distortion


def positive_labels(nearest_index: torch.Tensor, total: int) -> torch.Tensor:
    """PU labels: sample ``s`` is positive iff it is the nearest chart point of some target.

    ``nearest_index (T,)`` holds, for each target point, the flat index of its nearest
    sample among all ``total`` chart samples; returns ``(total,)`` bool.
    """
    labels = torch.zeros(total, dtype=torch.bool, device=nearest_index.device)
    labels[nearest_index] = True
    return labels


def reconstruction_loss(targets: torch.Tensor, matched: torch.Tensor) -> torch.Tensor:
    """Unidirectional Chamfer: ``mean_t ||y_t - x_nn(t)||^2`` with ``matched (T, 3)`` = nearest chart points."""
    return ((targets - matched) ** 2).sum(-1).mean()


def chamfer_to(points: torch.Tensor, targets: torch.Tensor, nearest_index: torch.Tensor) -> torch.Tensor:
    """``mean_x ||x - y_nn(x)||^2`` for points ``(P, 3)`` whose nearest targets are ``nearest_index (P,)``."""
    return ((points - targets[nearest_index]) ** 2).sum(-1).mean()


def occupancy_loss(logits: torch.Tensor, labels: torch.Tensor) -> torch.Tensor:
    """BCE of the labelled probability ``sigmoid(logits)`` against PU labels (same shape)."""
    return F.binary_cross_entropy_with_logits(logits, labels.to(logits.dtype))


def distortion_loss(jac: torch.Tensor, eps: float = distortion.SSDE_EPS) -> torch.Tensor:
    """``2 sqrt(mean tr g_hat * mean tr g_hat^-1)`` over Jacobians ``jac (..., 3, 2)`` (one scale for all)."""
    return distortion.scaled_symmetric_dirichlet(distortion.metric_tensor(jac), eps)
