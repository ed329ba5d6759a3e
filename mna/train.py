"""Train the conditional atlas on a dataset: one process, or many under ``torchrun``.

    mna train CONFIG.yaml [--resume]                        # one process, CPU or one GPU
    torchrun --nproc_per_node=N -m mna.train CONFIG.yaml    # DistributedDataParallel, N ranks

Under torchrun (``env://``: RANK, WORLD_SIZE, LOCAL_RANK, MASTER_ADDR/PORT) the model is
wrapped in ``DistributedDataParallel`` (NCCL on CUDA, gloo on the CPU), so gradients are
averaged across ranks; a ``DistributedSampler`` splits every epoch's shuffled order; rank 0
alone writes the training folder. The loss is the fit stage's :func:`atlas_losses` on a batch
with ``z = encoder(input)``. A checkpoint holds model, optimiser, lr scheduler, grad scaler,
epoch, the batch index within the epoch (so a resume skips exactly the batches already done)
and the log; every random draw is keyed by ``(seed, epoch, item)`` (see
:mod:`mna.datasets`), so a resumed run repeats an uninterrupted one.
"""
from __future__ import annotations

import argparse
import math
import os
import signal
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import torch
import torch.distributed as dist
from torch import nn
from torch.utils.data import DataLoader

from mna import datasets, train_config
from mna.checkpoint import read_state, write_state
from mna.conditional import CHECKPOINT_FORMAT, ConditionalAtlas, load_state
from mna.config import save_yaml
from mna.distributed import (
    Distributed,
    ResumableSampler,
    end_rank,
    rank_param_divergence,
    setup_distributed,
    teardown_distributed,
)
from mna.interrupt import exit_code, graceful_stop
from mna.model import flush_denormals
from mna.objective import LossTerms, atlas_losses
from mna.train_config import TrainConfig
from mnacore.atomic import clean_stale_temporaries, write_json, write_text
from mnacore.errors import MnaError
from mnacore.machine import cpu_summary

CONFIG = "config.yaml"
CHECKPOINT = "checkpoint.pt"
METRICS = "metrics.json"
LOG_CSV = "log.csv"
LOG_COLUMNS = ("step", "epoch", "lr", "loss", "rec", "occ", "dist", "shapes_per_second",
               "val_chamfer_pcl", "val_fscore_pcl")


class TrainStep(nn.Module):
    """What DDP wraps: ``(input, uv (K,B,N,2), target (B,T,3))`` -> the fit stage's LossTerms."""

    def __init__(self, model: ConditionalAtlas, cfg: TrainConfig):
        super().__init__()
        self.model, self.fit_cfg = model, cfg.fit_config()

    def forward(self, inputs: torch.Tensor, uv: torch.Tensor, target: torch.Tensor) -> LossTerms:
        z = self.model.encode(inputs)
        return atlas_losses(self.model.atlas, uv, target, self.fit_cfg, z.float())


@dataclass
class TrainResult:
    out: Path
    interrupted: bool
    epoch: int
    step: int
    seconds: float
    metrics: dict | None
    model: ConditionalAtlas
    stop_signal: int | None = None
    """SIGINT or SIGTERM when a signal interrupted training (the checkpoint is saved)."""


