"""``mna train``, ``mna reconstruct`` and ``mna evaluate``: the conditional atlas over datasets."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from mna import train_config
from mnacore.errors import MnaError


def register(subparsers) -> None:
    """Add this group's subcommands to the `mna` parser."""
    t = subparsers.add_parser("train", help="train the conditional atlas on a dataset of shapes",
                              description="Train one network for a whole dataset (one process; for several GPUs "
                                          "or nodes run `torchrun --nproc_per_node=N -m mna.train CONFIG.yaml`).")
    train_config.add_arguments(t)
    t.set_defaults(func=run_train)

    r = subparsers.add_parser("reconstruct", help="feed-forward reconstruction of one shape into a run folder",
                              description="Encode INPUT with a trained checkpoint and write the same run folder "
                                          "as `mna fit` (export, compare and render take it unchanged).")
    r.add_argument("checkpoint", metavar="CHECKPOINT", help="training checkpoint.pt (or its training folder)")
    r.add_argument("input", metavar="INPUT", help="mesh or point cloud (point models) or image (image models)")
    r.add_argument("-o", "--out", required=True, metavar="RUN", help="run folder to write")
    r.add_argument("--reference", default=None, metavar="SURFACE",
                   help="image models: the object's mesh or point cloud (output frame and metrics)")
    r.add_argument("--points", type=int, default=None, help="points in points.ply (default: the config's)")
    r.add_argument("--grid", type=int, default=None, help="UV grid resolution per chart (default: the config's)")
    r.add_argument("--device", default="auto", choices=["auto", "cpu", "cuda"])
    r.add_argument("--overwrite", action="store_true", help="replace the run already in RUN (else RUN must be empty)")
    r.set_defaults(func=run_reconstruct)

    e = subparsers.add_parser("evaluate", help="the paper's metrics of a checkpoint over a dataset split",
                              description="Reconstruct every item of a split feed-forward and report mean "
                                          "Chamfer, F-score and distortion metrics (unit-ball frame).")
    e.add_argument("checkpoint", metavar="CHECKPOINT")
    e.add_argument("--split", default="test", help="train, val, test or a split file name (default test)")
    e.add_argument("--root", default=None, help="dataset folder (default: the one the checkpoint was trained on)")
    e.add_argument("--limit", type=int, default=0, help="evaluate the first N items only (0 = all)")
    e.add_argument("--points-only", action="store_true", help="point-cloud metrics only (faster)")
    e.add_argument("-o", "--out", default=None, metavar="JSON", help="write the results here")
    e.add_argument("--device", default="auto", choices=["auto", "cpu", "cuda"])
    e.add_argument("--no-progress", action="store_true")
    e.set_defaults(func=run_evaluate)


def run_train(args: argparse.Namespace) -> int:
    from mna.train import run_as_rank

    return run_as_rank("mna train", args)


def run_reconstruct(args: argparse.Namespace) -> int:
    from mna.reconstruct import reconstruct_run

    if args.points is not None and args.points < 1:
        raise MnaError(f"--points must be positive, got {args.points}")
    if args.grid is not None and args.grid < 2:
        raise MnaError(f"--grid must be at least 2, got {args.grid}")
    m = reconstruct_run(args.checkpoint, args.input, args.out, reference=args.reference, device=args.device,
                        points=args.points, grid=args.grid, overwrite=args.overwrite)
    print(f"reconstructed in {m['timings']['reconstruct']:.3f} s: fscore_mesh {m['fscore_mesh']:.2f}, "
          f"chamfer_mesh {m['chamfer_mesh']:.2e}, distortion_metric {m['distortion_metric']:.3f}, "
          f"occupancy {', '.join(f'{r:.0f}%' for r in m['occupancy_rate'])} -> {args.out}")
    return 0


def run_evaluate(args: argparse.Namespace) -> int:
    from mna.reconstruct import evaluate_split

    if args.limit < 0:
        raise MnaError(f"--limit must be >= 0, got {args.limit}")
    if args.out and Path(args.out).is_dir():
        raise MnaError(f"--out must be a file path, got the folder {args.out}")
    r = evaluate_split(args.checkpoint, args.split, root=args.root, limit=args.limit, device=args.device,
                       full=not args.points_only, out=args.out, progress=not args.no_progress)
    summary = {k: v for k, v in r.items() if k not in ("per_item", "checkpoint")}
    print(json.dumps(summary, indent=2))
    return 0
