"""Fit quality per CPU budget on the shared real meshes; writes the ``## fit_quality`` section.

    .venv/bin/python benchmarks/fit_quality.py                      # 300 s per mesh, all meshes
    .venv/bin/python benchmarks/fit_quality.py --budget 60 --only bunny,eight --no-write
    .venv/bin/python benchmarks/fit_quality.py --hard --steps 3000 --curve-every 300   # section fit_quality_hard
    python benchmarks/fit_quality.py --device cuda --budget 60      # GPU: section fit_quality_cuda

For every mesh in ../shared/data/meshes: ``--preset`` (default ``mna fit``'s) with 3 charts (and 1 chart on
the open surfaces) under a wall-clock budget, then DESIGN's metrics; next to each, the
"oracle" F-score of two independent 25,000-point samples of the input surface (the
ceiling at this point count). Also steps/s of the ``paper`` preset on this machine.
Quality targets (issue 2): fscore_mesh >= 97 and distortion_metric <= 0.5 on the closed
meshes of genus 0-2 (bunny, spot, bob_tri, eight).
"""
from __future__ import annotations

import argparse
import os
import re
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import numpy as np  # noqa: E402
import torch  # noqa: E402

from mna import config as C  # noqa: E402
from mna.data import load_surface  # noqa: E402
from mna.fit import Fitter  # noqa: E402
from mna.metrics import chamfer_fscore  # noqa: E402
from mna.run import fit_run  # noqa: E402
from mnacore.machine import cpu_summary  # noqa: E402

RESULTS = ROOT / "benchmarks" / "RESULTS.md"
MESHES = ROOT.parent / "shared" / "data" / "meshes"
CLOSED = ("bunny.off", "spot.obj", "bob_tri.obj", "eight.off")
OPEN = ("tshirt.obj", "face.obj", "inspired_mesh.obj")
SEVERAL = ("cesium_milk_truck.obj",)


def oracle_fscore(path: Path, points: int = 25000) -> float:
    s = load_surface(path)
    a = s.sample(points, np.random.default_rng(1))
    b = s.sample(points, np.random.default_rng(2))
    return chamfer_fscore(a, b).fscore


def _sync(device: str) -> None:
    if device == "cuda":
        torch.cuda.synchronize()


def paper_steps_per_second(path: Path, steps: int, device: str = "cpu") -> float:
    cfg = C.paper()
    s = load_surface(path)
    f = Fitter(cfg, s, torch.device(device))
    f.train_step()  # warm-up
    _sync(device)
    t0 = time.perf_counter()
    for _ in range(steps):
        f.train_step()
    _sync(device)
    return steps / (time.perf_counter() - t0)


def run_one(path: Path, charts: int, budget: float, work: Path, device: str = "cpu",
            preset: str = C.DEFAULT_PRESET) -> dict:
    cfg = C.preset(preset)
    cfg.model.charts = charts
    cfg.time_budget = budget
    cfg.device = device
    t0 = time.perf_counter()
    name = path.stem if charts == 3 else f"{path.stem}_k{charts}"  # 3-chart runs feed atlas_vs_xatlas --reuse
    res = fit_run(str(path), work / name, cfg, progress_bar=False, log=lambda s: None)
    wall = time.perf_counter() - t0
    m = res.metrics
    return {"mesh": path.name, "charts": charts, "steps": res.steps, "sps": res.steps / res.seconds,
            "wall": wall, **{k: m[k] for k in ("fscore_mesh", "chamfer_mesh", "fscore_pcl", "precision_mesh",
                                                 "recall_mesh", "distortion_metric", "distortion_conformal",
                                                 "distortion_area", "occupancy_rate", "degenerate_charts")}}


def table(rows: list[dict], oracle: dict) -> str:
    head = ("| mesh | K | fscore_mesh | oracle F | chamfer_mesh | fscore_pcl | P / R (mesh) | d_metric | "
            "d_conformal | d_area | occupancy % | steps | steps/s | wall s |\n|" + "---|" * 14)
    lines = [head]
    for r in rows:
        lines.append(
            f"| {r['mesh']} | {r['charts']} | {r['fscore_mesh']:.2f} | {oracle[r['mesh']]:.2f} | "
            f"{r['chamfer_mesh']:.2e} | {r['fscore_pcl']:.2f} | {r['precision_mesh']:.1f} / {r['recall_mesh']:.1f} | "
            f"{r['distortion_metric']:.3f} | {r['distortion_conformal']:.3f} | {r['distortion_area']:.3f} | "
            f"{' / '.join(f'{o:.0f}' for o in r['occupancy_rate'])} | {r['steps']} | {r['sps']:.2f} | {r['wall']:.0f} |")
    return "\n".join(lines)


