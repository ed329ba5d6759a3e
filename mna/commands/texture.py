"""``mna export``, ``mna uv`` and ``mna compare``: the texture stage (package ``texture``)."""
from __future__ import annotations

import argparse
from pathlib import Path

from mnacore.errors import MnaError


def register(subparsers) -> None:
    """Add this group's subcommands to the `mna` parser."""
    e = subparsers.add_parser("export", help="pack the run's charts into one UV atlas and write a textured OBJ/GLB",
                              description="Trim overlapping charts, cut clean borders, pack all islands at one texel "
                                          "density and write RUN/mesh.obj, mesh.mtl, mesh_texture.png, mesh.glb and "
                                          "RUN/atlas.json (input coordinate frame).")
    e.add_argument("run", metavar="RUN", help="run folder with charts.npz (from mna fit / mna extract)")
    e.add_argument("--texture", default="checker", choices=["checker", "uvgrid", "bake"],
                   help="checker (default), uvgrid, or bake the input mesh's colours/texture")
    e.add_argument("--size", default="2048", help="texture size in texels (default 2048)")
    e.add_argument("--padding", default="8", help="gutter around each island in texels (default 8)")
    e.add_argument("--square-size", type=float, default=None,
                   help="checker square size in the unit-ball frame (default 0.1)")
    e.add_argument("--max-islands", type=int, default=6,
                   help="halve islands along short cuts while that packs tighter, within this many islands "
                        "(one more only for a large gain; default 6; 0 = never cut)")
    e.add_argument("--relax", default="8", metavar="N",
                   help="re-flatten every island toward an isometry with at most N SLIM iterations before packing "
                        "(default 8; 0 = keep the charts' own UVs)")
    e.add_argument("--config", default=None, metavar="FILE",
                   help="repeat an export: every option from an atlas.json (its 'config') or a JSON/YAML file "
                        "of the same keys; the options above are then not allowed")
    e.set_defaults(func=run_export)

    u = subparsers.add_parser("uv", help="UV-map any mesh with xatlas and write a textured OBJ/GLB + metrics",
                              description="UV-map MESH with xatlas; writes OUT/mesh.obj, mesh.mtl, mesh_texture.png, "
                                          "mesh.glb and OUT/metrics.json (the texture harness).")
    u.add_argument("mesh", metavar="MESH", help="triangle mesh (.obj .ply .off .stl .glb)")
    u.add_argument("-o", "--out", required=True, metavar="OUT", help="output folder")
    u.add_argument("--method", default="xatlas", choices=["xatlas"], help="UV method (only xatlas)")
    u.add_argument("--max-cost", type=float, default=2.0, help="xatlas chart growth cost limit (default 2)")
    u.add_argument("--max-iterations", type=int, default=1, help="xatlas segmentation iterations (default 1)")
    u.add_argument("--max-chart-area", type=float, default=0.0, help="largest chart area, unit-ball frame (0: none)")
    u.add_argument("--max-boundary-length", type=float, default=0.0,
                   help="largest chart boundary, unit-ball frame (0: none)")
    u.add_argument("--resolution", type=int, default=2048, help="atlas resolution in texels (default 2048)")
    u.add_argument("--padding", type=int, default=8, help="gutter in texels (default 8)")
    u.add_argument("--brute-force", action="store_true", help="slower, tighter packing")
    u.add_argument("--input-units", action="store_true",
                   help="give xatlas the mesh in its own units instead of the unit-ball frame")
    u.add_argument("--texture", default="checker", choices=["checker", "uvgrid", "bake"])
    u.add_argument("--size", default=None, help="texture size (default: --resolution)")
    u.add_argument("--overwrite", action="store_true",
                   help="write OUT even if it holds earlier output: what mna wrote there is removed first")
    u.set_defaults(func=run_uv)

    m = subparsers.add_parser("uv-metrics", help="measure any UV-mapped mesh with the texture harness",
                              description="Distortions, charts, seam length, flips, folds, overlap, utilisation and "
                                          "texel-density spread of MESH's UVs (the harness used by mna compare).")
    m.add_argument("mesh", metavar="MESH", help="mesh with UVs (.obj .glb .ply)")
    m.add_argument("--reference", default=None, metavar="REF", help="true surface (normals for folds, boundary for seams)")
    m.add_argument("-o", "--out", default=None, metavar="JSON", help="write the summary here (default: print it)")
    m.set_defaults(func=run_uv_metrics)

    c = subparsers.add_parser("compare", help="our atlas vs xatlas on the same mesh, one harness: compare.json/.md",
                              description="Run xatlas on the run's reconstructed mesh (RUN/xatlas/) and on the input "
                                          "mesh, sweep xatlas's max_cost/max_iterations, and tabulate every method "
                                          "with one harness into RUN/compare.json and RUN/compare.md.")
    c.add_argument("run", metavar="RUN")
    c.add_argument("--no-sweep", action="store_true", help="skip the xatlas max_cost/max_iterations sweep")
    c.add_argument("--size", default="2048", help="texture size for exports (default 2048)")
    c.add_argument("--padding", default="8", help="gutter in texels (default 8)")
    c.set_defaults(func=run_compare)


def _int_arg(value: str, name: str, minimum: int) -> int:
    try:
        v = int(str(value).strip())
    except ValueError:
        raise MnaError(f"{name} must be an integer >= {minimum}, got {value!r}") from None
    if v < minimum:
        raise MnaError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return v


