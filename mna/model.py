"""The neural atlas: K charts ``phi_k`` and K labelled-probability nets ``l_k``, evaluated batched.

Shape vocabulary: ``K`` charts, ``B`` shapes in a batch (1 for a per-shape fit), ``N``
samples per chart and shape, ``D`` latent size. Inputs are laid out ``(K, B, N, d)``.
Every chart has its own weights, stored as ``(K, in, out)`` tensors and applied with one
``baddbmm`` for all charts: there is no Python loop over charts in the hot path.

Chart ``phi_k: (-1, 1)^2 -> R^3`` (paper, Sec. 4): MLP with weight normalisation,
Softplus(beta=100), and the input re-concatenated after the 2nd hidden layer.
``l_k: R^3 -> [0, 1]`` is a ReLU MLP on a positional encoding of the 3D point with a
sigmoid output. An optional latent code ``z (B, D)`` conditions every layer that sees the
input (first layer and the skip layer), which is what the conditional version needs.

The exact Jacobian ``d phi / d(u, v)`` is propagated in forward mode (two tangents through
the same weights), which is cheaper here than reverse-mode autograd and stays
differentiable with respect to the weights for the distortion loss.
"""
from __future__ import annotations

import contextlib
import math
from typing import Iterator, NamedTuple

import torch
from torch import nn
from torch.nn import functional as F

SOFTPLUS_BETA = 100.0
_flushing = False


@contextlib.contextmanager
def flush_denormals(enabled: bool = True) -> Iterator[None]:
    """Flush denormals to zero on the CPU inside the block, then restore the previous state.

    Softplus with beta = 100 evaluates ``exp(-100 |x|)``, which underflows into denormals for
    most activations; denormal arithmetic made every chart evaluation about 8x slower here
    (117 ms -> 15 ms for 3.5M activations). It is a process-wide CPU mode, and some scipy
    code (cKDTree builds) misbehaves under it, so it is only ever switched on around torch
    work and off again (``enabled=False`` turns it off for a nested block).
    """
    global _flushing
    previous = _flushing
    torch.set_flush_denormal(enabled)
    _flushing = enabled
    try:
        yield
    finally:
        torch.set_flush_denormal(previous)
        _flushing = previous


def wide(t: torch.Tensor) -> torch.Tensor:
    """``t`` in at least float32 (float16/bfloat16 from autocast are widened; float64 stays)."""
    return t.float() if t.dtype in (torch.float16, torch.bfloat16) else t


class BatchedLinear(nn.Module):
    """K independent linear layers ``y_k = x_k W_k + b_k`` with optional weight norm.

    Weight norm (Salimans & Kingma 2016): ``W[:, :, o] = g[o] * v[:, :, o] / ||v[:, :, o]||``,
    one gain per output unit, as ``torch.nn.utils.weight_norm`` does for ``nn.Linear``.
    """

    def __init__(self, charts: int, fan_in: int, fan_out: int, weight_norm: bool = True):
        super().__init__()
        bound = 1.0 / math.sqrt(fan_in)
        self.v = nn.Parameter(torch.empty(charts, fan_in, fan_out).uniform_(-bound, bound))
        self.b = nn.Parameter(torch.empty(charts, fan_out).uniform_(-bound, bound))
        self.weight_norm = weight_norm
        if weight_norm:
            self.g = nn.Parameter(self.v.detach().norm(dim=1))

    def weight(self) -> torch.Tensor:
        """Effective weight ``(K, in, out)``."""
        if not self.weight_norm:
            return self.v
        return self.v * (self.g / self.v.norm(dim=1)).unsqueeze(1)


def _apply(weight: torch.Tensor, bias: torch.Tensor | None, x: torch.Tensor) -> torch.Tensor:
    """``x (K, M, in) @ weight (K, in, out) (+ bias (K, out))``."""
    if bias is None:
        return torch.bmm(x, weight)
    return torch.baddbmm(bias.unsqueeze(1), x, weight)