class Trainer:
    """Model, DDP wrapper, optimiser, schedule and data of one training run (one rank)."""

    def __init__(self, cfg: TrainConfig, ctx: Distributed):
        self.cfg, self.ctx = cfg, ctx
        if cfg.batch_size % ctx.world:
            raise MnaError(f"batch_size {cfg.batch_size} is not a multiple of the {ctx.world} processes")
        self.per_rank = cfg.batch_size // ctx.world
        torch.manual_seed(cfg.seed)
        self.model = ConditionalAtlas.from_config(cfg).to(ctx.device)
        step = TrainStep(self.model, cfg)
        self.step_fn = step
        if ctx.active:
            ids = [ctx.device.index] if ctx.device.type == "cuda" else None
            self.step_fn = nn.parallel.DistributedDataParallel(step, device_ids=ids)
        self.optimizer = torch.optim.Adam(self.model.parameters(), lr=cfg.lr)
        self.scheduler = torch.optim.lr_scheduler.MultiStepLR(self.optimizer, cfg.lr_milestones, cfg.lr_gamma)
        self.amp = bool(cfg.amp and ctx.device.type == "cuda")
        self.scaler = torch.amp.GradScaler("cuda", enabled=self.amp)
        self.amp_skips = 0
        self.train_set = datasets.build(cfg, cfg.data.train_split)
        self.sampler = ResumableSampler(self.train_set, num_replicas=ctx.world, rank=ctx.rank, shuffle=True,
                                        seed=cfg.seed)
        self.epoch, self.batch_in_epoch, self.step, self.elapsed = 0, 0, 0, 0.0
        self.stop_signal: int | None = None
        self.log_rows: list[dict] = []

    # -- state -----------------------------------------------------------------------------
    def state_dict(self) -> dict:
        return {
            "format": CHECKPOINT_FORMAT,
            "config": train_config.to_dict(self.cfg),
            "model": self.model.state_dict(),
            "optimizer": self.optimizer.state_dict(),
            "scheduler": self.scheduler.state_dict(),
            "scaler": self.scaler.state_dict(),
            "amp": self.amp,
            "epoch": self.epoch, "batch_in_epoch": self.batch_in_epoch, "step": self.step,
            "elapsed": self.elapsed, "world_size": self.ctx.world, "per_rank_batch": self.per_rank,
            "encoder_weights": self.model.encoder.weights, "log": self.log_rows,
        }

    def load_state_dict(self, state: dict, path: Path) -> None:
        if state.get("format") != CHECKPOINT_FORMAT:
            raise MnaError(f"{path} is not a training checkpoint of `mna train`")
        load_state(self.model, state["model"], path)
        try:
            self.optimizer.load_state_dict(state["optimizer"])
        except (ValueError, KeyError) as exc:
            raise MnaError(f"optimiser state in {path} does not match this model: {exc}") from None
        self.scheduler.load_state_dict(state["scheduler"])
        self.amp = bool(state.get("amp", self.amp)) and self.amp
        self.scaler.load_state_dict(state["scaler"]) if self.amp and state["scaler"] else None
        self.epoch, self.batch_in_epoch = int(state["epoch"]), int(state["batch_in_epoch"])
        self.step, self.elapsed = int(state["step"]), float(state["elapsed"])
        self.log_rows = list(state.get("log", []))
        if self.batch_in_epoch and int(state["world_size"]) != self.ctx.world:
            raise MnaError(f"{path} stopped mid-epoch with {state['world_size']} process(es); resume it with "
                           f"the same number (got {self.ctx.world})")

    # -- one step --------------------------------------------------------------------------
    def train_step(self, batch: dict) -> torch.Tensor:
        """One optimiser step; returns the rank-averaged ``[total, rec, occ, dist]``."""
        dev = self.ctx.device
        inputs, uv, target = batch["input"].to(dev), batch["uv"].to(dev), batch["target"].to(dev)
        with torch.autocast("cuda", dtype=torch.float16, enabled=self.amp):
            terms = self.step_fn(inputs, uv, target)
        self.optimizer.zero_grad(set_to_none=True)
        self.scaler.scale(terms.total).backward()
        scale = self.scaler.get_scale() if self.amp else 1.0
        self.scaler.step(self.optimizer)
        self.scaler.update()
        stats = torch.stack([terms.total, terms.rec, terms.occ, terms.dist]).detach().float()
        if self.ctx.active:
            dist.all_reduce(stats)
            stats /= self.ctx.world
        if self.amp:
            # gradients are averaged before the scaler looks at them: every rank skips alike
            self.amp_skips = self.amp_skips + 1 if self.scaler.get_scale() < scale else 0
            if self.amp_skips >= self.cfg.amp_max_skips:
                self.amp = False
                self.scaler = torch.amp.GradScaler("cuda", enabled=False)
                print(f"mna train: {self.amp_skips} mixed-precision steps in a row overflowed; "
                      "continuing in float32", file=sys.stderr)
        elif not bool(torch.isfinite(stats).all()):
            raise MnaError(f"loss became {float(stats[0])} at step {self.step + 1}; lower lr or check the data")
        self.step += 1
        return stats.cpu()

    def loader(self) -> DataLoader:
        self.train_set.set_epoch(self.epoch)
        self.sampler.set_epoch(self.epoch)
        self.sampler.start = self.batch_in_epoch * self.per_rank
        return DataLoader(self.train_set, batch_size=self.per_rank, sampler=self.sampler,
                          num_workers=self.cfg.data.workers, collate_fn=datasets.collate,
                          pin_memory=self.ctx.device.type == "cuda")

    def batches_per_epoch(self) -> int:
        return math.ceil(self.sampler.num_samples / self.per_rank)


