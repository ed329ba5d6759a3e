"""The training objective for a batch of shapes: one implementation for per-shape fits and datasets.

For each shape ``b``: evaluate all charts at the UV samples without gradients; find each
target point's nearest chart sample (PU positives); then evaluate the charts *with*
gradients (and exact Jacobians) at the unique positives only. L_rec and L_dist only ever
touch positives (a target's nearest sample is a positive), so this equals evaluating every
sample with gradients, at a fraction of the cost. L_occ trains ``l_k`` on all samples with
``phi`` detached (paper: no gradient from L_occ into the charts).

L_surf (``loss.w_surface``, an mna extension) is the other direction of the Chamfer distance,
from chart samples to their nearest target, on a random subset of every chart's samples
whether they lie in the domain or not. Without it only positives get a gradient from the
reconstruction, so the part of a chart outside its domain drifts where no target is, and
a stretch of surface that no chart reaches (the walls of a plate's holes, a wheel beside a
body) can only be taken by pulling a domain's edge across to it. With it, every chart's
whole square lies on the surface, and its outside parts lie where they can become positives.
"""
from __future__ import annotations

from typing import NamedTuple

import torch

from mna import losses
from mna.config import FitConfig
from mna.model import NeuralAtlas
from mna.neighbors import nearest
from mnacore.tolerances import NEAR_TOL


class LossTerms(NamedTuple):
    total: torch.Tensor
    rec: torch.Tensor
    occ: torch.Tensor
    dist: torch.Tensor
    positives: int
    orient: torch.Tensor | None = None
    distance: torch.Tensor | None = None
    """``(B, T)`` distance of every target to its nearest chart sample (no gradient)."""
    surface: torch.Tensor | None = None


def atlas_losses(model: NeuralAtlas, uv: torch.Tensor, targets: torch.Tensor, cfg: FitConfig,
                 z: torch.Tensor | None = None, normals: torch.Tensor | None = None,
                 labelled: int | None = None, surface: bool = True, w_dist: float | None = None,
                 exclusive: bool | None = None) -> LossTerms:
    """Weighted losses for ``uv (K, B, N, 2)`` samples and ``targets (B, T, 3)`` (unit-ball frame).

    ``normals (B, T, 3)``: unit surface normals of the targets, for L_orient (``w_orient > 0``;
    without normals the term is 0). ``labelled``: only the first ``labelled`` targets of each
    shape label PU positives (the uniform draw; the rest are hard examples that only pull,
    :mod:`mna.hard_targets`); None = all. ``surface``: False leaves L_surf out this step (a fit's
    schedule: a fit's lr decay). ``w_dist``: L_dist's weight this step (None: ``loss.w_dist``;
    a fit's ``late_w_dist``). ``exclusive``: exclusive PU labels this step (None:
    ``exclusive_labels``; a fit's lr decay).
    """
    orient = torch.zeros((), device=uv.device)
    want_surface = surface and cfg.loss.w_surface > 0
    surface = torch.zeros((), device=uv.device)
    if cfg.ablation.atlasnet:
        rec, dist, n, d = _atlasnet_terms(model, uv, targets, cfg, z)
        occ = torch.zeros((), device=uv.device)
    else:
        exclusive = cfg.exclusive_labels if exclusive is None else exclusive
        rec, dist, occ, n, o, d = _mna_terms(model, uv, targets, cfg, z, normals, labelled, exclusive)
        orient = o if o is not None else orient
        if want_surface:
            surface = _surface_term(model, uv[:, :, :cfg.surface_samples], targets, z)
    w = cfg.loss
    w_dist = w.w_dist if w_dist is None else w_dist
    total = w.w_rec * rec + w.w_occ * occ + w_dist * dist + w.w_orient * orient + w.w_surface * surface
    return LossTerms(total, rec, occ, dist, n, orient, d, surface)


def _surface_term(model: NeuralAtlas, uv: torch.Tensor, targets: torch.Tensor, z) -> torch.Tensor:
    """L_surf at ``uv (K, B, H, 2)``: mean squared distance of the chart points to their nearest
    target, per shape (all charts together), averaged over the batch. UV samples are i.i.d., so
    the first ``H`` of a step's draw are a random subset."""
    K, B, H, _ = uv.shape
    x = model.chart(uv, z).x
    terms = []
    for b in range(B):
        pts = x[:, b].reshape(K * H, 3)
        terms.append(losses.chamfer_to(pts, targets[b], nearest(pts, targets[b]).index.to(uv.device)))
    return torch.stack(terms).mean()


