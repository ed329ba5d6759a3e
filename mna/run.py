"""The run folder (DESIGN contract): fit a surface into RUN/, extract and measure it.

``fit_run`` writes ``config.yaml`` and ``checkpoint.pt`` as it goes, then ``extract_run``
writes ``points.ply``, ``charts.npz``, ``charts.ply`` and ``metrics.json``. Every file is
written under a temporary name and renamed, so an interrupted run leaves no half file.
"""
from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import torch
import trimesh

from mna import config as config_mod
from mna.checkpoint import read_state, write_state
from mna.config import FitConfig
from mna.data import Surface, load_surface
from mna.fit import Fitter, resolve_device
from mna.inference import extract_grid, rejection_sample, settle_c
from mna.metrics import atlas_distortion, chamfer_fscore, sample_mesh
from mna.model import NeuralAtlas, flush_denormals
from mna.runfolder import prepare_run_folder, remove_derived
from mnacore.atomic import atomic_path, write_json
from mnacore.charts import save_charts
from mnacore.errors import MnaError
from mnacore.frame import Normalization, far_from_origin
from mnacore.machine import cpu_summary
from mnacore.topology import mesh_topology

CONFIG = "config.yaml"
CHECKPOINT = "checkpoint.pt"
METRICS = "metrics.json"
POINTS = "points.ply"
CHARTS = "charts.npz"
CHARTS_PLY = "charts.ply"


def prepare_output(out: str | Path, resume: bool, overwrite: bool = False, keep=(), can_resume: bool = True) -> Path:
    """The run folder of a fit: see :func:`mna.runfolder.prepare_run_folder`."""
    return prepare_run_folder(out, resume=resume, overwrite=overwrite, keep=keep, resume_file=CHECKPOINT,
                              can_resume=can_resume)


def read_metrics(run: str | Path) -> dict:
    """``RUN/metrics.json`` as a dict ({} when absent); a damaged file is named in the error."""
    path = Path(run) / METRICS
    if not path.is_file():
        return {}
    try:
        data = json.loads(path.read_text())
    except (ValueError, UnicodeDecodeError) as exc:
        raise MnaError(f"{path} is not valid JSON ({str(exc).splitlines()[0]}); delete it to start its "
                       f"metrics afresh") from None
    if not isinstance(data, dict):
        raise MnaError(f"{path} must hold a JSON object, got {type(data).__name__}; delete it to start afresh")
    return data


def run_config_dict(cfg: FitConfig, input_path: str) -> dict:
    data = config_mod.to_dict(cfg)
    return {"input": str(input_path), **data}


def load_run_config(run: str | Path) -> tuple[FitConfig, str]:
    """``(FitConfig, input path)`` from ``RUN/config.yaml``."""
    data = config_mod.load_yaml(Path(run) / CONFIG)
    input_path = data.pop("input", None)
    if input_path is None:
        raise MnaError(f"{Path(run) / CONFIG} has no 'input' key")
    return config_mod.from_dict(data).validate(), input_path


def save_checkpoint(run: Path, fitter: Fitter, normalization: Normalization) -> None:
    state = fitter.state_dict()
    state["normalization"] = normalization.to_dict()
    state["config"] = config_mod.to_dict(fitter.cfg)
    write_state(run / CHECKPOINT, state)


@dataclass
class FitRunResult:
    run: Path
    interrupted: bool
    steps: int
    seconds: float
    metrics: dict | None
    stop_signal: int | None = None
    """SIGINT or SIGTERM when a signal interrupted the fit (the checkpoint is saved)."""


def fit_run(input_path: str | Path, out: str | Path, cfg: FitConfig, resume: bool = False,
            callback: Callable[[int], bool] | None = None, progress_bar: bool = True,
            extract: bool = True, log: Callable[[str], None] = print, overwrite: bool = False) -> FitRunResult:
    """Fit ``input_path`` into the run folder ``out`` (resuming from its checkpoint if asked).

    ``out`` must be missing or empty unless ``resume`` (continue it) or ``overwrite`` (replace
    the run that is there); see :func:`mna.runfolder.prepare_run_folder`.
    """
    cfg.validate()
    # everything is validated before the output folder is touched
    surface = load_surface(input_path)
    device = resolve_device(cfg.device)
    if resume:
        read_metrics(out)  # a damaged metrics.json fails now, not after the fit
    out = prepare_output(out, resume, overwrite, keep=[input_path])
    if cfg.threads:
        torch.set_num_threads(cfg.threads)
    # Flush-to-zero is per thread and inherited by threads created under it: switching it on
    # before the model exists lets torch's worker pool start with it too (2x faster fits here).
    # Extraction runs outside: its scipy work (Chamfer) stays in the CPU's normal mode.
    if not resume:  # a resumed run keeps the model its checkpoint has
        config_mod.settle_encoding(cfg)
    with flush_denormals():
        fitter = Fitter(cfg, surface, device)
        result, fit_seconds = _optimise(fitter, cfg, surface, out, input_path, resume, callback, progress_bar, log)
    if extract and not result.interrupted:
        result.metrics = extract_run(out, timings={"fit": fit_seconds,
                                                   "steps_per_second": fitter.step / max(fitter.elapsed, 1e-9)},
                                     surface=surface, model=fitter.model, cfg=cfg)
    return result