class Logger:
    """Rows to ``log.csv`` (always) and to TensorBoard when it is importable (rank 0 only)."""

    def __init__(self, out: Path, rows: list[dict], enabled: bool):
        self.out, self.rows, self.enabled, self.writer = out, rows, enabled, None
        self.backend = "csv"
        if enabled:
            try:
                from torch.utils.tensorboard import SummaryWriter
            except ImportError:
                pass
            else:
                self.writer = SummaryWriter(str(out / "tensorboard"))
                self.backend = "tensorboard+csv"

    def log(self, row: dict) -> None:
        self.rows.append(row)
        if self.writer is not None:
            for key, value in row.items():
                if key not in ("step", "epoch") and value is not None:
                    self.writer.add_scalar(key, value, row["step"])

    def flush(self) -> None:
        if not self.enabled:
            return
        lines = [",".join(LOG_COLUMNS)]
        for row in self.rows:
            lines.append(",".join("" if row.get(c) is None else f"{row[c]:.6g}" if isinstance(row[c], float)
                                  else str(row[c]) for c in LOG_COLUMNS))
        write_text(self.out / LOG_CSV, "\n".join(lines) + "\n")
        if self.writer is not None:
            self.writer.flush()

    def close(self) -> None:
        if self.writer is not None:
            self.writer.close()


def _save(trainer: Trainer, out: Path, logger: Logger) -> None:
    if trainer.ctx.main:
        write_state(out / CHECKPOINT, trainer.state_dict())
        logger.flush()


def prepare_out(cfg: TrainConfig, resume: bool) -> Path:
    out = Path(cfg.out)
    if out.exists() and not out.is_dir():
        raise MnaError(f"training folder path exists and is not a folder: {out}")
    if resume and not (out / CHECKPOINT).is_file():
        raise MnaError(f"--resume: no {CHECKPOINT} in {out}")
    if not resume and (out / CHECKPOINT).is_file():
        raise MnaError(f"{out} already holds a training run; use --resume or another out folder")
    clean_stale_temporaries(out, legacy=(CHECKPOINT, CONFIG, LOG_CSV, "metrics.json"))
    return out


def train(cfg: TrainConfig, resume: bool = False, progress: bool = True, stop_at_step: int | None = None,
          log=print) -> TrainResult:
    """Train per ``cfg`` into ``cfg.out`` (call once per process; torchrun sets the ranks).

    ``stop_at_step`` stops (checkpointing) after that global step, as an interruption would.
    """
    cfg.validate()
    if cfg.threads:
        torch.set_num_threads(cfg.threads)
    out = prepare_out(cfg, resume)
    ctx = setup_distributed(cfg.device)
    trainer = Trainer(cfg, ctx)
    val_set = datasets.build(cfg, cfg.data.val_split) if cfg.val_every else None
    if resume:
        state = read_state(out / CHECKPOINT, map_location=ctx.device)
        trainer.load_state_dict(state, out / CHECKPOINT)
        if ctx.main:
            log(f"resuming at epoch {trainer.epoch + 1}, batch {trainer.batch_in_epoch}, step {trainer.step}")
    if ctx.main:
        out.mkdir(parents=True, exist_ok=True)
        save_yaml(out / CONFIG, train_config.to_dict(cfg))
    logger = Logger(out, trainer.log_rows, ctx.main)
    if ctx.main:
        log(f"training on {len(trainer.train_set)} items ({cfg.data.layout}, {cfg.data.input}), "
            f"{ctx.world} process(es) on {ctx.device}, batch {cfg.batch_size}, {cfg.epochs} epochs, "
            f"preset {cfg.preset}, encoder weights {trainer.model.encoder.weights}, logging {logger.backend}")
    interrupted = _loop(trainer, out, logger, val_set, progress, stop_at_step)
    logger.close()
    metrics = None
    if not interrupted:
        metrics = _finish(trainer, out, val_set)
    return TrainResult(out, interrupted, trainer.epoch, trainer.step, trainer.elapsed, metrics, trainer.model,
                       trainer.stop_signal)


