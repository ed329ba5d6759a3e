"""Feed-forward reconstruction and dataset evaluation with a trained conditional atlas.

``reconstruct_run`` encodes one input into ``z (1, D)``, bakes the per-shape atlas
(:func:`mna.conditional.bake`: exact, the latent is a bias), estimates that shape's ``c`` and
writes the **same run folder as** ``mna fit`` through the fit stage's own writers
(:func:`mna.run.save_checkpoint` / :func:`mna.run.extract_run`): ``config.yaml`` (a
``FitConfig`` plus ``input``), ``checkpoint.pt`` (``mna.run.load_model`` reads it; it is even
resumable with ``mna fit --resume`` to refine the shape per-shape), ``metrics.json``,
``points.ply``, ``charts.npz``, ``charts.ply``. ``mna export``, ``compare`` and ``render``
therefore take it unchanged.

``evaluate_items`` gives DESIGN's metrics per shape of a dataset split (unit-ball frame).
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import torch

from mna import config as config_mod
from mna.conditional import ConditionalAtlas, LoadedCheckpoint, bake, load_checkpoint
from mna.config import FitConfig
from mna.data import load_surface
from mna.fit import Fitter, resolve_device
from mna.inference import extract_grid, rejection_sample, settle_c
from mna.metrics import atlas_distortion, chamfer_fscore, sample_mesh
from mna.model import NeuralAtlas
from mna.run import extract_run, prepare_output, run_config_dict, save_checkpoint
from mna.train_config import TrainConfig
from mnacore.atomic import write_json
from mnacore.errors import MnaError

IMAGE_EXTS = {".jpg", ".jpeg", ".png"}
PCL_METRICS = ("chamfer_pcl", "fscore_pcl")
FULL_METRICS = PCL_METRICS + ("chamfer_mesh", "fscore_mesh", "distortion_metric", "distortion_conformal",
                              "distortion_area", "occupancy_mean")


@torch.no_grad()
def shape_atlas(model: ConditionalAtlas, inputs: torch.Tensor, fit_cfg: FitConfig) -> tuple[NeuralAtlas, torch.Tensor]:
    """One input (``(P, 3)`` points or ``(3, H, W)`` image) -> baked per-shape atlas with its c, and z."""
    model.eval()
    z = model.encode(inputs.unsqueeze(0))  # (1, D)
    atlas = bake(model.atlas, z)
    settle_c(atlas, fit_cfg)
    return atlas, z


def shape_metrics(atlas: NeuralAtlas, reference: np.ndarray, fit_cfg: FitConfig, points: int, full: bool) -> dict:
    """DESIGN metrics of one baked atlas against ``reference (R, 3)`` (unit-ball frame)."""
    sample = rejection_sample(atlas, points, torch.Generator().manual_seed(fit_cfg.seed + 2), fit_cfg.tau)
    pcl = chamfer_fscore(sample.points, reference)
    row = {"chamfer_pcl": pcl.chamfer, "fscore_pcl": pcl.fscore}
    if full:
        grid = extract_grid(atlas, fit_cfg.grid, fit_cfg.tau)
        mesh = chamfer_fscore(sample_mesh(grid.vertices, grid.faces, points, seed=fit_cfg.seed + 4), reference)
        d = atlas_distortion(atlas, fit_cfg.eval_uv_samples, torch.Generator().manual_seed(fit_cfg.seed + 5),
                             fit_cfg.tau, fit_cfg.loss.eps)
        row.update(chamfer_mesh=mesh.chamfer, fscore_mesh=mesh.fscore, distortion_metric=d.distortion_metric,
                   distortion_conformal=d.distortion_conformal, distortion_area=d.distortion_area,
                   occupancy_mean=float(np.mean(d.occupancy_rate)), degenerate_charts=d.degenerate_charts)
    return row


def evaluate_items(model: ConditionalAtlas, dataset, indices: list[int], cfg: TrainConfig, points: int,
                   full: bool, device: torch.device | str = "cpu") -> list[dict]:
    """Per-item metrics for ``indices`` of ``dataset`` (epoch-0 draws: fixed inputs and references)."""
    fit_cfg = cfg.fit_config()
    was_training = model.training
    epoch = dataset.epoch
    dataset.set_epoch(0)
    rows = []
    try:
        for i in indices:
            item = dataset[i]
            atlas, _ = shape_atlas(model, item["input"].to(device), fit_cfg)
            ref = reference_points(dataset, i, points, cfg.seed)
            rows.append({"index": i, "name": dataset.object_of(i).name,
                         **shape_metrics(atlas, ref, fit_cfg, points, full)})
    finally:
        dataset.set_epoch(epoch)
        model.train(was_training)
    return rows


def reference_points(dataset, index: int, count: int, seed: int) -> np.ndarray:
    """``count`` reference points of item ``index``'s surface, unit-ball frame, fixed per item."""
    rng = np.random.default_rng([seed, 10**6, index])
    obj = index // dataset.views
    if dataset.cfg.data.layout == "meshes":
        return dataset.surface(obj).sample(count, rng)
    pts = dataset.cloud(obj)[0]
    return pts[rng.choice(len(pts), size=min(count, len(pts)), replace=False)]


def reduce_mean(rows: list[dict], keys, ctx=None) -> dict:
    """Mean of ``keys`` over rows (non-finite values skipped), summed across ranks when distributed."""
    sums = torch.zeros(2 * len(keys), dtype=torch.float64)
    for r in rows:
        for j, k in enumerate(keys):
            v = r.get(k)
            if v is not None and math.isfinite(v):
                sums[2 * j] += v
                sums[2 * j + 1] += 1
    if ctx is not None and ctx.active:
        import torch.distributed as dist

        moved = sums.to(ctx.device)
        dist.all_reduce(moved)
        sums = moved.cpu()
    return {k: float(sums[2 * j] / sums[2 * j + 1]) if sums[2 * j + 1] else float("nan") for j, k in enumerate(keys)}