def write_section(name: str, text: str) -> None:
    """Replace (or append) the ``## name`` section of RESULTS.md, re-read just before writing."""
    from mnacore.atomic import write_text

    current = RESULTS.read_text() if RESULTS.is_file() else "# Benchmark results\n"
    pattern = re.compile(rf"^## {re.escape(name)}\n.*?(?=^## |\Z)", re.MULTILINE | re.DOTALL)
    new = (pattern.sub(lambda _: text.rstrip("\n") + "\n\n", current) if pattern.search(current)
           else current.rstrip("\n") + "\n\n" + text.rstrip("\n") + "\n")
    write_text(RESULTS, new)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", type=Path, default=MESHES)
    ap.add_argument("--budget", type=float, default=300.0, help="seconds of fitting per mesh (default 300)")
    ap.add_argument("--only", default="", help="comma-separated mesh stems to run (default: all)")
    ap.add_argument("--paper-steps", type=int, default=10, help="steps timed for the paper preset (0 = skip)")
    ap.add_argument("--work", type=Path, default=ROOT / "benchmarks" / "runs", help="run folders (git-ignored)")
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--device", default="cpu", choices=["cpu", "cuda"],
                    help="fit on this device (default cpu; cuda writes the section fit_quality_cuda)")
    ap.add_argument("--hard", action="store_true",
                    help="hard shapes (genus 4, fine relief, thin limbs, many parts) as curves; see fit_curves.py")
    ap.add_argument("--preset", default=C.DEFAULT_PRESET,
                    help=f"fit preset (default {C.DEFAULT_PRESET}, mna fit's; `detail` opens its encoding only in "
                    "runs long enough, which under --budget depends on the machine's pace)")
    ap.add_argument("--steps", type=int, default=3000, help="--hard: steps per fit (default: the presets' 3000)")
    ap.add_argument("--curve-every", type=int, default=300, help="--hard: score every this many steps")
    ap.add_argument("--charts", default="3", help="--hard: charts per fit, or auto (3, grown where coverage stalls)")
    ap.add_argument("--hard-targets", type=int, default=None, help="--hard: extra hard targets per step "
                    "(default: the preset's)")
    ap.add_argument("--threads", type=int, default=0, help="--hard: torch CPU threads (0 = torch's default)")
    ap.add_argument("--report-only", action="store_true", help="--hard: report the cached rows, fit nothing")
    args = ap.parse_args(argv)
    if args.hard:
        return hard_main(args)
    if not args.meshes.is_dir():
        print(f"fit_quality: mesh folder not found: {args.meshes}", file=sys.stderr)
        return 2
    only = {s for s in args.only.split(",") if s}
    jobs = [(n, 3) for n in CLOSED + SEVERAL + OPEN] + [(n, 1) for n in OPEN]
    jobs = [(n, k) for n, k in jobs if (args.meshes / n).is_file() and (not only or Path(n).stem in only)]
    rows, oracle = [], {}
    load = os.getloadavg()[0]
    for name, k in jobs:
        path = args.meshes / name
        oracle.setdefault(name, oracle_fscore(path))
        r = run_one(path, k, args.budget, args.work, args.device, args.preset)
        rows.append(r)
        print(f"{name} K={k}: F_mesh {r['fscore_mesh']:.2f} (oracle {oracle[name]:.2f}), "
              f"d_metric {r['distortion_metric']:.3f}, {r['steps']} steps, {r['sps']:.2f} steps/s", flush=True)
    paper_sps = None
    if args.paper_steps and (args.meshes / "bunny.off").is_file():
        paper_sps = paper_steps_per_second(args.meshes / "bunny.off", args.paper_steps, args.device)
        print(f"paper preset: {paper_sps:.2f} steps/s", flush=True)
    cfg = C.preset(args.preset)
    section = "fit_quality" if args.device == "cpu" else "fit_quality_cuda"
    if args.device == "cuda":
        where = f"{torch.cuda.get_device_name(0)} (CUDA {torch.version.cuda}), host {os.cpu_count()} cores"
    else:
        where = f"CPU, {torch.get_num_threads()} threads"
    flags = "" if args.device == "cpu" else f" --device {args.device}"
    text = (
        f"## {section}\n\n"
        f"`benchmarks/fit_quality.py --budget {args.budget:.0f}{flags} --preset {args.preset}`: preset "
        f"`{args.preset}` (width {cfg.model.chart_width}, "
        f"{cfg.uv_samples} UV samples/chart, {cfg.targets} fresh targets/step, L_dist on {cfg.dist_samples} "
        f"positives/chart, lr {cfg.lr} with cosine decay from {cfg.lr_decay_start:.0%} of the budget), seed 0, "
        f"{args.budget:.0f} s of fitting per mesh. Machine: {cpu_summary()}, "
        f"torch {torch.__version__} ({where}); load average at start {load:.1f}. "
        "Metrics in the unit-ball frame, 25,000 points each side; oracle F = two independent "
        "25,000-point samples of the input surface.\n\n"
        + table(rows, oracle) + "\n\n"
        + (f"Paper preset (width 512, 5,000 UV samples, 2,500 targets): **{paper_sps:.2f} steps/s** on this {args.device.upper()} "
           f"(bunny, 3 charts, {args.paper_steps} steps).\n" if paper_sps else "")
    )
    print(text)
    if not args.no_write:
        write_section(section, text)
    return 0


