"""Encoders: an input (point cloud or image) -> latent code ``z (B, D)`` conditioning the atlas.

- :class:`PointNet`: a shared per-point MLP (ReLU, **no batch norm**: batch statistics would
  couple the items of a batch and differ between ranks), max-pooled over the points, then
  ``Linear + ReLU`` to ``D`` (as the paper's encoder head).
- :class:`ResNet18`: torchvision's ResNet-18 with its classifier replaced by ``Linear + ReLU``
  to ``D``. ImageNet weights are used only when already in the local torch hub cache; the
  encoder records which weights it started from (``weights``).

Shapes: ``B`` items, ``P`` points, ``H W`` image.
"""
from __future__ import annotations

from pathlib import Path

import torch
from torch import nn

from mnacore.errors import MnaError

#: torchvision's ImageNet ResNet-18 checkpoint file name (torch hub cache, ``checkpoints/``).
RESNET18_IMAGENET = "resnet18-f37072fd.pth"
IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)
TORCHVISION_HINT = ("the image encoder needs torchvision built for this torch "
                    f"({torch.__version__}): pip install torchvision matching it "
                    "(torch 2.13 pairs with torchvision 0.28; a CPU-only torch needs the CPU torchvision build)")


class PointNet(nn.Module):
    """``points (B, P, 3)`` -> ``z (B, D)``: per-point MLP ``widths``, max over points, Linear+ReLU."""

    def __init__(self, latent: int, widths: tuple[int, ...] | list[int] = (64, 128, 1024)):
        super().__init__()
        if not widths or min(widths) < 1:
            raise MnaError(f"encoder.pointnet_widths must be positive widths, got {list(widths)}")
        dims = [3, *widths]
        self.mlp = nn.ModuleList(nn.Linear(a, b) for a, b in zip(dims, dims[1:]))
        self.head = nn.Linear(dims[-1], latent)
        self.weights = "random"

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        h = points
        for i, layer in enumerate(self.mlp):
            h = layer(h)
            if i < len(self.mlp) - 1:  # PointNet's last shared layer is linear before the max
                h = torch.relu(h)
        return torch.relu(self.head(h.max(dim=1).values))


def imagenet_weights_path() -> Path:
    """Where torchvision would cache the ImageNet ResNet-18 weights (never downloaded here)."""
    return Path(torch.hub.get_dir()) / "checkpoints" / RESNET18_IMAGENET


def _import_torchvision():
    try:
        import torchvision  # noqa: F401 (optional heavy backend, imported where used)
        from torchvision.models import resnet18
    except Exception as exc:  # ImportError, or a torchvision built for another torch (RuntimeError)
        raise MnaError(f"{TORCHVISION_HINT} ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''})") from None
    return resnet18


class ResNet18(nn.Module):
    """``image (B, 3, H, W)`` in ``[0, 1]`` -> ``z (B, D)`` (ImageNet-normalised inside)."""

    def __init__(self, latent: int, pretrained: bool = False):
        super().__init__()
        resnet18 = _import_torchvision()
        self.core = resnet18(weights=None)
        self.weights = "random"
        if pretrained:
            path = imagenet_weights_path()
            if path.is_file():
                self.core.load_state_dict(torch.load(path, map_location="cpu", weights_only=True))
                self.weights = f"imagenet ({path.name})"
            else:
                self.weights = f"random (ImageNet weights not found at {path})"
        self.core.fc = nn.Linear(self.core.fc.in_features, latent)
        self.register_buffer("mean", torch.tensor(IMAGENET_MEAN).view(1, 3, 1, 1), persistent=False)
        self.register_buffer("std", torch.tensor(IMAGENET_STD).view(1, 3, 1, 1), persistent=False)

    def forward(self, image: torch.Tensor) -> torch.Tensor:
        return torch.relu(self.core((image - self.mean) / self.std))


def build_encoder(kind: str, latent: int, widths=(64, 128, 1024), pretrained: bool = False) -> nn.Module:
    """The encoder named by ``kind`` (``pointnet`` or ``resnet18``)."""
    if kind == "pointnet":
        return PointNet(latent, widths)
    if kind == "resnet18":
        return ResNet18(latent, pretrained)
    raise MnaError(f"unknown encoder {kind!r}; choose pointnet or resnet18")
