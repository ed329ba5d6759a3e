"""Fit fidelity on hard shapes, as curves of quality against steps and time (issue 18).

    .venv/bin/python benchmarks/fit_quality.py --hard [--steps 3000] [--curve-every 300]

Shapes a 3-chart fit finds hard, made procedurally (:data:`mna.shapes.HARD_SHAPES`: a genus-4
plate, a sphere with fine relief, a body with thin limbs, a 12-part assembly), plus the
shared 13-part truck when present. Each is fitted with a preset (``mna fit``'s default,
:data:`mna.config.DEFAULT_PRESET`, unless ``--preset`` names another) for a step budget;
every ``curve_every`` steps a copy of the model gets its own c and is scored by the same
metrics as a finished run (:func:`mna.reconstruct.shape_metrics`: F-score of the chart mesh
and of the point sample, distortions, occupancy), so the last point of a curve is the
fit's result. Training time excludes the scoring.
"""
from __future__ import annotations

import copy
import json
import time
from pathlib import Path

import numpy as np
import torch

from mna import config as C
from mna import shapes
from mna.data import load_surface
from mna.fit import Fitter
from mna.inference import settle_c
from mna.model import flush_denormals
from mna.reconstruct import shape_metrics

SHARED_HARD = ("cesium_milk_truck.obj",)


def hard_inputs(work: Path, meshes: Path) -> list[Path]:
    """The procedural hard shapes (written once under ``work``) and the shared ones present."""
    paths = [shapes.shape_file(name, work / "shapes") for name in shapes.HARD_SHAPES]
    return paths + [meshes / n for n in SHARED_HARD if (meshes / n).is_file()]


def score(fitter: Fitter, reference: np.ndarray) -> dict:
    """Metrics of the model as it stands, on a copy that gets its own c (as a finished fit)."""
    cfg = fitter.cfg
    model = copy.deepcopy(fitter.model).eval()
    settle_c(model, cfg)
    m = shape_metrics(model, reference, cfg, cfg.eval_points, full=True)
    return {k: m[k] for k in ("fscore_mesh", "fscore_pcl", "chamfer_mesh", "distortion_metric", "occupancy_mean")}


def curve(path: Path, steps: int, every: int, charts: int | str = 3, seed: int = 0, device: str = "cpu",
          hard_targets: int | None = None, threads: int = 0, preset: str = C.DEFAULT_PRESET) -> dict:
    """Fit ``path`` for ``steps`` steps, scoring every ``every``; the curve and the last score.

    ``charts``: a number, or ``auto`` (start with 3 and grow where coverage stalls, :mod:`mna.grow`);
    ``hard_targets``: None keeps the preset's; ``threads`` > 0 sets torch's CPU threads. The
    fitter opens a ``detail`` fit's encoding only in runs of ``chart_octaves_min_steps`` or more.
    """
    cfg = C.preset(preset)
    cfg.steps, cfg.seed, cfg.device = steps, seed, device
    surface = load_surface(path)
    if charts in ("auto", "grow"):
        cfg.charts_rule = "grow"
    else:
        cfg.model.charts, cfg.charts_rule = int(charts), "fixed"
    if hard_targets is not None:
        cfg.hard_targets = hard_targets
    if threads:
        torch.set_num_threads(threads)
    reference = surface.sample(cfg.eval_points, np.random.default_rng(cfg.seed + 3))
    fitter = Fitter(cfg, surface, torch.device(device))
    points = []
    with flush_denormals():
        while not fitter.done():
            t0 = time.perf_counter()
            fitter.train_step()
            fitter.elapsed += time.perf_counter() - t0
            if fitter.step % every == 0 or fitter.done():
                points.append({"step": fitter.step, "seconds": fitter.elapsed, **score(fitter, reference)})
                points[-1]["charts"] = fitter.model.charts
                print(f"  {path.stem} step {fitter.step} (K={fitter.model.charts}): "
                      f"F_mesh {points[-1]['fscore_mesh']:.2f}, "
                      f"d_metric {points[-1]['distortion_metric']:.3f}, {fitter.elapsed:.0f} s", flush=True)
    faces = len(surface.mesh.faces) if surface.is_mesh else 0
    return {"mesh": path.name, "faces": faces, "preset": preset, "charts": cfg.model.charts, "rule": cfg.charts_rule,
            "steps": steps,
            "hard_targets": cfg.hard_targets, "threads": torch.get_num_threads(),
            "sps": steps / max(fitter.elapsed, 1e-9), "wall": fitter.elapsed, "curve": points, **points[-1]}


