"""Inference (paper Sec. 4.3): the PU constant c, the domain, point and mesh extraction.

Everything here runs without gradients and in chunks, so grids of 256^2 per chart or
hundreds of thousands of samples fit in memory on a small machine.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import torch

from mna.model import NeuralAtlas, flush_denormals
from mnacore.charts import kept_mesh
from mnacore.grid import grid_uv

#: samples per chart per forward chunk at inference.
CHUNK = 16384


def uniform_uv(charts: int, count: int, generator: torch.Generator, batch: int = 1,
               device: str | torch.device = "cpu") -> torch.Tensor:
    """``(K, B, count, 2)`` UV samples uniform in ``(-1, 1)^2`` (drawn on the CPU for determinism)."""
    uv = torch.rand(charts, batch, count, 2, generator=generator) * 2.0 - 1.0
    return uv.to(device)


class Evaluated(NamedTuple):
    """Chart points ``x (K, B, N, 3)``, occupancy ``o (K, B, N)`` and optional ``jac (K, B, N, 3, 2)``."""

    x: torch.Tensor
    occ: torch.Tensor
    jac: torch.Tensor | None


@torch.no_grad()
def evaluate(model: NeuralAtlas, uv: torch.Tensor, z: torch.Tensor | None = None, jacobian: bool = False) -> Evaluated:
    """Chunked ``phi``, ``o`` (and Jacobian) at ``uv (K, B, N, 2)``."""
    xs, os_, js = [], [], []
    with flush_denormals():
        for chunk in uv.split(CHUNK, dim=2):
            out = model.chart(chunk, z, jacobian=jacobian)
            xs.append(out.x)
            os_.append(model.occupancy_value(chunk, out.x, z))
            if jacobian:
                js.append(out.jac)
    return Evaluated(torch.cat(xs, 2), torch.cat(os_, 2), torch.cat(js, 2) if jacobian else None)


@torch.no_grad()
def labelled_probabilities(model: NeuralAtlas, uv: torch.Tensor, z: torch.Tensor | None = None) -> torch.Tensor:
    """``l_k(phi_k(u))`` at ``uv (K, B, N, 2)`` -> ``(K, B, N)`` (c not applied)."""
    if model.label is None:
        return torch.ones(uv.shape[:-1], dtype=uv.dtype, device=uv.device)
    return torch.cat([
        torch.sigmoid(model.label_logits(chunk, model.chart(chunk, z).x, z))
        for chunk in uv.split(CHUNK, dim=2)
    ], 2)


def c_from_probabilities(probs: torch.Tensor, eta: float = 0.4) -> torch.Tensor:
    """PU constant ``c``: median of the top ``eta`` fraction of labelled probabilities ``probs (...)``.

    Per shape when ``probs`` is ``(K, B, N)``: returns ``(B,)`` pooled over charts.
    """
    flat = probs.transpose(0, 1).reshape(probs.shape[1], -1) if probs.dim() == 3 else probs.reshape(1, -1)
    top = max(1, int(math.ceil(eta * flat.shape[1])))
    values = flat.topk(top, dim=1).values
    return values.median(dim=1).values


def estimate_c(model: NeuralAtlas, generator: torch.Generator, samples: int, eta: float = 0.4,
               z: torch.Tensor | None = None, naive: bool = False) -> torch.Tensor:
    """Estimate and return ``c`` (B,); ``naive`` (plain binary classification ablation) gives 1."""
    batch = 1 if z is None else z.shape[0]
    device = next(model.parameters()).device
    if naive or model.label is None:
        return torch.ones(batch, device=device)
    uv = uniform_uv(model.charts, samples, generator, batch, device)
    return c_from_probabilities(labelled_probabilities(model, uv, z), eta)


def settle_c(model: NeuralAtlas, cfg) -> None:
    """Fix a per-shape atlas's ``c`` (a buffer saved with it) as a finished fit does: from
    ``cfg.c_samples`` UV samples drawn with seed ``cfg.seed + 1``."""
    gen = torch.Generator().manual_seed(cfg.seed + 1)
    model.c.fill_(float(estimate_c(model, gen, cfg.c_samples, cfg.eta, naive=cfg.ablation.naive_classifier)[0]))


class PointSample(NamedTuple):
    """Accepted surface points ``points (P, 3)`` with their ``uv (P, 2)`` and ``chart (P,)``."""

    points: np.ndarray
    uv: np.ndarray
    chart: np.ndarray
    acceptance: float


def rejection_sample(model: NeuralAtlas, count: int, generator: torch.Generator, tau: float = 0.5,
                     z: torch.Tensor | None = None, pilot: int = 4096, margin: float = 1.02) -> PointSample:
    """Two-step batch rejection sampling of ``count`` in-domain points (one shape).

    Step 1 draws a pilot batch per chart to estimate the acceptance rate ``r``; step 2
    draws ``margin * count / r`` samples over all charts at once and keeps in-domain ones,
    then randomly drops the surplus. The result lands within sampling noise of ``count``.
    """
    device = next(model.parameters()).device
    K = model.charts
    ev = evaluate(model, uniform_uv(K, pilot, generator, 1, device), z)
    rate = float((ev.occ > tau).float().mean())
    if rate == 0.0:
        return PointSample(np.zeros((0, 3)), np.zeros((0, 2)), np.zeros(0, np.int64), 0.0)
    per_chart = int(math.ceil(margin * count / (rate * K)))
    uv = uniform_uv(K, per_chart, generator, 1, device)
    ev = evaluate(model, uv, z)
    keep = (ev.occ[:, 0] > tau)  # (K, N)
    k_idx, n_idx = keep.nonzero(as_tuple=True)
    if len(k_idx) > count:
        pick = torch.randperm(len(k_idx), generator=generator)[:count].sort().values
        k_idx, n_idx = k_idx[pick.to(k_idx.device)], n_idx[pick.to(n_idx.device)]
    pts = ev.x[k_idx, 0, n_idx].cpu().double().numpy()
    return PointSample(pts, uv[k_idx, 0, n_idx].cpu().double().numpy(), k_idx.cpu().numpy(), rate)


class ChartGrid(NamedTuple):
    """Regular UV grid per chart and the kept mesh (see docs/run_folder.md)."""

    uv: np.ndarray  # (K, G, G, 2)
    xyz: np.ndarray  # (K, G, G, 3), model frame
    occ: np.ndarray  # (K, G, G)
    vertices: np.ndarray  # (V, 3)
    faces: np.ndarray  # (F, 3)
    vertex_uv: np.ndarray  # (V, 2)
    vertex_chart: np.ndarray  # (V,)
    face_chart: np.ndarray  # (F,)
    grid_index: np.ndarray  # (V,)


def extract_grid(model: NeuralAtlas, resolution: int, tau: float = 0.5, z: torch.Tensor | None = None) -> ChartGrid:
    """Evaluate every chart on a ``G x G`` grid; keep triangles whose 3 vertices are in-domain."""
    device = next(model.parameters()).device
    K, G = model.charts, resolution
    uv_np = grid_uv(G)
    uv = torch.from_numpy(uv_np.reshape(1, 1, G * G, 2)).float().expand(K, 1, G * G, 2).contiguous().to(device)
    ev = evaluate(model, uv, z)
    xyz = ev.x[:, 0].cpu().double().numpy().reshape(K, G, G, 3)
    occ = ev.occ[:, 0].cpu().double().numpy().reshape(K, G, G)
    kept = kept_mesh(occ, tau)
    return ChartGrid(
        uv=np.broadcast_to(uv_np, (K, G, G, 2)).astype(np.float32),
        xyz=xyz, occ=occ,
        vertices=xyz.reshape(-1, 3)[kept.grid_index], faces=kept.faces,
        vertex_uv=np.broadcast_to(uv_np.reshape(-1, 2), (K, G * G, 2)).reshape(-1, 2)[kept.grid_index],
        vertex_chart=kept.grid_index // (G * G), face_chart=kept.face_chart, grid_index=kept.grid_index,
    )