def _latent_bias(weight_z: torch.Tensor, z: torch.Tensor | None, n: int) -> torch.Tensor | None:
    """Per-shape bias ``z_b W_z`` of shape ``(K, B*N, out)`` (None without a latent)."""
    if z is None:
        return None
    zb = torch.einsum("bd,kdo->kbo", z, weight_z)  # (K, B, out)
    return zb.repeat_interleave(n, dim=1)


class ChartForward(NamedTuple):
    """Chart points ``x (K, B, N, 3)`` and, if asked for, Jacobians ``jac (K, B, N, 3, 2)``."""

    x: torch.Tensor
    jac: torch.Tensor | None


class ChartNet(nn.Module):
    """``phi_k(u; z)`` for all charts: width ``W``, ``depth`` hidden layers, skip at ``skip``."""

    def __init__(self, charts: int, width: int = 512, depth: int = 4, skip: int = 2, latent: int = 0,
                 weight_norm: bool = True, octaves: int = 0):
        super().__init__()
        if depth < 2 or not 0 < skip < depth:
            raise ValueError(f"chart net needs depth >= 2 and 0 < skip < depth, got depth={depth}, skip={skip}")
        self.charts, self.latent, self.skip, self.octaves = charts, latent, skip, octaves
        self.in_dim = 2 * (1 + 2 * octaves)
        if octaves:
            # how many octaves are open (:func:`windowed_encoding`); a fit opens them as it goes,
            # and a finished or loaded model uses what its fit ended with
            self.register_buffer("window", torch.tensor(float(octaves)))
        layers = []
        for i in range(depth):
            fan_in = self.in_dim + latent if i == 0 else width + (self.in_dim + latent if i == skip else 0)
            layers.append(BatchedLinear(charts, fan_in, width, weight_norm))
        self.hidden = nn.ModuleList(layers)
        self.out = BatchedLinear(charts, width, 3, weight_norm)

    def forward(self, uv: torch.Tensor, z: torch.Tensor | None = None, jacobian: bool = False) -> ChartForward:
        """``uv (K, B, N, 2)``, ``z (B, D)`` or None -> points (and Jacobians) per chart."""
        K, B, N, _ = uv.shape
        M = B * N
        u = uv.reshape(K, M, 2)
        d_u = None  # d enc / d(u, v): (K, 2, M, in_dim); None for the plain input (the identity)
        if self.octaves:
            u, d_u = windowed_encoding(u, self.octaves, self.window, jacobian)
        E = self.in_dim
        h = None
        t = None  # tangents d h / d(u, v): (K, 2, M, width)
        for i, layer in enumerate(self.hidden):
            w = layer.weight()
            takes_input = i == 0 or i == self.skip
            n_h = 0 if i == 0 else w.shape[1] - (E + self.latent if takes_input else 0)
            pre = layer.b.unsqueeze(1)
            if n_h:
                pre = torch.baddbmm(pre, h, w[:, :n_h])
            if takes_input:
                w_u = w[:, n_h:n_h + E]
                pre = torch.baddbmm(pre, u, w_u)
                if self.latent:
                    pre = pre + _latent_bias(w[:, n_h + E:], z, N)
            if jacobian:
                # chain rule; d u / d(u, v) is the identity, so the plain input's tangent is a row of W_u
                tp = torch.bmm(t.reshape(K, 2 * M, n_h), w[:, :n_h]).view(K, 2, M, -1) if n_h else 0.0
                if takes_input:
                    tp = tp + (w_u.unsqueeze(2) if d_u is None
                               else torch.bmm(d_u.reshape(K, 2 * M, E), w_u).view(K, 2, M, -1))
                # d softplus_beta(x) / dx = sigmoid(beta x)
                t = tp * torch.sigmoid(SOFTPLUS_BETA * pre).unsqueeze(1)
            h = F.softplus(pre, beta=SOFTPLUS_BETA)
        # The output layer runs in float32 even under autocast, so positions, Jacobians and every
        # loss built on them are float32: float16 positions are quantised to ~5e-4 of the unit
        # ball, and g = J^T J from float16 Jacobians would lose det(g) to cancellation.
        with torch.autocast(h.device.type, enabled=False):
            w = self.out.weight()
            x = torch.baddbmm(self.out.b.unsqueeze(1), wide(h), w).view(K, B, N, 3)
            jac = None
            if jacobian:
                jt = torch.bmm(wide(t.reshape(K, 2 * M, -1)), w).view(K, 2, B, N, 3)
                jac = jt.permute(0, 2, 3, 4, 1)  # (K, B, N, 3, 2): columns d/du, d/dv
        return ChartForward(x, jac)


