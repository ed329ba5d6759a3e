"""The batched model against naive per-chart loops, and forward-mode Jacobians against autograd."""
from __future__ import annotations

import math

import pytest
import torch
from torch.nn import functional as F

from mna.model import SOFTPLUS_BETA, ChartNet, LabelNet, octave_weights, positional_encoding, windowed_encoding


def _naive_chart(net: ChartNet, k: int, u: torch.Tensor, z: torch.Tensor | None) -> torch.Tensor:
    """phi_k for one chart with plain matmuls and explicit concatenation: u (M, 2), z (M, D)."""
    inp = u if z is None else torch.cat([u, z], -1)
    h = inp
    for i, layer in enumerate(net.hidden):
        if i == net.skip:
            h = torch.cat([h, inp], -1)
        h = F.softplus(h @ layer.weight()[k] + layer.b[k], beta=SOFTPLUS_BETA)
    return h @ net.out.weight()[k] + net.out.b[k]


@pytest.mark.parametrize("latent", [0, 5])
def test_batched_charts_match_naive_loop(latent):
    torch.manual_seed(0)
    K, B, N = 3, 2, 17
    net = ChartNet(K, width=24, latent=latent).double()
    uv = torch.rand(K, B, N, 2, dtype=torch.float64) * 2 - 1
    z = torch.randn(B, latent, dtype=torch.float64) if latent else None
    x = net(uv, z).x
    for k in range(K):
        for b in range(B):
            zz = z[b].expand(N, latent) if latent else None
            ref = _naive_chart(net, k, uv[k, b], zz)
            torch.testing.assert_close(x[k, b], ref, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("latent,octaves,window", [(0, 0, 0.0), (4, 0, 0.0), (0, 3, 3.0), (0, 3, 1.4), (4, 3, 2.5)])
def test_forward_mode_jacobian_matches_autograd(latent, octaves, window):
    """Also on the windowed sine/cosine encoding of (u, v), where the forward-mode Jacobian
    carries the encoding's own derivative (frequencies up to 4 pi, so a missing factor shows)."""
    torch.manual_seed(1)
    K, B, N = 2, 2, 11
    net = ChartNet(K, width=16, latent=latent, octaves=octaves).double()
    if octaves:
        net.window.fill_(window)
    uv = (torch.rand(K, B, N, 2, dtype=torch.float64) * 2 - 1).requires_grad_(True)
    z = torch.randn(B, latent, dtype=torch.float64) if latent else None
    out = net(uv, z, jacobian=True)
    for c in range(3):
        (grad,) = torch.autograd.grad(out.x[..., c].sum(), uv, retain_graph=True)
        # softplus switches to the identity above beta*x = 20, where its slope is 1 - 2e-9
        torch.testing.assert_close(out.jac[..., c, :], grad, rtol=1e-7, atol=1e-9)


def test_jacobian_is_differentiable_in_weights():
    torch.manual_seed(2)
    net = ChartNet(1, width=8).double()
    uv = torch.rand(1, 1, 5, 2, dtype=torch.float64) * 2 - 1
    w = net.hidden[1].v

    loss = net(uv, jacobian=True).jac.pow(2).sum()
    (g,) = torch.autograd.grad(loss, w)
    # finite difference along a random direction
    d = torch.randn_like(w)
    h = 1e-6
    with torch.no_grad():
        w += h * d
        lp = net(uv, jacobian=True).jac.pow(2).sum()
        w -= 2 * h * d
        lm = net(uv, jacobian=True).jac.pow(2).sum()
        w += h * d
    assert float((g * d).sum()) == pytest.approx(float((lp - lm) / (2 * h)), rel=1e-5)


def test_positional_encoding_layout():
    p = torch.tensor([[0.25, -0.5, 1.0]], dtype=torch.float64)
    enc = positional_encoding(p, 2)
    assert enc.shape == (1, 3 * (1 + 2 * 2))
    torch.testing.assert_close(enc[0, :3], p[0])
    # sin(2^i pi p) for i = 0, 1 then cos, per coordinate
    import math
    x = 0.25
    torch.testing.assert_close(enc[0, 3:7], torch.tensor(
        [math.sin(math.pi * x), math.sin(2 * math.pi * x), math.cos(math.pi * x), math.cos(2 * math.pi * x)],
        dtype=torch.float64))


def test_label_net_matches_naive_loop():
    torch.manual_seed(3)
    K, N = 2, 9
    net = LabelNet(K, in_dim=3, width=12, depth=2, octaves=3).double()
    p = torch.randn(K, 1, N, 3, dtype=torch.float64)
    out = net(p)
    for k in range(K):
        h = positional_encoding(p[k, 0], 3)
        for layer in net.hidden:
            h = torch.relu(h @ layer.weight()[k] + layer.b[k])
        ref = torch.sigmoid(h @ net.out.weight()[k] + net.out.b[k])[:, 0]
        torch.testing.assert_close(out[k, 0], ref)
    assert ((out > 0) & (out < 1)).all()


def test_chart_outputs_stay_float32_under_autocast():
    """Mixed precision (autocast) runs the hidden layers in low precision, but positions and
    Jacobians come out in float32: float16 positions are quantised to ~5e-4 and g = J^T J from
    float16 Jacobians loses det(g) to cancellation."""
    torch.manual_seed(0)
    net = ChartNet(charts=2, width=64, depth=4, skip=2)
    uv = torch.rand(2, 1, 500, 2) * 2 - 1
    ref = net(uv, jacobian=True)
    with torch.autocast("cpu", dtype=torch.bfloat16):
        low = net(uv, jacobian=True)
        hidden = F.linear(uv, torch.ones(3, 2))  # autocast is on: a plain matmul comes out bfloat16
    assert hidden.dtype == torch.bfloat16
    assert low.x.dtype == low.jac.dtype == torch.float32
    # bfloat16 hidden layers (8-bit mantissa) move the outputs a little, not to bfloat16's grid
    assert (low.x - ref.x).abs().max() < 0.05 * ref.x.abs().max()
    assert (low.jac - ref.jac).abs().max() < 0.05 * ref.jac.abs().max()
    assert not torch.equal(low.x, low.x.bfloat16().float())
    double = ChartNet(charts=2, width=64, depth=4, skip=2).double()
    assert double(uv.double(), jacobian=True).jac.dtype == torch.float64  # wider stays wider


def test_octave_window_opens_coarse_to_fine():
    """Octave i is shut below window i, open above i + 1, half open at i + 0.5; shut octaves
    leave only the plain (u, v) in the encoding."""
    u = torch.tensor([[[0.3, -0.7]]], dtype=torch.float64)
    w = octave_weights(4, 1.5, u)
    torch.testing.assert_close(w, torch.tensor([1.0, 0.5, 0.0, 0.0], dtype=torch.float64))
    enc, _ = windowed_encoding(u, 4, 0.0)
    assert enc.shape == (1, 1, 2 * (1 + 2 * 4))
    torch.testing.assert_close(enc[..., :2], u)
    assert float(enc[..., 2:].abs().max()) == 0.0
    enc, _ = windowed_encoding(u, 4, 4.0)  # fully open: per coordinate its sines, then cosines
    f = math.pi * 2.0 ** torch.arange(4, dtype=torch.float64)
    want = torch.cat([u[0, 0], torch.sin(0.3 * f), torch.cos(0.3 * f), torch.sin(-0.7 * f), torch.cos(-0.7 * f)])
    torch.testing.assert_close(enc[0, 0], want)
    torch.testing.assert_close(positional_encoding(u, 4), enc)
