"""Typed fit configuration; presets are instances; the resolved config is saved with every run."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import yaml

from mna.errors import MnaError


@dataclass
class ModelConfig:
    """Network sizes. The paper: charts 4 x 512 with weight norm and Softplus(100)."""

    charts: int = 3
    """Number of charts K (1-3 in the paper's experiments)."""
    chart_width: int = 512
    """Hidden width of each chart MLP phi_k."""
    chart_depth: int = 4
    """Hidden layers of phi_k; the input is re-concatenated after layer ``chart_skip``."""
    chart_skip: int = 2
    """Hidden layer index that receives the input again."""
    label_width: int = 256
    """Hidden width of each labelled-probability MLP l_k."""
    label_depth: int = 4
    """Hidden layers of l_k."""
    octaves: int = 6
    """Positional-encoding octaves of l_k's input (0 = no encoding: an ablation)."""
    latent: int = 0
    """Latent code size D for the conditional version (0 for a per-shape fit)."""


@dataclass
class LossConfig:
    """Loss weights and the paper's constants."""

    w_rec: float = 1.0
    """Weight of L_rec (unidirectional Chamfer, targets to chart points)."""
    w_occ: float = 1.0
    """Weight of L_occ (BCE of l_k against PU labels, no gradient into phi)."""
    w_dist: float = 1e-5
    """Weight of L_dist (scaled symmetric Dirichlet energy over positives); 0 = ablation."""
    eps: float = 1e-4
    """epsilon in g_hat = J^T J + eps I."""
    w_orient: float = 0.0
    """Weight of L_orient (an mna extension, not in the paper; needs a mesh input): the share of
    positives whose chart normal points against the input's normal, per chart's majority.
    Charts that turn inside out become folded faces in the atlas; 0 = off."""


@dataclass
class AblationConfig:
    """The switches the paper studies (all False = the full method)."""

    occupancy_on_uv: bool = False
    """No reformulation: l_k classifies the UV point directly instead of phi_k(u)."""
    naive_classifier: bool = False
    """Plain binary classification instead of PU learning: c fixed to 1."""
    atlasnet: bool = False
    """AtlasNet-style: no occupancy, every chart is its full square; bidirectional Chamfer."""


@dataclass
class FitConfig:
    """Everything a per-shape fit needs; saved as ``config.yaml`` beside its outputs."""

    preset: str = "fast"
    """Name of the preset this config started from."""
    model: ModelConfig = field(default_factory=ModelConfig)
    loss: LossConfig = field(default_factory=LossConfig)
    ablation: AblationConfig = field(default_factory=AblationConfig)
    uv_samples: int = 5000
    """UV samples per chart per step."""
    targets: int = 2500
    """Target surface points per step (drawn fresh from a mesh every step)."""
    dist_samples: int = 0
    """Positives per chart whose Jacobian enters L_dist each step (0 = all, as the paper)."""
    lr: float = 1e-3
    """Adam learning rate."""
    lr_decay_start: float = 1.0
    """Fraction of the run after which the lr decays (cosine); 1.0 = constant lr."""
    lr_final: float = 1.0
    """Final lr as a fraction of ``lr``."""
    steps: int = 10000
    """Optimisation steps (ignored for the stopping rule when ``time_budget`` is set)."""
    time_budget: float | None = None
    """Wall-clock seconds for the fit; the lr schedule then follows elapsed time."""
    tau: float = 0.5
    """Domain threshold on o_k = l_k / c."""
    eta: float = 0.4
    """c = median of l over the top eta fraction of samples."""
    c_samples: int = 20000
    """UV samples per chart used to estimate c."""
    seed: int = 0
    device: str = "auto"
    """auto (CUDA when present), cpu or cuda."""
    threads: int = 0
    """torch CPU threads (0 = torch's default)."""
    checkpoint_every: int = 500
    """Write checkpoint.pt every this many steps (and at the end / on Ctrl-C)."""
    log_every: int = 25
    """Refresh the progress bar's loss read-out every this many steps."""
    eval_points: int = 25000
    """Points for Chamfer / F-score (each side)."""
    eval_uv_samples: int = 20000
    """UV samples per chart for the distortion metrics."""
    grid: int = 256
    """UV grid resolution of the extracted chart meshes."""

    def validate(self) -> "FitConfig":
        m = self.model
        if m.charts < 1:
            raise MnaError(f"--charts must be at least 1, got {m.charts}")
        for name in ("uv_samples", "targets", "eval_points", "eval_uv_samples", "c_samples"):
            if getattr(self, name) < 1:
                raise MnaError(f"{name} must be positive, got {getattr(self, name)}")
        if self.steps < 1 and not self.time_budget:
            raise MnaError(f"--steps must be at least 1, got {self.steps}")
        if self.time_budget is not None and self.time_budget <= 0:
            raise MnaError(f"--time-budget must be positive seconds, got {self.time_budget}")
        if self.grid < 2:
            raise MnaError(f"--grid must be at least 2, got {self.grid}")
        if not 0 < self.eta <= 1:
            raise MnaError(f"eta must be in (0, 1], got {self.eta}")
        if self.device not in ("auto", "cpu", "cuda"):
            raise MnaError(f"--device must be auto, cpu or cuda, got {self.device!r}")
        return self


def paper() -> FitConfig:
    """The paper's sizes: width 512, 5,000 UV samples, 2,500 targets, lr 1e-3, 1/1/1e-5."""
    return FitConfig(preset="paper", model=ModelConfig(chart_width=512, label_width=512), steps=20000)


def fast() -> FitConfig:
    """Best quality per CPU-minute measured on a 2-core machine (see benchmarks/RESULTS.md)."""
    return FitConfig(
        preset="fast",
        model=ModelConfig(chart_width=128, label_width=96, label_depth=3),
        uv_samples=3000,
        targets=3000,
        dist_samples=256,
        # 10x the paper's weight: on the bunny at equal steps, F-score unchanged and
        # distortion_metric 0.52 instead of 1.06 (benchmarks/RESULTS.md, fit_quality).
        # L_orient (mesh inputs): on the bunny at 2,000 steps, inside-out chart area 5.6 % ->
        # 0.4 % of the surface and 11 -> 4 trimmed islands; 1e-2 raised distortion to 0.49
        loss=LossConfig(w_dist=1e-4, w_orient=1e-3),
        lr=1e-3,
        lr_decay_start=0.55,
        lr_final=0.02,
        steps=3000,
        checkpoint_every=250,
    )


def tiny() -> FitConfig:
    """Small and quick, for tests and smoke runs (not for quality)."""
    return FitConfig(
        preset="tiny",
        model=ModelConfig(chart_width=32, label_width=32, label_depth=2, octaves=4),
        uv_samples=600, targets=400, steps=100, lr=2e-3, lr_decay_start=0.6, lr_final=0.1,
        c_samples=4000, eval_points=4000, eval_uv_samples=3000, grid=48, checkpoint_every=50, threads=1,
    )


PRESETS = {"fast": fast, "paper": paper, "tiny": tiny}


def preset(name: str) -> FitConfig:
    if name not in PRESETS:
        raise MnaError(f"unknown preset {name!r}; choose from {', '.join(PRESETS)}")
    return PRESETS[name]()


def to_dict(cfg: Any) -> dict:
    return dataclasses.asdict(cfg)


def from_dict(data: dict, cls: type = FitConfig, where: str = "config") -> Any:
    """Build a (nested) dataclass from a dict, rejecting unknown keys and wrong types."""
    if not isinstance(data, dict):
        raise MnaError(f"{where} must be a mapping, got {type(data).__name__}")
    known = {f.name: f for f in fields(cls)}
    unknown = sorted(set(data) - set(known))
    if unknown:
        raise MnaError(f"unknown key(s) in {where}: {', '.join(unknown)}")
    kwargs = {}
    defaults = cls()
    for name, value in data.items():
        default = getattr(defaults, name)
        if dataclasses.is_dataclass(default):
            kwargs[name] = from_dict(value, type(default), f"{where}.{name}")
            continue
        kwargs[name] = _coerce(value, default, f"{where}.{name}")
    return cls(**kwargs)


def _coerce(value: Any, default: Any, where: str) -> Any:
    if default is None or value is None:
        if value is not None and not isinstance(value, (int, float, str)):
            raise MnaError(f"{where} has the wrong type: {type(value).__name__}")
        return value
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise MnaError(f"{where} must be true or false, got {value!r}")
        return value
    if isinstance(default, int) and not isinstance(value, bool) and isinstance(value, int):
        return value
    if isinstance(default, float) and not isinstance(value, bool) and isinstance(value, (int, float)):
        return float(value)
    if isinstance(default, float) and isinstance(value, str):
        # YAML 1.1 reads 1e-3 (no dot) as a string
        try:
            return float(value)
        except ValueError:
            pass
    if isinstance(default, str) and isinstance(value, str):
        return value
    raise MnaError(f"{where} must be {type(default).__name__}, got {value!r}")


def save_yaml(path: str | Path, data: dict) -> None:
    from mna.atomic import write_text

    write_text(path, yaml.safe_dump(data, sort_keys=False))


def load_yaml(path: str | Path) -> dict:
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except FileNotFoundError:
        raise MnaError(f"config file not found: {path}") from None
    except yaml.YAMLError as exc:
        raise MnaError(f"config file {path} is not valid YAML: {str(exc).splitlines()[0]}") from None
    return data or {}