def _optimise(fitter: Fitter, cfg: FitConfig, surface: Surface, out: Path, input_path, resume: bool,
              callback, progress_bar: bool, log) -> tuple[FitRunResult, float]:
    """Resume if asked, optimise, then set c; returns the result (no metrics yet) and the fit time."""
    device = fitter.device
    if resume:
        state = read_state(out / CHECKPOINT, map_location=device)
        try:
            fitter.load_state_dict(state)
        except (RuntimeError, KeyError, TypeError, ValueError) as exc:
            raise MnaError(f"checkpoint in {out} does not match this configuration: {str(exc).splitlines()[0]}") from None
        log(f"resuming from step {fitter.step} ({fitter.elapsed:.1f} s done)")
        stale = remove_derived(out)  # an export, comparison or renders of the charts before this resume
        if stale:
            log(f"removed what was made from the earlier charts ({', '.join(stale)}): run mna export, compare, "
                f"render again after the fit")
    config_mod.save_yaml(out / CONFIG, run_config_dict(cfg, str(input_path)))
    encoding = config_mod.encoding_summary(cfg)
    log(f"fitting {Path(input_path).name} ({'mesh' if surface.is_mesh else 'point cloud'}) with "
        f"{cfg.model.charts} chart(s), preset {cfg.preset}{', ' + encoding if encoding else ''}, device {device}")
    t0 = time.perf_counter()
    saved_charts = cfg.model.charts

    def checkpoint(f: Fitter) -> None:
        nonlocal saved_charts
        save_checkpoint(out, f, surface.normalization)
        if cfg.model.charts != saved_charts:  # a chart grew (mna.grow): config.yaml says how many now
            config_mod.save_yaml(out / CONFIG, run_config_dict(cfg, str(input_path)))
            saved_charts = cfg.model.charts

    interrupted = fitter.run(checkpoint, callback, progress_bar)
    fit_seconds = time.perf_counter() - t0
    if interrupted:
        log(f"interrupted at step {fitter.step}; checkpoint saved to {out / CHECKPOINT} (continue with --resume)")
        return FitRunResult(out, True, fitter.step, fitter.elapsed, None, fitter.stop_signal), fit_seconds
    settle_c(fitter.model, cfg)  # c is part of the model from here on (saved with the checkpoint)
    save_checkpoint(out, fitter, surface.normalization)
    return FitRunResult(out, False, fitter.step, fitter.elapsed, None), fit_seconds


def load_model(run: str | Path, device: str = "cpu") -> tuple[NeuralAtlas, FitConfig, Normalization, dict]:
    """Model (with its fitted c), config and normalisation from a run folder."""
    run = Path(run)
    if not (run / CHECKPOINT).is_file():
        raise MnaError(f"no {CHECKPOINT} in {run}: run `mna fit` first")
    cfg, _ = load_run_config(run)
    state = read_state(run / CHECKPOINT, map_location=device)
    model = NeuralAtlas.from_config(cfg.model, cfg.ablation).to(device)
    try:
        model.load_state_dict(state["model"])
        norm = Normalization.from_dict(state["normalization"])
    except (RuntimeError, KeyError, TypeError, ValueError) as exc:
        raise MnaError(f"{run / CHECKPOINT} does not match {run / CONFIG}: {str(exc).strip().splitlines()[0]}") from None
    return model.eval(), cfg, norm, state