#: `mna export` options that --config replaces (name, default)
_EXPORT_OPTIONS = (("texture", "checker"), ("size", "2048"), ("padding", "8"), ("square_size", None),
                   ("max_islands", 6), ("relax", "8"))


def run_export(args: argparse.Namespace) -> int:
    from texture.pipeline import export_run
    from texture.textures import check_size

    if args.config is not None:
        from texture.export_config import load_export_config

        given = [f"--{n.replace('_', '-')}" for n, d in _EXPORT_OPTIONS if getattr(args, n) != d]
        if given:
            raise MnaError(f"--config holds every export option; drop {', '.join(given)}")
        return _report_export(args.run, export_run(args.run, config=load_export_config(args.config)))
    # strings parsed here; every range is checked once, by ExportConfig inside export_run
    size = check_size(args.size)
    padding = _int_arg(args.padding, "--padding", 0)
    relax = _int_arg(args.relax, "--relax", 0)
    r = export_run(args.run, texture=args.texture, size=size, padding=padding, square_size=args.square_size,
                   max_islands=args.max_islands, relax=relax)
    return _report_export(args.run, r)


def _report_export(run: str, r) -> int:
    a, m = r.atlas, r.uv_metrics
    print(f"atlas: {a.islands} islands from {a.charts_used} charts, seam length {m['seam_length']:.2f}, "
          f"distortion_metric {m['distortion_metric']:.3f}, utilization {a.utilization:.2f}, "
          f"doubly covered {a.doubly_covered_percent:.2f} %, fscore drop {a.fscore_drop:.2f}"
          f" -> {Path(run) / 'mesh.obj'}, mesh.glb")
    return 0


def run_uv(args: argparse.Namespace) -> int:
    from texture.pipeline import uv_mesh_file
    from texture.xatlas_uv import XatlasOptions

    opts = XatlasOptions(max_cost=args.max_cost, max_iterations=args.max_iterations,
                         max_chart_area=args.max_chart_area, max_boundary_length=args.max_boundary_length,
                         resolution=args.resolution, padding=args.padding, brute_force=args.brute_force,
                         normalize=not args.input_units)
    from mna.runfolder import prepare_run_folder

    # the run-folder rule: an earlier output (and its compare.md, renders/) is not left beside
    # the new one; the input mesh inside OUT is kept
    r = uv_mesh_file(args.mesh, args.out, opts, texture=args.texture, size=args.size,
                     prepare_out=lambda: prepare_run_folder(args.out, overwrite=args.overwrite, keep=[args.mesh]))
    m = r["uv_metrics"]
    print(f"xatlas: {m['charts']} charts, seam length {m['seam_length']:.2f}, distortion_metric "
          f"{m['distortion_metric']:.3f}, utilization {m['utilization']:.2f} in {r['timings']['xatlas']:.2f} s "
          f"-> {Path(args.out) / 'mesh.obj'}")
    return 0


def run_compare(args: argparse.Namespace) -> int:
    from texture.textures import check_size

    size = check_size(args.size)
    padding = _int_arg(args.padding, "--padding", 0)
    if (Path(args.run) / "unwrap.json").is_file():  # an `mna unwrap` folder: ours vs xatlas on the input mesh
        from texture.unwrap_compare import compare_unwrap as compare
    else:  # a fit's folder: our atlas of the reconstruction vs xatlas
        from texture.compare import compare_run as compare
    r = compare(args.run, sweep=not args.no_sweep, size=size, padding=padding)
    print(f"compared {len(r['methods'])} methods -> {Path(args.run) / 'compare.md'}")
    return 0


def run_uv_metrics(args: argparse.Namespace) -> int:
    """The harness on one file, with the same reference and frame as ``mna compare`` when the
    file belongs to a run (``RUN/mesh.obj``, ``RUN/xatlas/mesh.obj``), so the numbers agree."""
    import json

    import trimesh

    from mnacore.atomic import strict_json, write_json
    from mnacore.frame import unit_ball_normalization
    from mnacore.uvmesh import load_uv_mesh
    from texture.compare import harness_context, run_folder_of
    from texture.harness import measure

    mesh, _ = load_uv_mesh(args.mesh)
    run = run_folder_of(args.mesh)
    if args.reference:
        _, ref = load_uv_mesh(args.reference, require_uv=False)
        ref = trimesh.Trimesh(ref.vertices, ref.faces, process=False)
        kw = {"reference": ref, "normalization": unit_ball_normalization(ref.vertices[ref.faces.ravel()])}
        described = f"{args.reference} (its unit ball)"
    elif run is not None:
        kw = harness_context(run)
        described = (f"the input of run {run.name} (its unit ball)" if kw["reference"] is not None
                     else f"none: run {run.name} has no input mesh, its surface is taken as closed")
    else:
        kw, described = {}, "none: the mesh's own open borders are the surface's boundary (its unit ball)"
    summary = {"mesh": str(args.mesh), "reference": described, **measure(mesh, **kw).summary}
    if args.out:
        if Path(args.out).is_dir():
            raise MnaError(f"-o {args.out} is a folder; give the JSON file to write, e.g. {Path(args.out) / 'uv_metrics.json'}")
        write_json(args.out, summary)
    else:
        print(json.dumps(strict_json(summary), indent=2, allow_nan=False))
    return 0