def _loop(trainer: Trainer, out: Path, logger: Logger, val_set, progress: bool, stop_at_step: int | None) -> bool:
    from tqdm.auto import tqdm

    cfg, ctx = trainer.cfg, trainer.ctx
    # Ctrl-C or SIGTERM: finish the step, checkpoint, stop (torchrun handles its own signals)
    with graceful_stop(enabled=not ctx.active) as stop:
        while trainer.epoch < cfg.epochs:
            bar = tqdm(total=trainer.batches_per_epoch(), initial=trainer.batch_in_epoch, unit="batch",
                       desc=f"epoch {trainer.epoch + 1}/{cfg.epochs}", disable=not (progress and ctx.main),
                       dynamic_ncols=True, leave=False)
            t_epoch = time.perf_counter()
            done_items = 0
            for batch in trainer.loader():
                t0 = time.perf_counter()
                with flush_denormals():
                    stats = trainer.train_step(batch)
                trainer.elapsed += time.perf_counter() - t0
                trainer.batch_in_epoch += 1
                done_items += len(batch["index"]) * ctx.world
                bar.update(1)
                if trainer.step % cfg.log_every == 0:
                    rate = done_items / max(time.perf_counter() - t_epoch, 1e-9)
                    logger.log({"step": trainer.step, "epoch": trainer.epoch + 1,
                                "lr": trainer.optimizer.param_groups[0]["lr"], "loss": float(stats[0]),
                                "rec": float(stats[1]), "occ": float(stats[2]), "dist": float(stats[3]),
                                "shapes_per_second": rate})
                    bar.set_postfix(rec=f"{float(stats[1]):.2e}", occ=f"{float(stats[2]):.3f}", refresh=False)
                if cfg.checkpoint_every and trainer.step % cfg.checkpoint_every == 0:
                    _save(trainer, out, logger)
                if stop.requested or (stop_at_step is not None and trainer.step >= stop_at_step):
                    trainer.stop_signal = stop.signum
                    bar.close()
                    _save(trainer, out, logger)
                    return True
            bar.close()
            trainer.epoch += 1
            trainer.batch_in_epoch = 0
            trainer.scheduler.step()
            last = trainer.epoch == cfg.epochs
            if val_set is not None and (trainer.epoch % cfg.val_every == 0 or last):
                m = validate(trainer, val_set)
                logger.log({"step": trainer.step, "epoch": trainer.epoch, "val_chamfer_pcl": m["chamfer_pcl"],
                            "val_fscore_pcl": m["fscore_pcl"]})
            _save(trainer, out, logger)
    return False


def validate(trainer: Trainer, val_set) -> dict:
    """Point-cloud Chamfer / F-score over (a fixed subset of) the validation split, all ranks."""
    from mna.reconstruct import evaluate_items, reduce_mean

    cfg, ctx = trainer.cfg, trainer.ctx
    n = len(val_set) if not cfg.val_shapes else min(cfg.val_shapes, len(val_set))
    indices = list(range(n))[ctx.rank::ctx.world]
    rows = evaluate_items(trainer.model, val_set, indices, cfg, points=cfg.val_points, full=False,
                          device=ctx.device)
    return reduce_mean(rows, ("chamfer_pcl", "fscore_pcl"), ctx)