def _mna_terms(model: NeuralAtlas, uv: torch.Tensor, targets: torch.Tensor, cfg: FitConfig, z, normals=None,
               labelled: int | None = None, exclusive: bool = False):
    K, B, N, _ = uv.shape
    T = targets.shape[1]
    with torch.no_grad():
        x = model.chart(uv, z).x  # (K, B, N, 3)
    logits = model.label_logits(uv, x, z)  # x carries no gradient: L_occ never reaches phi
    # per shape: the sample (flat k*N + n) each target labels -> global key b*K*N + k*N + n
    keys, labels, dists = [], [], []
    for b in range(B):
        if exclusive:
            idx, dist = _exclusive_positives(targets[b], x[:, b], logits[:, b].detach())
        else:
            near = nearest(targets[b], x[:, b].reshape(K * N, 3))
            idx, dist = near.index, near.dist2.sqrt()
        idx = idx.to(uv.device)
        labels.append(losses.positive_labels(idx[:labelled], K * N).view(K, N))
        keys.append(idx + b * K * N)
        dists.append(dist)
    labels = torch.stack(labels, 1)  # (K, B, N), like the logits
    key = torch.cat(keys)
    uniq, inverse = torch.unique(key, sorted=True, return_inverse=True)
    b_of, rest = uniq // (K * N), uniq % (K * N)
    k_of, n_of = rest // N, rest % N
    group = b_of * K + k_of  # keys sorted by (b, k): each group's positives are contiguous
    counts = torch.bincount(group, minlength=B * K)
    offsets = torch.cumsum(counts, 0) - counts
    slot = torch.arange(len(uniq), device=uv.device) - offsets[group]
    pos_uv = torch.zeros(K, B, int(counts.max()), 2, device=uv.device, dtype=uv.dtype)
    pos_uv[k_of, b_of, slot] = uv[k_of, b_of, n_of]

    limit = cfg.dist_samples
    want_orient = cfg.loss.w_orient > 0 and normals is not None
    want_jac = cfg.loss.w_dist > 0 or want_orient
    split_jac = want_jac and 0 < limit < int(counts.max())
    out = model.chart(pos_uv, z, jacobian=want_jac and not split_jac)
    matched = out.x[k_of, b_of, slot]  # (U, 3)
    rec = losses.reconstruction_loss(targets.reshape(B * T, 3), matched[inverse])
    if not want_jac:
        dist = torch.zeros((), device=uv.device)
    else:
        if split_jac:
            # L_dist on the first `limit` positives of each chart: positives come in random order
            # within a chart (UV samples are i.i.d.), so this is a random subset
            jac_all = model.chart(pos_uv[:, :, :limit], z, jacobian=True).jac
            keep = slot < limit
            jac, jb = jac_all[k_of[keep], b_of[keep], slot[keep]], b_of[keep]
        else:
            jac, jb = out.jac[k_of, b_of, slot], b_of
        # one scale per shape (shared by its charts), averaged over the batch
        dist = torch.stack([losses.distortion_loss(jac[jb == b], cfg.loss.eps) for b in range(B)]).mean()
    orient = None
    if want_orient:
        # one target per positive (any of those whose nearest sample it is: the largest index)
        tgt = torch.full((len(uniq),), -1, dtype=torch.long, device=uv.device).scatter_reduce(
            0, inverse, torch.arange(B * T, device=uv.device), reduce="amax")
        tgt_n = normals.reshape(B * T, 3).to(uv.dtype)[tgt]
        sel = keep if split_jac else torch.ones_like(group, dtype=torch.bool)
        tgt_n, grp = tgt_n[sel], group[sel]
        orient = torch.stack([losses.orientation_loss(jac[jb == b], tgt_n[jb == b], grp[jb == b])
                              for b in range(B)]).mean()
    occ = losses.occupancy_loss(logits.reshape(-1), labels.reshape(-1))
    return rec, dist, occ, len(uniq), orient, torch.stack(dists)


def _exclusive_positives(targets: torch.Tensor, x: torch.Tensor, logits: torch.Tensor):
    """``exclusive_labels``: for ``targets (T, 3)``, chart samples ``x (K, N, 3)`` and their label
    logits ``(K, N)``, the flat index ``k*N + n`` each target labels (its nearest sample in the
    chart with the highest logit there, among the charts whose nearest sample lies within
    ``NEAR_TOL`` of the nearest overall) and the distance to the nearest sample overall."""
    K, N, _ = x.shape
    per = [nearest(targets, x[k]) for k in range(K)]
    d = torch.stack([p.dist2 for p in per], 1).sqrt()  # (T, K)
    ix = torch.stack([p.index for p in per], 1).to(logits.device)
    best = d.min(1, keepdim=True).values
    lab = logits[torch.arange(K, device=logits.device)[None, :], ix].to(d.device)
    lab = torch.where(d <= best + NEAR_TOL, lab, torch.full_like(lab, -torch.inf))
    k = lab.argmax(1)
    return k.to(ix.device) * N + ix.gather(1, k.to(ix.device)[:, None])[:, 0], best[:, 0]


def _atlasnet_terms(model: NeuralAtlas, uv: torch.Tensor, targets: torch.Tensor, cfg: FitConfig, z):
    """No occupancy: every sample counts; bidirectional Chamfer; distortion over all samples."""
    K, B, N, _ = uv.shape
    out = model.chart(uv, z, jacobian=cfg.loss.w_dist > 0)
    rec, dist, dists = 0.0, [], []
    for b in range(B):
        pts = out.x[:, b].reshape(K * N, 3)
        near = nearest(targets[b], pts)
        to_pts = near.index.to(uv.device)
        dists.append(near.dist2.sqrt())
        to_tgt = nearest(pts, targets[b]).index.to(uv.device)
        rec = rec + losses.reconstruction_loss(targets[b], pts[to_pts]) + losses.chamfer_to(pts, targets[b], to_tgt)
        if out.jac is not None:
            dist.append(losses.distortion_loss(out.jac[:, b].reshape(-1, 3, 2), cfg.loss.eps))
    dist_t = torch.stack(dist).mean() if dist else torch.zeros((), device=uv.device)
    return rec / B, dist_t, K * B * N, torch.stack(dists)