def curves_figure(rows: list[dict], stem: Path) -> None:
    """F-score (mesh) and metric distortion against steps, one line per shape (PNG + PDF)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
    shapes_seen = sorted({r["mesh"] for r in rows})
    colours = {m: plt.cm.tab10(i % 10) for i, m in enumerate(shapes_seen)}
    for r in rows:
        # one colour per shape, one line style per variant: 3 fixed charts solid, more dashed,
        # grown dotted, hard targets dash-dot
        style = "-." if r.get("hard_targets") else ":" if r.get("rule") == "grow" else "-" if r["charts"] == 3 else "--"
        label = f"{Path(r['mesh']).stem} {row_preset(r)} K={r['charts']}{' grown' if r.get('rule') == 'grow' else ''}" + \
            (f" +{r['hard_targets']} hard" if r.get("hard_targets") else "") + f", {r['steps']} steps"
        s = [p["step"] for p in r["curve"]]
        kw = dict(marker="o", ms=3, color=colours[r["mesh"]], ls=style, label=label)
        ax[0].plot(s, [p["fscore_mesh"] for p in r["curve"]], **kw)
        ax[1].plot(s, [p["distortion_metric"] for p in r["curve"]], **kw)
    for m in shapes_seen:
        oracle = next((r["oracle"] for r in rows if r["mesh"] == m and r.get("oracle") is not None), None)
        if oracle is not None:
            ax[0].axhline(oracle, color=colours[m], ls=":", lw=0.6)
    ax[0].set(xlabel="steps", ylabel="F@1% (chart mesh)", title="Fidelity (dotted: oracle)")
    ax[1].set(xlabel="steps", ylabel="metric distortion", title="Distortion", yscale="log")
    ax[1].legend(fontsize=6, ncol=2, loc="upper right")
    fig.tight_layout()
    for ext in ("png", "pdf"):
        tmp = stem.with_name(f".{stem.name}.tmp.{ext}")
        fig.savefig(tmp, dpi=110)
        tmp.replace(stem.with_suffix(f".{ext}"))
    plt.close(fig)


def row_preset(row: dict) -> str:
    """The preset a cached row was fitted with (rows cached before the preset was recorded: ``fast``)."""
    return row.get("preset", "fast")


def row_name(stem: str, charts: int | str, hard_targets: int, steps: int, preset: str = "fast") -> str:
    """The cache file of one (shape, variant) row: variants run apart are reported together
    (``fast`` rows keep the names they were cached under)."""
    tag = "" if preset == "fast" else f"_{preset}"
    return f"{stem}_k{charts}_h{hard_targets}_s{steps}{tag}.json"


def save_row(folder: Path, row: dict, charts: int | str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / row_name(Path(row["mesh"]).stem, charts, row["hard_targets"], row["steps"], row_preset(row))
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(row, default=float))
    tmp.replace(path)
    return path


def load_rows(folder: Path) -> list[dict]:
    """Every cached row, ordered by shape then variant."""
    rows = [json.loads(p.read_text()) for p in sorted(folder.glob("*.json"))] if folder.is_dir() else []
    return sorted(rows, key=lambda r: (r["mesh"], r["steps"], row_preset(r), r["charts"], r["hard_targets"]))


def table(rows: list[dict]) -> str:
    head = ("| shape | faces | preset | K | hard targets | F_mesh | oracle F | gap | F_pcl | d_metric | occupancy % | "
            "steps | steps/s | train s | F_mesh at 25 / 50 / 75 % of the steps |\n|" + "---|" * 15)
    lines = [head]
    for r in rows:
        c = r["curve"]
        marks = [min(c, key=lambda p, q=q: abs(p["step"] - q * r["steps"]))["fscore_mesh"] for q in (0.25, 0.5, 0.75)]
        k = f"3 -> {r['charts']} (auto)" if r.get("rule") == "grow" else str(r["charts"])
        lines.append(f"| {r['mesh']} | {r['faces']} | {row_preset(r)} | {k} | {r.get('hard_targets', 0)} | "
                     f"{r['fscore_mesh']:.2f} | "
                     f"{r['oracle']:.2f} | "
                     f"{r['oracle'] - r['fscore_mesh']:.2f} | {r['fscore_pcl']:.2f} | {r['distortion_metric']:.3f} | "
                     f"{r['occupancy_mean']:.1f} | {r['steps']} | {r['sps']:.2f} | {r['wall']:.0f} | "
                     f"{' / '.join(f'{m:.1f}' for m in marks)} |")
    return "\n".join(lines)