def hard_main(args) -> int:
    """``--hard``: curves of F and distortion against steps on hard shapes; section fit_quality_hard.

    Each (shape, variant) row is cached under ``WORK/hard_rows``, so variants run at different
    times (``--charts``, ``--hard-targets``) land in one table; ``--report-only`` fits nothing.
    """
    import fit_curves

    only = {s for s in args.only.split(",") if s}
    paths = [p for p in fit_curves.hard_inputs(args.work, args.meshes) if not only or p.stem in only]
    cache = args.work / "hard_rows"
    load = os.getloadavg()[0]
    for path in [] if args.report_only else paths:
        oracle = oracle_fscore(path)
        print(f"{path.name}: oracle F {oracle:.2f}", flush=True)
        row = fit_curves.curve(path, args.steps, args.curve_every, charts=args.charts, device=args.device,
                               hard_targets=args.hard_targets, threads=args.threads, preset=args.preset)
        fit_curves.save_row(cache, {**row, "oracle": oracle, "load": load}, args.charts)
    rows = fit_curves.load_rows(cache)
    if not rows:
        print("fit_quality --hard: no rows to report", file=sys.stderr)
        return 2
    fig = (args.work if args.no_write else ROOT / "benchmarks") / "fit_quality_hard"
    fit_curves.curves_figure(rows, fig)
    cfg = C.preset(args.preset)
    text = (
        "## fit_quality_hard\n\n"
        "`benchmarks/fit_quality.py --hard --steps N --curve-every M [--preset P] [--charts K|auto] "
        f"[--hard-targets H] [--threads T]`: the row's preset (`{args.preset}` in this run; width "
        f"{cfg.model.chart_width}, {cfg.uv_samples} UV samples/chart, "
        f"{cfg.targets} uniform targets/step), seed 0, on {args.device} ({cpu_summary()}, "
        f"torch {torch.__version__}). One row per shape and variant (K charts; `3 -> K (auto)`: started with 3 "
        "and grown where coverage stalled, `mna.grow`; hard targets: extra targets per step where the charts err most, "
        "`mna.hard_targets`). Scores every M steps on a copy of the model with its own c (the same metrics as a "
        "finished run); train s excludes the scoring. Oracle F = two independent 25,000-point samples of the input "
        "surface. Curves: `benchmarks/fit_quality_hard.png`.\n\n" + fit_curves.table(rows) + "\n"
    )
    print(text)
    if not args.no_write:
        write_section("fit_quality_hard", text + kept_notes("fit_quality_hard"))
    return 0


def kept_notes(name: str) -> str:
    """The hand-written ``Notes ...`` that follow a section's generated table (kept on rewrite)."""
    current = RESULTS.read_text() if RESULTS.is_file() else ""
    match = re.search(rf"^## {re.escape(name)}\n.*?(?=^## |\Z)", current, re.MULTILINE | re.DOTALL)
    notes = match and re.search(r"^Notes .*", match.group(0), re.MULTILINE | re.DOTALL)
    return "\n" + notes.group(0) if notes else ""


if __name__ == "__main__":
    sys.exit(main())
