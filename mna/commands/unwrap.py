"""``mna unwrap MESH -o OUT``: neural-chart UVs on the user's own mesh (texture.unwrap)."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from mnacore.errors import MnaError

#: Fit steps of ``mna unwrap`` without ``--steps`` or ``--time-budget`` (the preset's own where
#: fewer). The unwrap takes only a segmentation from the charts and flattens every island
#: classically, so it needs far less fit than a reconstruction: on the 19 benchmark and
#: held-out shapes, fits of 250, 500 and 1,000 steps gave the same seams in sum (88.6, 88.0,
#: 88.1; median 0.40, 0.37, 0.37 of xatlas's), islands, distortion and utilisation within the
#: spread from one fit to the next (benchmarks/RESULTS.md, unwrap_vs_xatlas, "fit length"),
#: while the fit's own time grows with its steps (the `fast` preset's 3,000 take minutes here).
UNWRAP_FIT_STEPS = 500

#: with --run, a fallback share of the area above this is reported as a likely mismatch of the
#: run and the mesh (a fit of the mesh itself leaves only components it never sampled)
REUSED_FALLBACK_WARNING = 0.5


def register(subparsers) -> None:
    """Add ``unwrap`` to the `mna` parser."""
    p = subparsers.add_parser(
        "unwrap", help="UV-map your own mesh with a fitted neural atlas (same faces, same order)",
        description="Fit a neural atlas to MESH into the run folder OUT (or reuse --run RUN), then UV-map MESH itself: "
                    "its faces in their order, vertices duplicated only along seams. Writes OUT/mesh.obj, mesh.mtl, "
                    "mesh_texture.png, mesh.glb and OUT/unwrap.json (input coordinate frame). "
                    "`mna compare OUT` then compares with xatlas on the same mesh.")
    p.add_argument("mesh", metavar="MESH", help="triangle mesh (.obj .ply .off .stl .glb)")
    p.add_argument("-o", "--out", required=True, metavar="OUT", help="output (and run) folder")
    p.add_argument("--charts", default=None, metavar="K|auto",
                   help="K charts throughout, or auto: start with 3 and add charts (up to 6) where the coverage "
                        "stalls")
    p.add_argument("--preset", default="fast", choices=["fast", "detail", "paper", "tiny"],
                   help="fit preset (default fast)")
    budget = p.add_mutually_exclusive_group()
    budget.add_argument("--steps", type=int, default=None,
                        help=f"optimisation steps of the fit (default {UNWRAP_FIT_STEPS}, or the preset's own where fewer: "
                             "the unwrap needs far less fit than a reconstruction)")
    budget.add_argument("--time-budget", type=float, default=None, metavar="SECONDS", help="fit for this many seconds")
    p.add_argument("--seed", type=int, default=None)
    p.add_argument("--device", default=None, choices=["auto", "cpu", "cuda"])
    p.add_argument("--threads", type=int, default=None, help="torch CPU threads")
    p.add_argument("--run", default=None, metavar="RUN", help="reuse this run's charts (RUN/charts.npz) instead of fitting")
    p.add_argument("--overwrite", action="store_true",
                   help="write OUT even if it holds an earlier run or unwrap: what mna wrote there is removed first "
                        "(same rule as `mna fit`; with --run RUN -o RUN the fit's own files stay)")
    p.add_argument("--texture", default="checker", choices=["checker", "uvgrid", "bake"],
                   help="checker (default), uvgrid, or bake the input mesh's colours/texture")
    p.add_argument("--size", default="2048", help="texture size in texels (default 2048)")
    p.add_argument("--padding", default="8", help="gutter around each island in texels (default 8)")
    p.add_argument("--square-size", type=float, default=None, help="checker square size, unit-ball frame (default 0.1)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run_unwrap)


def _fit_args(args: argparse.Namespace) -> argparse.Namespace:
    """The ``mna fit`` arguments this unwrap implies (same config rules as ``mna fit``; without
    a budget, :data:`UNWRAP_FIT_STEPS` or the preset's own steps where fewer)."""
    from mna.config import preset

    steps = args.steps
    if steps is None and args.time_budget is None:
        steps = min(UNWRAP_FIT_STEPS, preset(args.preset).steps)
    return argparse.Namespace(
        resume=False, config=None, preset=args.preset, charts=args.charts, seed=args.seed, device=args.device,
        steps=steps, time_budget=args.time_budget, threads=args.threads, grid=None, out=args.out,
        overwrite=args.overwrite,
        no_reformulation=False, naive_classifier=False, no_pe=False, no_distortion=False, atlasnet=False)


def for_unwrap(cfg):
    """``cfg`` as the unwrap fits it: without L_surf and with the charts' plain (u, v) input.
    The unwrap's segmentation is the charts' domains, and L_surf (which lays each chart's
    whole square on the surface) makes them overlap more, and they cut the mesh more: five
    1,000-step refits with it gave seams of 21.33 -> 23.24 in sum (genus2 5.38 -> 6.80 and
    4 -> 7 islands; the bunny alone shorter, 4.46 -> 3.82; benchmarks/RESULTS.md,
    fit_quality_hard). The input encoding (``model.chart_octaves``) buys the reconstruction
    detail; the unwrap needs regions, not detail, and its benchmark was measured without it
    (nor with the late distortion weight that relaxes what the encoding bends)."""
    cfg.loss.w_surface = 0.0
    cfg.model.chart_octaves = 0
    cfg.late_w_dist = 0.0
    # the face labels settle where two charts reach a face (texture.assign: depth within
    # NEAR_TOL), so the fit need not; and its short run is mostly the phase that places the
    # charts, where exclusive labels starve a chart that loses its contested regions early
    # (measured from the first step: seams longer on 2 of 5 inputs, benchmarks/RESULTS.md,
    # fit_quality_hard, thirty-fifth session)
    cfg.exclusive_labels = False
    return cfg


def fit_config(args: argparse.Namespace):
    """The config of the fit this unwrap runs: ``mna fit``'s for :func:`_fit_args`, :func:`for_unwrap`."""
    from mna.commands.fit import build_config

    return for_unwrap(build_config(_fit_args(args)))


def run_unwrap(args: argparse.Namespace) -> int:
    from mnacore.charts import load_charts
    from texture.unwrap_run import check_options, load_unwrap_input, unwrap_to_folder

    # everything is validated before anything is written
    inp = load_unwrap_input(args.mesh)
    check_options(args.texture, args.size, args.padding)
    if args.run is not None:
        if any(v is not None for v in (args.charts, args.steps, args.time_budget, args.seed)):
            raise MnaError("--run reuses a fit: --charts, --steps, --time-budget and --seed do not apply")
        if not Path(args.run).is_dir():
            raise MnaError(f"--run: run folder not found: {args.run}")
        load_charts(Path(args.run) / "charts.npz")
        # the run-folder rule of every command: an earlier unwrap's compare.md or renders/ must
        # not sit beside the new mesh; the input mesh, and the fit when unwrapping into its own
        # folder, are kept
        from mna.runfolder import FIT_FILES, prepare_run_folder

        own = Path(args.out).resolve() == Path(args.run).resolve()
        prepare_run_folder(args.out, overwrite=args.overwrite,
                           keep=[args.mesh, *([Path(args.out) / n for n in FIT_FILES] if own else [])])
        run = args.run
        fit_info = {"fit": "reused", "fit_run": str(Path(args.run).resolve())}
    else:
        from mna.run import fit_run

        cfg = fit_config(args)
        result = fit_run(args.mesh, args.out, cfg, progress_bar=not args.no_progress, overwrite=args.overwrite)
        if result.interrupted:
            return 130
        run = args.out
        fit_info = {"fit": "fitted", "fit_steps": result.steps, "fit_seconds": result.seconds,
                    "fit_fscore_mesh": result.metrics["fscore_mesh"]}
    doc = unwrap_to_folder(inp, run, args.out, texture=args.texture, size=args.size, padding=args.padding,
                           square_size=args.square_size, extra=fit_info, progress=not args.no_progress)
    m = doc["uv_metrics"]
    print(f"unwrap: {doc['islands']} islands, seam length {m['seam_length']:.2f}, distortion_metric "
          f"{m['distortion_metric']:.3f}, flipped {m['flipped_faces']}, overlap {m['uv_overlap_percent']:.2f} %, "
          f"utilization {m['utilization']:.2f}, fallback area {doc['assignment']['fallback_area_fraction']:.3f}, "
          f"{doc['timings']['unwrap_total']:.1f} s -> {Path(args.out) / 'mesh.obj'}, mesh.glb")
    if inp.had_uv:
        print(f"the texture coordinates {Path(args.mesh).name} carried were replaced (mesh.obj and mesh.glb hold the new "
              "ones; the input file is unchanged)")
    turned = doc["prepare"].get("turned_faces", 0)
    if turned:
        print(f"{turned} of {Path(args.mesh).name}'s faces were wound against their neighbours: mesh.obj and mesh.glb "
              "hold them wound like their neighbours (the same triangles, corners 2 and 3 swapped)")
    copied = doc["prepare"].get("copied_faces", 0)
    if copied:
        print(f"{copied} of {Path(args.mesh).name}'s faces repeat an earlier face (the same corners, wound the same "
              "way): each has its original's texture coordinates")
    fallback = doc["assignment"]["fallback_area_fraction"]
    if fit_info["fit"] == "reused" and fallback > REUSED_FALLBACK_WARNING:
        # a fit of this mesh reaches every part it sampled: most of the area out of reach means
        # charts of another surface, or of this one in other units or at another place
        print(f"mna unwrap: warning: the charts of {args.run} reach only {100 * (1 - fallback):.0f} % of the mesh's "
              "area (the rest took the classical fallback): was that run fitted to this mesh, in these units and "
              "at this place?", file=sys.stderr)
    if fit_info["fit"] == "fitted":  # a short fit by default: say what the run folder's fit is
        print(f"fit: {fit_info['fit_steps']} steps, {fit_info['fit_seconds']:.1f} s, F-score "
              f"{fit_info['fit_fscore_mesh']:.1f} (the charts serve the unwrap; for a reconstruction fit longer: "
              "mna fit, or --steps)")
    return 0
