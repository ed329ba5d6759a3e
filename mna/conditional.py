"""The conditional atlas: an encoder and a :class:`mna.model.NeuralAtlas` with a latent code.

``z = encoder(input)`` conditions every chart ``phi_k`` and labelled-probability net ``l_k``
(the fit stage's model with ``latent = D``). The latent enters each MLP only as an additive
bias ``z W_z`` of the layers that see the input (chart: first and skip layer; label net:
first layer), so for one shape the conditional atlas *is* a plain per-shape atlas whose
biases absorb ``z W_z``: :func:`bake` builds that ``NeuralAtlas(latent=0)``, which is how a
feed-forward reconstruction becomes an ordinary run folder (``mna.run.load_model`` reads it).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import torch
from torch import nn

from mna.checkpoint import read_state
from mna.encoders import build_encoder
from mna.model import BatchedLinear, NeuralAtlas
from mna.train_config import TrainConfig, from_dict
from mnacore.errors import MnaError

#: tag stored in every training checkpoint (tells it apart from a per-shape fit's).
CHECKPOINT_FORMAT = "mna-train-1"


class ConditionalAtlas(nn.Module):
    """``encoder`` (input -> ``z (B, D)``) and ``atlas`` (NeuralAtlas with ``latent = D``)."""

    def __init__(self, encoder: nn.Module, atlas: NeuralAtlas):
        super().__init__()
        self.encoder, self.atlas = encoder, atlas

    @classmethod
    def from_config(cls, cfg: TrainConfig) -> "ConditionalAtlas":
        enc = build_encoder(cfg.encoder.kind, cfg.model.latent, cfg.encoder.pointnet_widths, cfg.encoder.pretrained)
        return cls(enc, NeuralAtlas.from_config(cfg.model, cfg.ablation))

    def encode(self, inputs: torch.Tensor) -> torch.Tensor:
        """``points (B, P, 3)`` or ``image (B, 3, H, W)`` -> ``z (B, D)``."""
        return self.encoder(inputs)


def _bake_linear(layer: BatchedLinear, n_keep: int, bias: torch.Tensor | None) -> BatchedLinear:
    """A copy of ``layer`` keeping its first ``n_keep`` input rows, ``bias`` added to ``b``.

    The kept rows are the *effective* weight (weight norm included); the copy's gain is set
    to their norm, so its own weight norm reproduces them (to float rounding).
    """
    w = layer.weight().detach()[:, :n_keep].clone()
    K, _, out = w.shape
    new = BatchedLinear(K, n_keep, out, layer.weight_norm)
    with torch.no_grad():
        new.v.copy_(w)
        new.b.copy_(layer.b.detach() + (0 if bias is None else bias))
        if layer.weight_norm:
            new.g.copy_(w.norm(dim=1))
    return new.to(w.device)


@torch.no_grad()
def bake(atlas: NeuralAtlas, z: torch.Tensor) -> NeuralAtlas:
    """Per-shape ``NeuralAtlas(latent=0)`` equal to ``atlas`` conditioned on ``z (1, D)``."""
    if z.dim() != 2 or z.shape[0] != 1 or z.shape[1] != atlas.latent:
        raise ValueError(f"bake needs z of shape (1, {atlas.latent}), got {tuple(z.shape)}")
    chart, label = atlas.chart, atlas.label
    width = chart.hidden[0].v.shape[2]
    out = NeuralAtlas(
        atlas.charts, width, len(chart.hidden), chart.skip,
        label.hidden[0].v.shape[2] if label is not None else 1, len(label.hidden) if label is not None else 1,
        label.octaves if label is not None else 0, latent=0, label_on_uv=atlas.label_on_uv,
        occupancy=atlas.occupancy, chart_octaves=chart.octaves,
    ).to(z.device)
    if chart.octaves:
        out.chart.window.copy_(chart.window)
    D = atlas.latent
    for i, layer in enumerate(chart.hidden):
        fan_in = layer.v.shape[1]
        if i == 0 or i == chart.skip:
            n_keep = fan_in - D
            zb = torch.einsum("bd,kdo->kbo", z, layer.weight()[:, n_keep:])[:, 0]  # (K, out)
            out.chart.hidden[i] = _bake_linear(layer, n_keep, zb)
        else:
            out.chart.hidden[i].load_state_dict(layer.state_dict())
    out.chart.out.load_state_dict(chart.out.state_dict())
    if label is not None:
        first = label.hidden[0]
        n_keep = first.v.shape[1] - D
        zb = torch.einsum("bd,kdo->kbo", z, first.weight()[:, n_keep:])[:, 0]
        out.label.hidden[0] = _bake_linear(first, n_keep, zb)
        for i in range(1, len(label.hidden)):
            out.label.hidden[i].load_state_dict(label.hidden[i].state_dict())
        out.label.out.load_state_dict(label.out.state_dict())
    out.c.copy_(atlas.c)
    return out.eval()


@dataclass
class LoadedCheckpoint:
    model: ConditionalAtlas
    cfg: TrainConfig
    state: dict
    path: Path


def load_checkpoint(path: str | Path, device: str | torch.device = "cpu") -> LoadedCheckpoint:
    """A training checkpoint -> model (eval mode), its config and the raw state.

    Accepts the checkpoint file or a training folder holding ``checkpoint.pt``.
    """
    path = Path(path)
    if path.is_dir():
        path = path / "checkpoint.pt"
    if not path.is_file():
        raise MnaError(f"checkpoint not found: {path}")
    state = read_state(path, map_location=device)
    if not isinstance(state, dict) or state.get("format") != CHECKPOINT_FORMAT:
        raise MnaError(f"{path} is not a training checkpoint of `mna train` (a per-shape fit's run? "
                       "use `mna extract` for those)")
    try:
        cfg = from_dict(state["config"]).validate()
    except KeyError:
        raise MnaError(f"{path} has no 'config'") from None
    model = ConditionalAtlas.from_config(cfg).to(device)
    load_state(model, state["model"], path)
    return LoadedCheckpoint(model.eval(), cfg, state, path)


def load_state(model: nn.Module, weights: dict, path: str | Path) -> None:
    """``load_state_dict`` with a one-line error when the architecture differs."""
    try:
        model.load_state_dict(weights)
    except RuntimeError as exc:
        lines = [s.strip() for s in str(exc).splitlines() if s.strip()]
        detail = lines[1] if len(lines) > 1 else lines[0]
        raise MnaError(f"checkpoint {path} is for a different architecture than its config: {detail}") from None