def _finish(trainer: Trainer, out: Path, val_set) -> dict:
    cfg, ctx = trainer.cfg, trainer.ctx
    divergence = rank_param_divergence(trainer.model, ctx)
    metrics = {
        "epochs": trainer.epoch, "steps": trainer.step, "train_seconds": trainer.elapsed,
        "shapes_per_second": trainer.step * cfg.batch_size / max(trainer.elapsed, 1e-9),
        "world_size": ctx.world, "device": str(ctx.device), "amp": trainer.amp,
        "encoder_weights": trainer.model.encoder.weights, "rank_max_param_diff": divergence,
        "torch": torch.__version__, "machine": cpu_summary(),
    }
    rows = [r for r in trainer.log_rows if r.get("val_chamfer_pcl") is not None]
    if rows:
        metrics["val_chamfer_pcl"], metrics["val_fscore_pcl"] = rows[-1]["val_chamfer_pcl"], rows[-1]["val_fscore_pcl"]
    if ctx.main:
        write_json(out / METRICS, metrics)
    return metrics


# -- command line (also what `torchrun -m mna.train` runs) --------------------------------------
def build_config(path: str, out: str | None = None) -> TrainConfig:
    cfg = train_config.load(path)
    if out:
        cfg.out = out
    return cfg.validate()


def load_resume_config(out: str) -> TrainConfig:
    """The config a training folder was started with (``--resume`` uses it, not the YAML)."""
    return train_config.from_dict(train_config.fit_config_mod.load_yaml(Path(out) / CONFIG)).validate()


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m mna.train", description=__doc__.splitlines()[0])
    train_config.add_arguments(p)
    return p


#: keys a resumed run may change: where and how it runs, not what it learns.
RESUME_MAY_CHANGE = {"out", "device", "threads", "log_every", "checkpoint_every", "data.root", "data.workers"}


def _comparable(cfg: TrainConfig) -> dict:
    """Flat ``section.key -> value`` of the config, less :data:`RESUME_MAY_CHANGE`."""
    flat = {}
    for key, value in train_config.to_dict(cfg).items():
        for k, v in (value.items() if isinstance(value, dict) else [(None, value)]):
            name = key if k is None else f"{key}.{k}"
            if name not in RESUME_MAY_CHANGE:
                flat[name] = v
    return flat


def run(args: argparse.Namespace) -> int:
    cfg = build_config(args.config, args.out)
    if args.resume and (Path(cfg.out) / CONFIG).is_file():
        saved, given = _comparable(load_resume_config(cfg.out)), _comparable(cfg)
        differs = sorted(k for k in set(saved) | set(given) if saved.get(k) != given.get(k))
        if differs:
            raise MnaError(f"--resume: {args.config} differs from {Path(cfg.out) / CONFIG} in {', '.join(differs)}")
    result = train(cfg, resume=args.resume, progress=not args.no_progress)
    if result.interrupted:
        print(f"interrupted at step {result.step}; continue with --resume", file=sys.stderr)
        return exit_code(result.stop_signal or signal.SIGINT)
    if int(os.environ.get("RANK", "0")) == 0:
        m = result.metrics
        val = f", val chamfer_pcl {m['val_chamfer_pcl']:.3e}" if "val_chamfer_pcl" in m else ""
        print(f"done: {m['steps']} steps, {m['epochs']} epochs in {m['train_seconds']:.0f} s "
              f"({m['shapes_per_second']:.1f} shapes/s){val} -> {result.out}")
    return 0


def run_as_rank(prog: str, args: argparse.Namespace) -> int:
    """:func:`run` with the exit codes of :mod:`mna.cli`, then leave the process group; a rank
    of torchrun (WORLD_SIZE > 1) then ends at once (:func:`mna.distributed.end_rank` says why)."""
    from mna.cli import run_command

    try:
        code = run_command(prog, run, args)
    finally:
        teardown_distributed()
    if int(os.environ.get("WORLD_SIZE", "1")) > 1:
        end_rank(code)
    return code


def main(argv: list[str] | None = None) -> int:
    return run_as_rank("mna train", parser().parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
