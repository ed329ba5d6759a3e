"""Per-shape optimisation of a neural atlas (paper Sec. 4), resumable and interruptible.

One step: sample UVs in every chart's square; evaluate all charts without gradients; find
each target point's nearest chart sample (PU positives); then evaluate the charts *with*
gradients and exact Jacobians at the unique positives only. L_rec and L_dist only ever
touch positives (the nearest sample of a target is a positive), so this is the same loss
as evaluating everything with gradients, at a fraction of the cost. L_occ trains ``l_k``
on all samples with ``phi`` detached.
"""
from __future__ import annotations

import math
import signal
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np
import torch

from mna import losses
from mna.config import FitConfig
from mna.data import Surface
from mna.inference import uniform_uv
from mna.model import NeuralAtlas
from mna.neighbors import nearest


def resolve_device(name: str) -> torch.device:
    """``auto`` -> CUDA when present, else CPU; ``cuda`` without a GPU is an error."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name == "cuda" and not torch.cuda.is_available():
        raise ValueError("--device cuda was asked for, but no CUDA device is available")
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


class Fitter:
    """Owns the model, optimiser and random streams of one fit; ``state_dict`` makes it resumable."""

    def __init__(self, cfg: FitConfig, surface: Surface, device: torch.device):
        self.cfg, self.surface, self.device = cfg, surface, device
        torch.manual_seed(cfg.seed)
        self.model = NeuralAtlas.from_config(cfg.model, cfg.ablation).to(device)
        self.optimizer = torch.optim.Adam(self.model.parameters(), lr=cfg.lr)
        self.generator = torch.Generator().manual_seed(cfg.seed)
        self.rng = np.random.default_rng(cfg.seed)
        self.step = 0
        self.elapsed = 0.0

    # -- one optimisation step -------------------------------------------------------------
    def progress(self) -> float:
        if self.cfg.time_budget:
            return min(1.0, self.elapsed / self.cfg.time_budget)
        return min(1.0, self.step / self.cfg.steps)

    def done(self) -> bool:
        return self.progress() >= 1.0

    def train_step(self) -> StepLosses:
        cfg, model, dev = self.cfg, self.model, self.device
        for group in self.optimizer.param_groups:
            group["lr"] = cfg.lr * lr_factor(self.progress(), cfg.lr_decay_start, cfg.lr_final)
        K, N = cfg.model.charts, cfg.uv_samples
        uv = uniform_uv(K, N, self.generator, 1, dev)
        targets = torch.from_numpy(self.surface.sample(cfg.targets, self.rng)).float().to(dev)
        if cfg.ablation.atlasnet:
            rec, dist, n_pos = self._atlasnet_terms(uv, targets)
            occ = torch.zeros((), device=dev)
        else:
            rec, dist, occ, n_pos = self._mna_terms(uv, targets)
        total = cfg.loss.w_rec * rec + cfg.loss.w_occ * occ + cfg.loss.w_dist * dist
        self.optimizer.zero_grad(set_to_none=True)
        total.backward()
        self.optimizer.step()
        self.step += 1
        return StepLosses(total.item(), rec.item(), occ.item(), dist.item(), n_pos)

    def _mna_terms(self, uv: torch.Tensor, targets: torch.Tensor):
        model, cfg = self.model, self.cfg
        K, N = uv.shape[0], uv.shape[2]
        with torch.no_grad():
            x = model.chart(uv).x  # (K, 1, N, 3)
        nn = nearest(targets, x.reshape(K * N, 3))
        labels = losses.positive_labels(nn.index, K * N)
        # unique positives, sorted, so chart ids are non-decreasing; pack them per chart
        uniq, inverse = torch.unique(nn.index, sorted=True, return_inverse=True)
        chart_of = uniq // N
        counts = torch.bincount(chart_of, minlength=K)
        offsets = torch.cumsum(counts, 0) - counts
        slot = torch.arange(len(uniq), device=uniq.device) - offsets[chart_of]
        pos_uv = torch.zeros(K, 1, int(counts.max()), 2, device=uv.device, dtype=uv.dtype)
        pos_uv[chart_of, 0, slot] = uv.reshape(K * N, 2)[uniq]
        limit = cfg.dist_samples
        split_jac = cfg.loss.w_dist > 0 and 0 < limit < int(counts.max())
        out = model.chart(pos_uv, jacobian=cfg.loss.w_dist > 0 and not split_jac)
        matched = out.x[chart_of, 0, slot]  # (U, 3)
        rec = losses.reconstruction_loss(targets, matched[inverse])
        if cfg.loss.w_dist <= 0:
            dist = torch.zeros((), device=uv.device)
        elif split_jac:
            # L_dist on the first `limit` positives of each chart: positives come in random
            # order within a chart, so this is a random subset (an unbiased-ratio estimate)
            jac = model.chart(pos_uv[:, :, :limit], jacobian=True).jac
            keep = slot < limit
            dist = losses.distortion_loss(jac[chart_of[keep], 0, slot[keep]], cfg.loss.eps)
        else:
            dist = losses.distortion_loss(out.jac[chart_of, 0, slot], cfg.loss.eps)
        logits = model.label_logits(uv, x)  # x carries no gradient: L_occ never reaches phi
        occ = losses.occupancy_loss(logits.reshape(-1), labels)
        return rec, dist, occ, len(uniq)

    def _atlasnet_terms(self, uv: torch.Tensor, targets: torch.Tensor):
        """No occupancy: every sample counts; bidirectional Chamfer; distortion over all samples."""
        cfg = self.cfg
        K, N = uv.shape[0], uv.shape[2]
        out = self.model.chart(uv, jacobian=cfg.loss.w_dist > 0)
        pts = out.x.reshape(K * N, 3)
        to_pts = nearest(targets, pts)
        to_tgt = nearest(pts, targets)
        rec = losses.reconstruction_loss(targets, pts[to_pts.index]) + losses.chamfer_to(pts, targets, to_tgt.index)
        dist = (losses.distortion_loss(out.jac.reshape(-1, 3, 2), cfg.loss.eps)
                if out.jac is not None else torch.zeros((), device=uv.device))
        return rec, dist, K * N

    # -- state -----------------------------------------------------------------------------
    def state_dict(self) -> dict:
        return {
            "model": self.model.state_dict(),
            "optimizer": self.optimizer.state_dict(),
            "step": self.step,
            "elapsed": self.elapsed,
            "torch_rng": self.generator.get_state(),
            "numpy_rng": self.rng.bit_generator.state,
        }

    def load_state_dict(self, state: dict) -> None:
        self.model.load_state_dict(state["model"])
        self.optimizer.load_state_dict(state["optimizer"])
        self.step = int(state["step"])
        self.elapsed = float(state["elapsed"])
        self.generator.set_state(state["torch_rng"])
        self.rng.bit_generator.state = state["numpy_rng"]

    # -- the loop --------------------------------------------------------------------------
    def run(self, on_checkpoint: Callable[["Fitter"], None], callback: Callable[[int], bool] | None = None,
            progress_bar: bool = True) -> bool:
        """Optimise until done; returns True if interrupted (Ctrl-C or ``callback`` returning True).

        ``on_checkpoint(self)`` is called every ``checkpoint_every`` steps and on exit. Ctrl-C
        asks the loop to stop after the current step, so the saved state is always whole;
        a second Ctrl-C aborts at once.
        """
        from tqdm.auto import tqdm

        stop = {"requested": False}
        previous = None

        def on_sigint(signum, frame):
            if stop["requested"]:
                raise KeyboardInterrupt
            stop["requested"] = True

        try:
            previous = signal.signal(signal.SIGINT, on_sigint)
        except ValueError:  # not in the main thread: plain KeyboardInterrupt semantics
            previous = None
        cfg = self.cfg
        budget = cfg.time_budget
        bar = tqdm(total=round(budget) if budget else cfg.steps, initial=round(self.elapsed) if budget else self.step,
                   unit="s" if budget else "step", disable=not progress_bar, dynamic_ncols=True,
                   desc=f"fit K={cfg.model.charts}", leave=True)
        interrupted = False
        try:
            while not self.done():
                t0 = time.perf_counter()
                losses_ = self.train_step()
                dt = time.perf_counter() - t0
                self.elapsed += dt
                if not math.isfinite(losses_.total):
                    raise RuntimeError(f"loss became {losses_.total} at step {self.step}; lower --lr or check the input")
                if budget:
                    bar.n = min(round(self.elapsed), bar.total)
                    bar.refresh() if self.step % cfg.log_every == 0 else None
                else:
                    bar.update(1)
                if self.step % cfg.log_every == 0 or self.step == 1:
                    bar.set_postfix(step=self.step, rec=f"{losses_.rec:.2e}", occ=f"{losses_.occ:.3f}",
                                    dist=f"{losses_.dist - 4:.3f}", pos=losses_.positives, refresh=False)
                if self.step % cfg.checkpoint_every == 0:
                    on_checkpoint(self)
                if stop["requested"] or (callback is not None and callback(self.step)):
                    interrupted = True
                    break
        finally:
            bar.close()
            if previous is not None:
                signal.signal(signal.SIGINT, previous)
        on_checkpoint(self)
        return interrupted