# -- mna reconstruct ----------------------------------------------------------------------------
def _encoder_input(cfg: TrainConfig, input_path: Path, surface, seed: int) -> torch.Tensor:
    if cfg.data.input == "points":
        rng = np.random.default_rng(seed)
        pts = surface.sample(cfg.data.input_points, rng)
        return torch.from_numpy(pts.astype(np.float32))
    from PIL import Image

    try:
        with Image.open(input_path) as im:
            im = im.convert("RGB").resize((cfg.data.image_size,) * 2, Image.BILINEAR)
            arr = np.asarray(im, dtype=np.float32).transpose(2, 0, 1) / 255.0
    except OSError as exc:
        raise MnaError(f"cannot read image {input_path}: {exc}") from None
    return torch.from_numpy(arr)


def reconstruct_run(checkpoint: str | Path, input_path: str | Path, out: str | Path, reference: str | None = None,
                    device: str = "auto", points: int | None = None, grid: int | None = None,
                    log=print, overwrite: bool = False) -> dict:
    """Feed-forward reconstruction of ``input_path`` into the run folder ``out``; returns metrics.

    Point-cloud models take a mesh or point cloud (its own surface is the metrics' reference
    and its frame the output frame); image models take an image and need ``reference`` (the
    object's mesh or point cloud) for the frame and the metrics. ``out`` must be missing or
    empty unless ``overwrite`` (see :func:`mna.runfolder.prepare_run_folder`).
    """
    dev = resolve_device(device)
    ck: LoadedCheckpoint = load_checkpoint(checkpoint, dev)
    cfg = ck.cfg
    input_path = Path(input_path)
    if not input_path.is_file():
        raise MnaError(f"input file not found: {input_path}")
    is_image = input_path.suffix.lower() in IMAGE_EXTS
    if cfg.data.input == "points" and is_image:
        raise MnaError(f"this checkpoint encodes point clouds; {input_path.name} is an image")
    if cfg.data.input == "image" and not is_image:
        raise MnaError(f"this checkpoint encodes images (.jpg .png); got {input_path.name}")
    if cfg.data.input == "image" and reference is None:
        raise MnaError("this checkpoint encodes images: give --reference MESH_OR_CLOUD (frame and metrics)")
    surface = load_surface(reference or input_path)
    inputs = _encoder_input(cfg, input_path, surface, cfg.seed)
    out = prepare_output(out, resume=False, overwrite=overwrite, keep=[input_path, *([reference] if reference else [])],
                         can_resume=False)
    fit_cfg = cfg.fit_config(latent=0)  # the baked atlas is a plain per-shape one
    fit_cfg.preset = "reconstruct"
    t0 = time.perf_counter()
    atlas, z = shape_atlas(ck.model, inputs.to(dev), cfg.fit_config())
    seconds = time.perf_counter() - t0
    surface_path = str(reference or input_path)
    config_mod.save_yaml(out / "config.yaml", run_config_dict(fit_cfg, surface_path))
    fitter = Fitter(fit_cfg, surface, dev)  # fresh optimiser and RNG: `mna fit --resume` can refine it
    fitter.model = atlas
    fitter.optimizer = torch.optim.Adam(atlas.parameters(), lr=fit_cfg.lr)
    save_checkpoint(out, fitter, surface.normalization)
    _add_provenance(out / "checkpoint.pt", ck, z, input_path)
    metrics = extract_run(out, points=points, grid=grid, timings={"reconstruct": seconds}, surface=surface,
                          model=atlas, cfg=fit_cfg)
    metrics["reconstruct"] = {"checkpoint": str(ck.path), "input": str(input_path), "encoder": cfg.encoder.kind,
                              "encoder_weights": ck.state.get("encoder_weights"), "train_epoch": ck.state["epoch"],
                              "latent_norm": float(z.norm())}
    write_json(out / "metrics.json", metrics)
    return metrics


def _add_provenance(path: Path, ck: LoadedCheckpoint, z: torch.Tensor, input_path: Path) -> None:
    from mna.checkpoint import read_state, write_state

    state = read_state(path)
    state["reconstructed_from"] = {"checkpoint": str(ck.path), "input": str(input_path),
                                   "latent": z.detach().cpu()[0], "train_config": ck.state["config"]}
    write_state(path, state)


# -- mna evaluate -------------------------------------------------------------------------------
def evaluate_split(checkpoint: str | Path, split: str, root: str | None = None, limit: int = 0,
                   device: str = "auto", full: bool = True, out: str | None = None, progress: bool = True) -> dict:
    """Mean DESIGN metrics of a checkpoint over a dataset split (``limit`` items, 0 = all)."""
    from tqdm.auto import tqdm

    from mna import datasets

    dev = resolve_device(device)
    ck = load_checkpoint(checkpoint, dev)
    cfg = ck.cfg
    names = {"train": cfg.data.train_split, "val": cfg.data.val_split, "test": cfg.data.test_split}
    ds = datasets.build(cfg, names.get(split, split), root)
    n = len(ds) if not limit else min(limit, len(ds))
    rows = []
    for i in tqdm(range(n), desc=f"evaluate {split}", disable=not progress, dynamic_ncols=True, leave=False):
        rows += evaluate_items(ck.model, ds, [i], cfg, points=cfg.eval_points, full=full, device=dev)
    keys = FULL_METRICS if full else PCL_METRICS
    result = {"split": split, "items": n, "checkpoint": str(ck.path), **reduce_mean(rows, keys), "per_item": rows}
    if out:
        write_json(out, result)
    return result
