"""Typed configuration for training the conditional atlas on a dataset of shapes.

The atlas parts (``model``, ``loss``, ``ablation``) are the fit stage's own dataclasses, so
the objective (:func:`mna.objective.atlas_losses`) and inference read them unchanged through
:meth:`TrainConfig.fit_config`. Loading is strict: unknown keys and wrong types are errors
(:func:`mna.config.from_dict`), lists are checked here. The resolved config is saved beside
every training run and every reconstruction.
"""
from __future__ import annotations

import argparse
import copy
from dataclasses import dataclass, field, fields
from pathlib import Path

from mna import config as fit_config_mod
from mna.config import AtlasSettings, FitConfig, ModelConfig
from mnacore.errors import MnaError

LAYOUTS = ("meshes", "shapenet", "cloth3d")
INPUTS = ("points", "image")
ENCODERS = ("pointnet", "resnet18")


@dataclass
class DataConfig:
    """Where the shapes are and what one batch item holds (see docs/train.md for the layouts)."""

    layout: str = "meshes"
    """meshes (folder of meshes + ``<split>.lst``), shapenet (Occupancy-Networks preprocessed
    ShapeNet) or cloth3d (preprocessed CLOTH3D++)."""
    root: str = ""
    """Dataset folder."""
    classes: list[str] = field(default_factory=list)
    """Class folders to use (shapenet: synset ids such as 02691156; cloth3d: tshirt, dress, ...);
    empty = every class folder that has the split file."""
    input: str = "points"
    """Encoder input: points (a point cloud) or image (one rendered view, shapenet only)."""
    input_points: int = 2500
    """Points of the input cloud fed to the encoder."""
    target_points: int = 2500
    """Target surface points per item for L_rec (the paper draws the input and target from
    the same random subset: the smaller is a prefix of the larger)."""
    mesh_cache_points: int = 0
    """meshes layout: 0 samples fresh surface points every time; N > 0 samples N points once
    per mesh (deterministically) and draws subsets of them, like the point-cloud layouts."""
    image_size: int = 224
    """Image side in pixels after resizing (224 for ImageNet weights; the renders are 137)."""
    views: int = 24
    """Rendered views per object in ``img_choy2016`` (each view is one item)."""
    train_split: str = "train"
    val_split: str = "val"
    test_split: str = "test"
    workers: int = 0
    """DataLoader worker processes per rank (0 = load in the training process)."""


@dataclass
class EncoderConfig:
    """The encoder that turns an input into the latent code ``z (B, D)``, ``D = model.latent``."""

    kind: str = "pointnet"
    """pointnet (point clouds; no batch norm) or resnet18 (images; torchvision)."""
    pointnet_widths: list[int] = field(default_factory=lambda: [64, 128, 1024])
    """Widths of PointNet's shared per-point MLP; the last is the max-pooled feature."""
    pretrained: bool = False
    """resnet18: start from ImageNet weights if they are already in the local torch hub cache
    (never downloaded); the run records which weights were used."""


@dataclass
class TrainConfig(AtlasSettings):
    """Everything a training run needs; saved as ``config.yaml`` in the training folder.

    The atlas keys (``model``, ``loss``, ``ablation``, ``lr``, ``tau``, ...) are
    :class:`mna.config.AtlasSettings`, declared once for fits and training alike."""

    preset: str = "paper"
    model: ModelConfig = field(default_factory=lambda: ModelConfig(latent=1024, label_width=512))
    """As a fit's, with the paper's conditional sizes: latent D = 1024, label nets 512 wide."""
    out: str = "runs/train"
    """Training folder: config.yaml, checkpoint.pt, log.csv (or TensorBoard events), metrics.json."""
    encoder: EncoderConfig = field(default_factory=EncoderConfig)
    data: DataConfig = field(default_factory=DataConfig)
    uv_samples: int = 5000
    """UV samples per batch item, split evenly over the K charts (paper: 5,000)."""
    batch_size: int = 32
    """Effective batch over all ranks (paper: 32); each of W ranks takes batch_size / W."""
    epochs: int = 150
    lr_milestones: list[int] = field(default_factory=lambda: [120, 140, 145])
    """Epochs after which the lr is multiplied by ``lr_gamma`` (paper: 120, 140, 145)."""
    lr_gamma: float = 0.1
    amp: bool = True
    """Mixed precision (autocast fp16 + GradScaler) on CUDA; always off on the CPU. Steps whose
    scaled gradients are not finite are skipped; after ``amp_max_skips`` in a row it turns off."""
    amp_max_skips: int = 20
    checkpoint_every: int = 0
    """Also write checkpoint.pt every this many steps (0 = only at the end of each epoch)."""
    log_every: int = 10
    """Log losses every this many steps."""
    val_every: int = 3
    """Validate every this many epochs (paper: 3) and after the last; 0 = never."""
    val_shapes: int = 64
    """Validation items per validation (0 = the whole split)."""
    val_points: int = 5000
    """Points per shape for the validation Chamfer / F-score."""

    # -- derived ---------------------------------------------------------------------------
    def fit_config(self, latent: int | None = None) -> FitConfig:
        """The per-shape view: what ``atlas_losses``, inference and the run folder read."""
        shared = {f.name: copy.deepcopy(getattr(self, f.name)) for f in fields(AtlasSettings)}
        if latent is not None:
            shared["model"].latent = latent
        shared["preset"] = f"train:{self.preset}"
        return FitConfig(**shared, uv_samples=self.uv_samples // self.model.charts,
                         targets=self.data.target_points)

    def validate(self) -> "TrainConfig":
        d, m = self.data, self.model
        if d.layout not in LAYOUTS:
            raise MnaError(f"data.layout must be one of {', '.join(LAYOUTS)}, got {d.layout!r}")
        if d.input not in INPUTS:
            raise MnaError(f"data.input must be points or image, got {d.input!r}")
        if self.encoder.kind not in ENCODERS:
            raise MnaError(f"encoder.kind must be pointnet or resnet18, got {self.encoder.kind!r}")
        wanted = "pointnet" if d.input == "points" else "resnet18"
        if self.encoder.kind != wanted:
            raise MnaError(f"data.input {d.input} needs encoder.kind {wanted}, got {self.encoder.kind}")
        if d.input == "image" and d.layout != "shapenet":
            raise MnaError(f"data.input image needs data.layout shapenet (rendered views), got {d.layout}")
        if not d.root:
            raise MnaError("data.root is empty: set it to the dataset folder")
        self.validate_atlas()
        if m.latent < 1:
            raise MnaError(f"model.latent must be at least 1 for the conditional atlas, got {m.latent}")
        if self.uv_samples < m.charts:
            raise MnaError(f"uv_samples ({self.uv_samples}) must be at least model.charts ({m.charts})")
        for name in ("batch_size", "epochs", "log_every", "val_points", "amp_max_skips"):
            if getattr(self, name) < 1:
                raise MnaError(f"{name} must be positive, got {getattr(self, name)}")
        for name in ("input_points", "target_points", "image_size", "views"):
            if getattr(d, name) < 1:
                raise MnaError(f"data.{name} must be positive, got {getattr(d, name)}")
        for name in ("checkpoint_every", "val_every", "val_shapes"):
            if getattr(self, name) < 0:
                raise MnaError(f"{name} must be >= 0, got {getattr(self, name)}")
        if d.workers < 0 or d.mesh_cache_points < 0:
            raise MnaError("data.workers and data.mesh_cache_points must be >= 0")
        fit_config_mod.check_float(self.lr_gamma, "lr_gamma", 0, 1e3)
        return self


