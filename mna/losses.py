"""The fit losses (paper Sec. 4): L_rec, L_occ, L_dist, and the PU positive-label rule.

One formula each. ``L_dist`` is :func:`mna.distortion.scaled_symmetric_dirichlet`, the
same function the ``distortion_metric`` reports.
"""
from __future__ import annotations

import torch
from torch.nn import functional as F

from mnacore import distortion


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


def orientation_loss(jac: torch.Tensor, normals: torch.Tensor, group: torch.Tensor) -> torch.Tensor:
    """Share of chart normals that point against the surface normal (mna extension, not in the paper).

    ``jac (P, 3, 2)`` chart Jacobians at positives, ``normals (P, 3)`` unit normals of their
    targets, ``group (P,)`` which chart (of which shape) each belongs to. With
    ``c = <n_hat, normal>``, ``n_hat = J_u x J_v / |J_u x J_v|``, and ``s_g`` the sign of
    ``sum c`` over group ``g`` (the chart's majority orientation, no gradient):
    ``mean relu(-s_g c)``. Zero when every chart is consistently oriented (either way: a
    chart's UV handedness is arbitrary); 1 where a normal is exactly reversed.
    """
    n = torch.linalg.cross(jac[..., 0], jac[..., 1], dim=-1)
    n = n / n.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    c = (n * normals).sum(-1)
    size = int(group.max()) + 1 if len(group) else 0
    votes = torch.zeros(size, device=c.device, dtype=c.dtype).index_add_(0, group, c.detach())
    majority = torch.where(votes >= 0, 1.0, -1.0).to(c.dtype)
    return torch.relu(-majority[group] * c).mean() if len(c) else c.sum()