def extract_run(run: str | Path, points: int | None = None, grid: int | None = None, timings: dict | None = None,
                surface: Surface | None = None, model: NeuralAtlas | None = None, cfg: FitConfig | None = None,
                device: str = "cpu") -> dict:
    """Write points.ply, charts.npz, charts.ply and metrics.json for a fitted run."""
    run = Path(run)
    if points is not None and points < 1:
        raise MnaError(f"--points must be positive, got {points}")
    if grid is not None and grid < 2:
        raise MnaError(f"--grid must be at least 2, got {grid}")
    old = read_metrics(run)  # before any work: a damaged file is reported, not overwritten late
    if model is None or cfg is None:
        model, cfg, _, _ = load_model(run, device)
    if surface is None:
        _, input_path = load_run_config(run)
        surface = load_surface(input_path)
    norm = surface.normalization
    n_points = cfg.eval_points if points is None else points
    resolution = cfg.grid if grid is None else grid
    if n_points < 1:
        raise MnaError(f"--points must be positive, got {n_points}")
    if resolution < 2:
        raise MnaError(f"--grid must be at least 2, got {resolution}")
    model.eval()
    timings = dict(timings or {})
    t0 = time.perf_counter()
    gen = torch.Generator().manual_seed(cfg.seed + 2)
    sample = rejection_sample(model, n_points, gen, cfg.tau)
    timings["extract_points"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    chart_grid = extract_grid(model, resolution, cfg.tau)
    timings["extract_mesh"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    rng = np.random.default_rng(cfg.seed + 3)
    ref = surface.sample(cfg.eval_points, rng)
    pcl = chamfer_fscore(sample.points, ref)
    mesh_pts = sample_mesh(chart_grid.vertices, chart_grid.faces, cfg.eval_points, seed=cfg.seed + 4)
    mesh_m = chamfer_fscore(mesh_pts, ref)
    dist = atlas_distortion(model, cfg.eval_uv_samples, torch.Generator().manual_seed(cfg.seed + 5), cfg.tau, cfg.loss.eps)
    timings["metrics"] = time.perf_counter() - t0

    _write_points(run / POINTS, norm.invert(sample.points), _coordinate_dtype(norm))
    _write_charts(run, chart_grid, norm, cfg.tau)
    metrics = {
        "chamfer_pcl": pcl.chamfer, "fscore_pcl": pcl.fscore,
        "chamfer_mesh": mesh_m.chamfer, "fscore_mesh": mesh_m.fscore,
        "precision_mesh": mesh_m.precision, "recall_mesh": mesh_m.recall,
        "distortion_metric": dist.distortion_metric, "distortion_conformal": dist.distortion_conformal,
        "distortion_area": dist.distortion_area, "occupancy_rate": dist.occupancy_rate,
        "degenerate_charts": dist.degenerate_charts,
        "charts": cfg.model.charts, "charts_rule": cfg.charts_rule, "c": float(model.c),
        "points": int(len(sample.points)), "input_topology": _topology(surface),
        "acceptance_rate": sample.acceptance, "mesh_faces": int(len(chart_grid.faces)),
        "normalization": norm.to_dict(), "input": surface.path,
        "device": str(next(model.parameters()).device), "torch": torch.__version__,
        "machine": cpu_summary(),
    }
    metrics["timings"] = {**old.get("timings", {}), **timings}
    write_json(run / METRICS, metrics)
    return metrics


def _topology(surface: Surface) -> dict | None:
    """Parts, genus per part, boundary loops of a mesh input (None for a point cloud): what
    makes an input hard for few charts, next to how many the fit used."""
    if not surface.is_mesh:
        return None
    t = mesh_topology(surface.mesh.vertices, surface.mesh.faces)
    return {"parts": t.parts, "genus": t.total_genus, "genus_per_part": list(t.genus),
            "boundaries": int(sum(t.boundaries)), "manifold": t.manifold}


def _write_points(path: Path, points: np.ndarray, dtype: type = np.float32) -> None:
    _write_ply(path, points, None, dtype)


def _write_ply(path: Path, vertices: np.ndarray, faces: np.ndarray | None, dtype: type) -> None:
    """trimesh's PLY (always float32) unless ``dtype`` is float64 or there is no vertex (a
    collapsed fit samples no point, and trimesh cannot write an empty cloud): then a binary
    PLY written here, which trimesh, Open3D and Blender read too."""
    if dtype == np.float32 and len(vertices):
        obj = trimesh.PointCloud(vertices) if faces is None else trimesh.Trimesh(vertices, faces, process=False)
        with atomic_path(path) as tmp:
            obj.export(tmp)
        return
    kind, fmt = ("double", "<f8") if dtype == np.float64 else ("float", "<f4")
    v = np.ascontiguousarray(np.reshape(vertices, (-1, 3)), dtype=fmt)
    header = ["ply", "format binary_little_endian 1.0", f"element vertex {len(v)}",
              f"property {kind} x", f"property {kind} y", f"property {kind} z"]
    body = v.tobytes()
    if faces is not None:
        f = np.zeros(len(faces), dtype=[("n", "u1"), ("i", "<i4", (3,))])
        f["n"], f["i"] = 3, np.asarray(faces)
        header += [f"element face {len(f)}", "property list uchar int vertex_indices"]
        body += f.tobytes()
    with atomic_path(path) as tmp:
        tmp.write_bytes(("\n".join(header + ["end_header", ""])).encode() + body)


def _coordinate_dtype(norm: Normalization) -> type:
    """float32 for input-frame coordinates unless the input's scale is outside what float32
    keeps to full precision (normal numbers 1.2e-38 .. 3.4e38): a 1e-40 or 1e200 shape is
    written as float64 instead of subnormals or inf; so is a shape far from the origin for its
    size (:func:`mnacore.frame.far_from_origin`: a scan in map coordinates)."""
    extent = float(np.abs(norm.center).max()) + norm.scale
    far = far_from_origin(extent, 2 * norm.scale)
    return np.float32 if 1e-30 <= norm.scale and extent <= 1e37 and not far else np.float64


def _write_charts(run: Path, g, norm: Normalization, tau: float) -> None:
    """``charts.npz`` (the one writer, :func:`mnacore.charts.save_charts`) and ``charts.ply``."""
    K, G = g.xyz.shape[:2]
    xyz_in = norm.invert(g.xyz.reshape(-1, 3)).reshape(K, G, G, 3)
    dt = _coordinate_dtype(norm)
    save_charts(run / CHARTS, g.uv, xyz_in, g.occ, tau, norm, dt)
    verts_in = xyz_in.reshape(-1, 3)[g.grid_index]
    _write_ply(run / CHARTS_PLY, verts_in, g.faces, dt)