def paper() -> TrainConfig:
    """The paper's schedule: Adam 1e-3, 150 epochs, x0.1 at 120/140/145, batch 32, 2,500 input
    points, 5,000 UV samples per item, D = 1024, charts 4 x 512 (label nets 4 x 512)."""
    return TrainConfig()


def tiny() -> TrainConfig:
    """Trains a handful of shapes on a 2-core CPU in minutes (tests, smoke runs)."""
    return TrainConfig(
        preset="tiny",
        model=ModelConfig(charts=1, chart_width=32, label_width=32, label_depth=2, octaves=4, latent=32),
        encoder=EncoderConfig(pointnet_widths=[32, 64]),
        data=DataConfig(input_points=256, target_points=256, image_size=64),
        uv_samples=400, batch_size=4, epochs=30, lr=3e-3, lr_milestones=[24, 28], amp=False, threads=1,
        log_every=5, val_every=0, val_shapes=4, val_points=1000, c_samples=2000, eval_points=2000,
        eval_uv_samples=2000, grid=32,
    )


PRESETS = {"paper": paper, "tiny": tiny}


def preset(name: str) -> TrainConfig:
    if name not in PRESETS:
        raise MnaError(f"unknown training preset {name!r}; choose from {', '.join(PRESETS)}")
    return PRESETS[name]()


def from_dict(data: dict, base: TrainConfig | None = None) -> TrainConfig:
    """Build a TrainConfig from a mapping, strictly (:func:`mnacore.configs.from_dict`). Keys
    left out come from ``base`` (or the preset named by ``preset``, else ``paper``)."""
    if not isinstance(data, dict):
        raise MnaError(f"config must be a mapping, got {type(data).__name__}")
    name = data.get("preset", "paper")
    if base is None:
        if not isinstance(name, str):
            raise MnaError(f"config.preset must be str, got {name!r}")
        base = preset(name) if name in PRESETS else paper()
    return fit_config_mod.from_dict(_merge(fit_config_mod.to_dict(base), copy.deepcopy(data)), TrainConfig)


def _merge(base: dict, override: dict) -> dict:
    out = dict(base)
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value)
        else:
            out[key] = value
    return out


def load(path: str | Path) -> TrainConfig:
    """Strictly load a YAML training config (unknown keys / wrong types: MnaError)."""
    return from_dict(fit_config_mod.load_yaml(path))


def to_dict(cfg: TrainConfig) -> dict:
    return fit_config_mod.to_dict(cfg)


def field_names() -> list[str]:
    return [f.name for f in fields(TrainConfig)]


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of `mna train`, shared with `python -m mna.train` (torchrun); here, torch-free, so
    both entry points read one definition and neither imports the other."""
    p.add_argument("config", metavar="CONFIG.yaml", help="training config (see docs/train.md); "
                   "'preset: tiny' or 'preset: paper' fills the keys it leaves out")
    p.add_argument("-o", "--out", default=None, help="training folder (default: the config's 'out')")
    p.add_argument("--resume", action="store_true", help="continue from OUT/checkpoint.pt")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