def octave_weights(octaves: int, window: torch.Tensor | float, like: torch.Tensor) -> torch.Tensor:
    """Weight of each octave ``i < octaves`` with ``window`` of them open: 0 below ``i``, 1 above
    ``i + 1``, a cosine ramp between (coarse-to-fine, as BARF opens a NeRF's encoding), so a
    fit can place its charts with the smooth input and add detail once they lie right."""
    a = torch.as_tensor(window, dtype=like.dtype, device=like.device)
    i = torch.arange(octaves, dtype=like.dtype, device=like.device)
    return 0.5 * (1.0 - torch.cos(math.pi * (a - i).clamp(0.0, 1.0)))


def windowed_encoding(u: torch.Tensor, octaves: int, window: torch.Tensor | float,
                      jacobian: bool = False) -> tuple[torch.Tensor, torch.Tensor | None]:
    """``[u, w_i sin(2^i pi u), w_i cos(2^i pi u)]_{i<octaves}`` of ``u (..., d)`` (weights
    :func:`octave_weights`; per coordinate its sines, then its cosines) and, if asked (for
    ``u (K, M, 2)``), its derivatives ``(K, 2, M, 2 (1 + 2 octaves))`` along u and along v."""
    freqs = (2.0 ** torch.arange(octaves, dtype=u.dtype, device=u.device)) * math.pi
    wts = octave_weights(octaves, window, u)
    ang = u.unsqueeze(-1) * freqs  # (K, M, 2, octaves)
    sin, cos = torch.sin(ang), torch.cos(ang)
    enc = torch.cat([u, torch.cat([wts * sin, wts * cos], dim=-1).flatten(-2)], dim=-1)
    if not jacobian:
        return enc, None
    K, M, _ = u.shape
    d = []
    for axis in range(2):  # only coordinate ``axis`` of u moves
        one = torch.zeros(2, dtype=u.dtype, device=u.device)
        one[axis] = 1.0
        mask = one.view(1, 1, 2, 1)
        d_sin, d_cos = mask * wts * freqs * cos, -mask * wts * freqs * sin
        d.append(torch.cat([one.expand(K, M, 2), torch.cat([d_sin, d_cos], dim=-1).flatten(-2)], dim=-1))
    return enc, torch.stack(d, dim=1)


def positional_encoding(p: torch.Tensor, octaves: int) -> torch.Tensor:
    """``[p, sin(2^i pi p), cos(2^i pi p)]_{i<octaves}``: ``(..., d) -> (..., d (1 + 2 octaves))``
    (:func:`windowed_encoding` with every octave open: each weight is exactly 1)."""
    return windowed_encoding(p, octaves, float(octaves))[0] if octaves else p


