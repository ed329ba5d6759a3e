"""``mna demo``: the whole pipeline on a built-in procedural shape, in one command.

fit -> export (packed, textured atlas) -> compare (xatlas, one harness) -> render
(Mitsuba 3 checkerboards and heat maps, both methods) -> report.md / report.html.
Each stage is the same code path as its own subcommand.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

from mna.errors import MnaError


def register(subparsers) -> None:
    p = subparsers.add_parser("demo", help="run the whole pipeline on a built-in shape (what `make demo` runs)",
                              description=__doc__.splitlines()[0])
    p.add_argument("-o", "--out", default="demo_run", metavar="RUN", help="run folder (default demo_run)")
    p.add_argument("--shape", default="torus", help="built-in shape: sphere, torus, genus2, two_spheres, sheet")
    p.add_argument("--charts", type=int, default=3)
    p.add_argument("--time-budget", type=float, default=150.0, metavar="SECONDS", help="fit time (default 150)")
    p.add_argument("--res", type=int, default=512, help="render resolution (default 512)")
    p.add_argument("--spp", type=int, default=32, help="render samples per pixel (default 32)")
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=run_demo)


def run_demo(args: argparse.Namespace) -> int:
    from mna import shapes
    from mna.atomic import atomic_path
    from mna.cli import main

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise MnaError(f"output path exists and is not a folder: {out}")
    out.mkdir(parents=True, exist_ok=True)
    mesh = shapes.make(args.shape)
    src = out / f"input_{args.shape}.ply"
    with atomic_path(src) as tmp:
        mesh.export(tmp)
    stages = [
        ("fit", ["fit", str(src), "-o", str(out), "--charts", str(args.charts), "--seed", str(args.seed),
                 "--time-budget", str(args.time_budget), "--grid", "128"]),
        ("export", ["export", str(out)]),
        ("compare", ["compare", str(out)]),
        ("render", ["render", str(out), "--res", str(args.res), "--spp", str(args.spp),
                    "--views", "front,three_quarter", "--heatmap", "metric,charts", "--seed", str(args.seed)]),
    ]
    timings = {}
    for name, argv in stages:
        print(f"== mna {' '.join(argv)}", flush=True)
        t0 = time.perf_counter()
        code = main(argv)
        timings[name] = time.perf_counter() - t0
        if code != 0:
            raise MnaError(f"demo stage '{name}' failed with exit code {code}")
    from render.report import atlas_summary, write_report

    charts, islands = atlas_summary(out)
    report = write_report(out, title=f"mna demo: {args.shape}, a neural atlas of {charts or args.charts} charts "
                                     f"unwrapped into {islands if islands is not None else '?'} UV islands")
    total = sum(timings.values())
    print("stage seconds: " + ", ".join(f"{k} {v:.1f}" for k, v in timings.items()) + f"; total {total:.0f}")
    print(f"report: {report.html} and {report.markdown.name}")
    return 0
