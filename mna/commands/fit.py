"""``mna fit`` and ``mna extract``."""
from __future__ import annotations

import argparse
import signal
from pathlib import Path

from mnacore.errors import MnaError


def register(subparsers) -> None:
    from mna import config as C

    p = subparsers.add_parser("fit", help="fit a Minimal Neural Atlas to a mesh or point cloud",
                              description="Fit a neural atlas of K charts to INPUT and write the run folder RUN.")
    p.add_argument("input", metavar="INPUT", help="mesh (.obj .ply .off .stl .glb) or point cloud (.ply .xyz .npy .npz)")
    p.add_argument("-o", "--out", required=True, metavar="RUN", help="run folder to write")
    p.add_argument("--charts", default=None, metavar="K|auto",
                   help="K charts throughout, or auto: start with 3 and add charts (up to 6) where the coverage "
                        "stalls")
    p.add_argument("--preset", default=C.DEFAULT_PRESET,
                   help=f"detail (fast with the charts' input encoded, finer reconstructions; runs under "
                   f"{C.preset('detail').chart_octaves_min_steps:,} steps are fast), fast (fewer islands in the "
                   f"textured reconstruction), paper or tiny; default {C.DEFAULT_PRESET}")
    p.add_argument("--config", default=None, metavar="YAML", help="start from a saved config.yaml instead of a preset")
    p.add_argument("--seed", type=int, default=None)
    p.add_argument("--device", default=None, choices=["auto", "cpu", "cuda"])
    budget = p.add_mutually_exclusive_group()
    budget.add_argument("--steps", type=int, default=None, help="optimisation steps")
    budget.add_argument("--time-budget", type=float, default=None, metavar="SECONDS",
                        help="fit for this many seconds (the lr schedule follows elapsed time)")
    again = p.add_mutually_exclusive_group()
    again.add_argument("--resume", action="store_true", help="continue from RUN/checkpoint.pt with RUN/config.yaml")
    again.add_argument("--overwrite", action="store_true",
                       help="replace the run in RUN: first remove every file mna wrote there (a non-empty RUN "
                            "is refused without --resume or --overwrite)")
    p.add_argument("--grid", type=int, default=None, help="UV grid resolution of the extracted chart meshes (default 256)")
    p.add_argument("--threads", type=int, default=None, help="torch CPU threads")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    ab = p.add_argument_group("ablations (paper Sec. 5)")
    ab.add_argument("--no-reformulation", action="store_true", help="occupancy classifies UV directly")
    ab.add_argument("--naive-classifier", action="store_true", help="binary classification instead of PU (c = 1)")
    ab.add_argument("--no-pe", action="store_true", help="no positional encoding in l_k")
    ab.add_argument("--no-distortion", action="store_true", help="no distortion loss")
    ab.add_argument("--atlasnet", action="store_true", help="no occupancy: every chart is its full square")
    p.set_defaults(func=run_fit)

    e = subparsers.add_parser("extract", help="extract points and chart meshes from a fitted run")
    e.add_argument("run", metavar="RUN")
    e.add_argument("--points", type=int, default=25000, help="point count for points.ply (default 25000)")
    e.add_argument("--grid", type=int, default=256, help="UV grid resolution per chart (default 256)")
    e.add_argument("--device", default="auto", choices=["auto", "cpu", "cuda"])
    e.set_defaults(func=run_extract)


def build_config(args: argparse.Namespace):
    from mna import config as C
    from mna.run import load_run_config

    if args.resume:
        cfg, _ = load_run_config(args.out)
    elif args.config:
        data = C.load_yaml(args.config)
        data.pop("input", None)
        cfg = C.from_dict(data)
    else:
        cfg = C.preset(args.preset)
    if args.charts is not None:
        set_charts(cfg, args.charts, args.resume)
    if args.seed is not None:
        cfg.seed = args.seed
    if args.device is not None:
        cfg.device = args.device
    if args.steps is not None:
        cfg.steps, cfg.time_budget = args.steps, None
    if args.time_budget is not None:
        cfg.time_budget = args.time_budget
    if args.threads is not None:
        cfg.threads = args.threads
    if args.grid is not None:
        cfg.grid = args.grid
    if args.no_reformulation:
        cfg.ablation.occupancy_on_uv = True
    if args.naive_classifier:
        cfg.ablation.naive_classifier = True
    if args.no_pe:
        cfg.model.octaves = 0
    if args.no_distortion:
        cfg.loss.w_dist = cfg.late_w_dist = 0.0
    if args.atlasnet:
        cfg.ablation.atlasnet = True
    return cfg.validate()


#: charts an ``auto`` fit starts with (the paper's K)
AUTO_START = 3


def set_charts(cfg, value: str | int, resume: bool) -> None:
    """``--charts K`` fixes K; ``--charts auto`` starts with 3 and grows charts where the
    coverage stalls (:mod:`mna.grow`). On --resume it must agree with the run's."""
    if str(value) == "auto":
        if resume and cfg.charts_rule != "grow":
            raise MnaError(f"--charts auto differs from the run's fixed {cfg.model.charts} charts; cannot resume")
        if not resume:
            cfg.model.charts = min(AUTO_START, cfg.max_charts)
        cfg.charts_rule = "grow"
        return
    try:
        charts = int(value)
    except (TypeError, ValueError):
        raise MnaError(f"--charts must be an integer or auto, got {value!r}") from None
    if resume and charts != cfg.model.charts:
        raise MnaError(f"--charts {charts} differs from the run's {cfg.model.charts}; cannot resume")
    cfg.model.charts, cfg.charts_rule = charts, "fixed"


def run_fit(args: argparse.Namespace) -> int:
    from mna.run import fit_run, load_run_config

    if args.resume:
        _, input_path = load_run_config(args.out)
        if Path(args.input).resolve() != Path(input_path).resolve():
            raise MnaError(f"--resume: INPUT {args.input} differs from the run's input {input_path}")
    cfg = build_config(args)
    result = fit_run(args.input, args.out, cfg, resume=args.resume, progress_bar=not args.no_progress,
                     overwrite=args.overwrite)
    if result.interrupted:
        from mna.interrupt import exit_code

        return exit_code(result.stop_signal or signal.SIGINT)
    m = result.metrics
    print(f"done: {result.steps} steps in {result.seconds:.0f} s; fscore_mesh {m['fscore_mesh']:.2f}, "
          f"chamfer_mesh {m['chamfer_mesh']:.2e}, distortion_metric {m['distortion_metric']:.3f}, "
          f"occupancy {', '.join(f'{r:.0f}%' for r in m['occupancy_rate'])} -> {result.run}")
    return 0


def run_extract(args: argparse.Namespace) -> int:
    from mna.config import MAX_GRID
    from mna.fit import resolve_device
    from mna.run import extract_run

    if not Path(args.run).is_dir():
        raise MnaError(f"run folder not found: {args.run}")
    if args.points is not None and args.points < 1:
        raise MnaError(f"--points must be positive, got {args.points}")
    if args.grid is not None and not 2 <= args.grid <= MAX_GRID:
        raise MnaError(f"--grid must be between 2 and {MAX_GRID}, got {args.grid}")
    m = extract_run(args.run, points=args.points, grid=args.grid, device=str(resolve_device(args.device)))
    print(f"extracted {m['points']} points and {m['mesh_faces']} chart faces; fscore_mesh {m['fscore_mesh']:.2f}, "
          f"distortion_metric {m['distortion_metric']:.3f} -> {args.run}")
    return 0