class LabelNet(nn.Module):
    """Labelled-probability nets ``l_k(p; z) in [0, 1]`` for all charts (ReLU MLP, sigmoid out).

    ``in_dim`` is 3 for the paper's reformulation (``p = phi_k(u)``) and 2 for the ablation
    that classifies UV directly; ``octaves`` = 0 disables the positional encoding.
    """

    def __init__(self, charts: int, in_dim: int = 3, width: int = 256, depth: int = 4, octaves: int = 6,
                 latent: int = 0):
        super().__init__()
        self.octaves, self.latent = octaves, latent
        enc_dim = in_dim * (1 + 2 * octaves)
        dims = [enc_dim + latent] + [width] * depth
        self.hidden = nn.ModuleList(BatchedLinear(charts, a, b, weight_norm=False) for a, b in zip(dims, dims[1:]))
        self.out = BatchedLinear(charts, width, 1, weight_norm=False)

    def logits(self, p: torch.Tensor, z: torch.Tensor | None = None) -> torch.Tensor:
        """``p (K, B, N, in_dim)`` -> logits ``(K, B, N)``."""
        K, B, N, _ = p.shape
        h = positional_encoding(p.reshape(K, B * N, -1), self.octaves)
        for i, layer in enumerate(self.hidden):
            w = layer.weight()
            if i == 0 and self.latent:
                pre = _apply(w[:, : -self.latent], layer.b, h) + _latent_bias(w[:, -self.latent:], z, N)
            else:
                pre = _apply(w, layer.b, h)
            h = F.relu(pre)
        return _apply(self.out.weight(), self.out.b, h).view(K, B, N)

    def forward(self, p: torch.Tensor, z: torch.Tensor | None = None) -> torch.Tensor:
        return torch.sigmoid(self.logits(p, z))


class NeuralAtlas(nn.Module):
    """Charts ``phi`` plus labelled-probability nets ``l`` (absent in AtlasNet mode).

    ``label_on_uv`` is the paper's "no reformulation" ablation: ``l_k`` sees ``u``, not
    ``phi_k(u)``. ``c`` (the PU constant) is a buffer set after training by
    :func:`mna.inference.estimate_c`; the domain is ``l / c > tau``.
    """

    def __init__(self, charts: int, chart_width: int = 512, chart_depth: int = 4, chart_skip: int = 2,
                 label_width: int = 256, label_depth: int = 4, octaves: int = 6, latent: int = 0,
                 label_on_uv: bool = False, occupancy: bool = True, chart_octaves: int = 0):
        super().__init__()
        self.charts, self.latent = charts, latent
        self.label_on_uv, self.occupancy = label_on_uv, occupancy
        self.chart = ChartNet(charts, chart_width, chart_depth, chart_skip, latent, octaves=chart_octaves)
        self.label = (
            LabelNet(charts, 2 if label_on_uv else 3, label_width, label_depth, octaves, latent)
            if occupancy else None
        )
        self.register_buffer("c", torch.tensor(1.0))

    @classmethod
    def from_config(cls, model_cfg, ablation_cfg) -> "NeuralAtlas":
        m = model_cfg
        return cls(m.charts, m.chart_width, m.chart_depth, m.chart_skip, m.label_width, m.label_depth,
                   m.octaves, m.latent, label_on_uv=ablation_cfg.occupancy_on_uv,
                   occupancy=not ablation_cfg.atlasnet, chart_octaves=m.chart_octaves)

    def label_logits(self, uv: torch.Tensor, x: torch.Tensor, z: torch.Tensor | None = None) -> torch.Tensor:
        """Logits of ``l_k`` at chart points ``x (K, B, N, 3)`` (or at ``uv`` in the ablation)."""
        return self.label.logits(uv if self.label_on_uv else x, z)

    def occupancy_value(self, uv: torch.Tensor, x: torch.Tensor, z: torch.Tensor | None = None) -> torch.Tensor:
        """``o_k = l_k / c``, shape ``(K, B, N)``; all ones (full squares) in AtlasNet mode."""
        if self.label is None:
            return torch.ones(x.shape[:-1], dtype=x.dtype, device=x.device)
        return torch.sigmoid(self.label_logits(uv, x, z)) / self.c
