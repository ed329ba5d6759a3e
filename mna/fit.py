"""Per-shape optimisation of a neural atlas (paper Sec. 4), resumable and interruptible.

Each step draws fresh UV samples and fresh target points (from the mesh surface, or a
subset of the input cloud) and minimises :func:`mna.objective.atlas_losses`.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np
import torch

from mna.config import FitConfig
from mna.data import Surface
from mna.grow import Growth, add_chart
from mna.hard_targets import ErrorMap, HardTargets
from mna.inference import uniform_uv
from mna.interrupt import graceful_stop
from mna.model import NeuralAtlas, flush_denormals
from mna.objective import atlas_losses
from mnacore.errors import MnaError


def resolve_device(name: str) -> torch.device:
    """``auto`` -> CUDA when present, else CPU; ``cuda`` without a GPU is an error."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name == "cuda" and not torch.cuda.is_available():
        raise MnaError("--device cuda was asked for, but no CUDA device is available")
    return torch.device(name)


def lr_factor(progress: float, decay_start: float, final: float) -> float:
    """Constant until ``decay_start``, then cosine down to ``final`` at progress 1."""
    if progress <= decay_start or decay_start >= 1.0:
        return 1.0
    t = min(1.0, (progress - decay_start) / (1.0 - decay_start))
    return final + (1.0 - final) * 0.5 * (1.0 + math.cos(math.pi * t))


@dataclass
class StepLosses:
    total: float
    rec: float
    occ: float
    dist: float
    positives: int
    orient: float = 0.0


