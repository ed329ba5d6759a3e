"""``mna demo``: the whole pipeline on a built-in procedural shape, in one command.

fit -> export (the reconstruction's packed, textured atlas) -> compare (xatlas on it, one
harness) -> render (Mitsuba 3 checkerboards and heat maps, both methods) -> unwrap (the input
mesh itself, UV-mapped with the same charts, into RUN/unwrap/) -> compare and render that
against xatlas on the input mesh -> report.md / report.html. Each stage is the same code path
as its own subcommand.
"""
from __future__ import annotations

import argparse
import time

from mnacore.errors import MnaError

#: The demo's fit is budgeted in steps, not seconds, so it gives one result on any machine.
#: It used to be 150 s of the fast preset: 1,050-1,350 steps on an idle 2-core machine
#: (7-9 steps/s), but 330 steps beside another job (F 58, a torn torus). 1,200 steps is the
#: middle of that range; measured on the demo torus (3 charts, seed 0, grid 128): 1,200 steps
#: gave fscore_mesh 94.4 and distortion_metric 0.25, a 150 s budget on the same machine
#: 1,393 steps, 94.6 and 0.22. With L_surf in the preset (docs/fit.md): 1,200 steps, 95.8 and 0.35.
DEMO_STEPS = 1200


def register(subparsers) -> None:
    p = subparsers.add_parser("demo", help="run the whole pipeline on a built-in shape (what `make demo` runs)",
                              description=__doc__.splitlines()[0])
    p.add_argument("-o", "--out", default="demo_run", metavar="RUN", help="run folder (default demo_run)")
    p.add_argument("--shape", default="torus", help="built-in shape: sphere, torus, genus2, two_spheres, sheet")
    p.add_argument("--charts", type=int, default=3)
    p.add_argument("--steps", type=int, default=DEMO_STEPS,
                   help=f"fit steps (default {DEMO_STEPS}: a busy or slow machine gets the same result, later)")
    p.add_argument("--res", type=int, default=512, help="render resolution (default 512)")
    p.add_argument("--spp", type=int, default=32, help="render samples per pixel (default 32)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--overwrite", action="store_true", help="replace the run already in RUN (`make demo` does)")
    p.set_defaults(func=run_demo)


def run_demo(args: argparse.Namespace) -> int:
    from mna import shapes
    from mna.cli import EXIT_INTERRUPTED, EXIT_TERMINATED, main
    from mna.config import MAX_CHARTS, MAX_SEED, check_int
    from mna.runfolder import prepare_run_folder
    from mnacore.atomic import atomic_path

    check_int(args.steps, "--steps", 1)
    check_int(args.charts, "--charts", 1, MAX_CHARTS)
    check_int(args.seed, "--seed", 0, MAX_SEED)
    if args.shape not in shapes.SHAPES:
        raise MnaError(f"--shape: unknown built-in shape {args.shape!r}; choose from {', '.join(shapes.SHAPES)}")
    # the demo also writes RUN/unwrap/ (its unwrap stage): --overwrite replaces it too
    out = prepare_run_folder(args.out, overwrite=args.overwrite, extra_outputs=("unwrap",))
    mesh = shapes.make(args.shape)
    src = out / f"input_{args.shape}.ply"
    with atomic_path(src) as tmp:
        mesh.export(tmp)
    render_opts = ["--res", str(args.res), "--spp", str(args.spp), "--views", "front,three_quarter",
                   "--heatmap", "metric,charts", "--seed", str(args.seed)]
    stages = [
        ("fit", ["fit", str(src), "-o", str(out), "--charts", str(args.charts), "--seed", str(args.seed),
                 "--steps", str(args.steps), "--grid", "128"]),
        ("export", ["export", str(out)]),
        ("compare", ["compare", str(out)]),
        ("render", ["render", str(out), *render_opts]),
        # the input mesh itself UV-mapped with the same charts, against xatlas on that mesh
        ("unwrap", ["unwrap", str(src), "-o", str(out / "unwrap"), "--run", str(out)]),
        ("compare unwrap", ["compare", str(out / "unwrap")]),
        ("render unwrap", ["render", str(out / "unwrap"), *render_opts]),
    ]
    timings = {}
    for name, argv in stages:
        print(f"== mna {' '.join(argv)}", flush=True)
        t0 = time.perf_counter()
        code = main(argv)
        timings[name] = time.perf_counter() - t0
        if code in (EXIT_INTERRUPTED, EXIT_TERMINATED):
            return code  # Ctrl-C / SIGTERM: the stage said what it saved
        if code != 0:
            raise MnaError(f"demo stage '{name}' failed with exit code {code}")
    from render.report import atlas_summary, write_report

    charts, islands = atlas_summary(out)
    report = write_report(out, title=f"mna demo: {args.shape}, a neural atlas of {charts or args.charts} charts")
    total = sum(timings.values())
    print("stage seconds: " + ", ".join(f"{k} {v:.1f}" for k, v in timings.items()) + f"; total {total:.0f}")
    print(f"report: {report.html} and {report.markdown.name}")
    return 0