class Fitter:
    """Owns the model, optimiser and random streams of one fit; ``state_dict`` makes it resumable."""

    def __init__(self, cfg: FitConfig, surface: Surface, device: torch.device):
        self.cfg, self.surface, self.device = cfg, surface, device
        torch.manual_seed(cfg.seed)
        self.model = NeuralAtlas.from_config(cfg.model, cfg.ablation).to(device)
        self.optimizer = torch.optim.Adam(self.model.parameters(), lr=cfg.lr)
        self.generator = torch.Generator().manual_seed(cfg.seed)
        self.rng = np.random.default_rng(cfg.seed)
        growing = cfg.charts_rule == "grow"
        self.errors = ErrorMap(surface, cfg.targets) if cfg.hard_targets or growing else None
        self.hard = HardTargets(self.errors, cfg.hard_targets) if cfg.hard_targets else None
        self.growth = Growth(cfg.max_charts) if growing else None
        self.step = 0
        self.elapsed = 0.0
        self.encoding: bool | None = None
        """whether the chart encoding opens in this run (None: not decided yet; :meth:`octaves_open`)."""
        self.stop_signal: int | None = None
        """the signal (SIGINT, SIGTERM) that stopped the last :meth:`run`, if one did."""

    # -- one optimisation step -------------------------------------------------------------
    def progress(self) -> float:
        if self.cfg.time_budget:
            return min(1.0, self.elapsed / self.cfg.time_budget)
        return min(1.0, self.step / self.cfg.steps)

    def done(self) -> bool:
        return self.progress() >= 1.0

    def uv_samples(self) -> int:
        """UV samples per chart this step: ``late_uv_samples`` from the lr decay on (if set)."""
        cfg = self.cfg
        late = cfg.late_uv_samples and self.progress() >= cfg.lr_decay_start
        return cfg.late_uv_samples if late else cfg.uv_samples

    def octaves_open(self) -> float:
        """How many of the chart encoding's octaves are open now: none until the first fraction
        ``chart_octaves_from``, all from ``chart_octaves_until``, linearly between; none at all
        in a run shorter than ``chart_octaves_min_steps``. That is decided once, as the window
        would start to open, and kept (a resumed run does not shut an open window): a steps
        run knows its length; a time-budget run estimates it from its pace so far."""
        cfg = self.cfg
        a, b = cfg.chart_octaves_from, cfg.chart_octaves_until
        p = self.progress()
        if p <= a:
            return 0.0
        if self.encoding is None:
            length = cfg.steps if not cfg.time_budget else self.step / p
            self.encoding = length >= cfg.chart_octaves_min_steps
        if not self.encoding:
            return 0.0
        share = 1.0 if p >= b else (p - a) / (b - a)
        return cfg.model.chart_octaves * share

    def dist_weight(self) -> float | None:
        """L_dist's weight this step when it is not ``loss.w_dist`` (None): ``late_w_dist`` in
        the lr decay, unless the chart encoding it relaxes was kept shut for the run's length
        (as :func:`mna.config.settle_encoding` drops both from a short steps run)."""
        return self.cfg.late_w_dist if self.cfg.late_w_dist and self._late() else None

    def exclusive(self) -> bool:
        """Exclusive PU labels this step: ``exclusive_labels`` in the lr decay, the charts placed
        (from the start, a chart that lost every contested region early was starved and the
        others stretched over what it held: benchmarks/RESULTS.md, fit_quality_hard, thirty-fifth
        session); not where the chart encoding was kept shut (the plain fit, as
        :func:`mna.config.settle_encoding` makes a short steps run)."""
        return self.cfg.exclusive_labels and self._late()

    def _late(self) -> bool:
        """In the lr decay of a fit whose chart encoding was not kept shut: where the late
        distortion weight and the exclusive labels apply."""
        return self.progress() >= self.cfg.lr_decay_start and self.encoding is not False

    def train_step(self) -> StepLosses:
        cfg, model, dev = self.cfg, self.model, self.device
        for group in self.optimizer.param_groups:
            group["lr"] = cfg.lr * lr_factor(self.progress(), cfg.lr_decay_start, cfg.lr_final)
        if model.chart.octaves:
            model.chart.window.fill_(self.octaves_open())
        uv = uniform_uv(cfg.model.charts, self.uv_samples(), self.generator, 1, dev)
        pts, nrm, elements = self.surface.sample_elements(cfg.targets, self.rng)
        if self.hard is not None:
            hp, hn, he = self.hard.draw(self.rng)
            pts, elements = np.concatenate([pts, hp]), np.concatenate([elements, he])
            nrm = None if nrm is None else np.concatenate([nrm, hn])
        targets = torch.from_numpy(pts).float().to(dev)
        normals = torch.from_numpy(nrm).float().to(dev)[None] if nrm is not None and cfg.loss.w_orient > 0 else None
        terms = atlas_losses(model, uv, targets[None], cfg, normals=normals, labelled=cfg.targets,
                             surface=self.progress() < cfg.lr_decay_start, w_dist=self.dist_weight(),
                             exclusive=self.exclusive())
        if self.errors is not None:
            self.errors.record(elements, terms.distance[0].cpu().numpy())
        total = terms.total
        self.optimizer.zero_grad(set_to_none=True)
        total.backward()
        self.optimizer.step()
        self.step += 1
        if self.growth is not None:
            center = self.growth.due(self.step, self.progress(), model.charts, self.errors)
            if center is not None:
                self.model, self.optimizer = add_chart(model, self.optimizer, cfg, center)
        return StepLosses(total.item(), terms.rec.item(), terms.occ.item(), terms.dist.item(), terms.positives,
                          float(terms.orient.item()) if terms.orient is not None else 0.0)

    # -- state -----------------------------------------------------------------------------
    def state_dict(self) -> dict:
        return {
            "model": self.model.state_dict(),
            "optimizer": self.optimizer.state_dict(),
            "step": self.step,
            "elapsed": self.elapsed,
            "encoding": self.encoding,
            "torch_rng": self.generator.get_state(),
            "numpy_rng": self.rng.bit_generator.state,
            **({"errors": self.errors.state_dict()} if self.errors is not None else {}),
            **({"growth": self.growth.state_dict()} if self.growth is not None else {}),
        }

    def load_state_dict(self, state: dict) -> None:
        charts = state["model"]["chart.out.b"].shape[0]
        if charts != self.model.charts and self.growth is not None:
            # the fit grew charts before it was saved: rebuild at that size, then load
            self.cfg.model.charts = charts
            self.model = NeuralAtlas.from_config(self.cfg.model, self.cfg.ablation).to(self.device)
            self.optimizer = torch.optim.Adam(self.model.parameters(), lr=self.cfg.lr)
        self.model.load_state_dict(state["model"])
        self.optimizer.load_state_dict(state["optimizer"])
        self.step = int(state["step"])
        self.elapsed = float(state["elapsed"])
        self.encoding = state.get("encoding")  # checkpoints from before the rule: decided anew
        self.generator.set_state(state["torch_rng"])
        self.rng.bit_generator.state = state["numpy_rng"]
        if self.errors is not None and "errors" in state:
            self.errors.load_state_dict(state["errors"])
        if self.growth is not None and "growth" in state:
            self.growth.load_state_dict(state["growth"])

    # -- the loop --------------------------------------------------------------------------
    def run(self, on_checkpoint: Callable[["Fitter"], None], callback: Callable[[int], bool] | None = None,
            progress_bar: bool = True) -> bool:
        """Optimise until done; returns True if interrupted (Ctrl-C, SIGTERM or ``callback`` returning True).

        ``on_checkpoint(self)`` is called every ``checkpoint_every`` steps and on exit. Ctrl-C or
        SIGTERM asks the loop to stop after the current step (``stop_signal`` says which), so the
        saved state is always whole; a second signal aborts at once.
        """
        from tqdm.auto import tqdm

        cfg = self.cfg
        budget = cfg.time_budget
        bar = tqdm(total=round(budget) if budget else cfg.steps, initial=round(self.elapsed) if budget else self.step,
                   unit="s" if budget else "step", disable=not progress_bar, dynamic_ncols=True,
                   desc=f"fit K={cfg.model.charts}", leave=True)
        interrupted = False
        self.stop_signal = None
        with graceful_stop() as stop, bar:
            while not self.done():
                t0 = time.perf_counter()
                with flush_denormals():
                    losses_ = self.train_step()
                dt = time.perf_counter() - t0
                self.elapsed += dt
                if not math.isfinite(losses_.total):
                    raise MnaError(f"loss became {losses_.total} at step {self.step}; lower lr or check the input")
                if budget:
                    bar.n = min(round(self.elapsed), bar.total)
                    if self.step % cfg.log_every == 0:
                        bar.refresh()
                else:
                    bar.update(1)
                if self.step % cfg.log_every == 0 or self.step == 1:
                    bar.set_postfix(step=self.step, rec=f"{losses_.rec:.2e}", occ=f"{losses_.occ:.3f}",
                                    dist=f"{losses_.dist - 4:.3f}", pos=losses_.positives, refresh=False)
                if self.step % cfg.checkpoint_every == 0:
                    on_checkpoint(self)
                if stop.requested or (callback is not None and callback(self.step)):
                    interrupted, self.stop_signal = True, stop.signum
                    break
        on_checkpoint(self)
        return interrupted
