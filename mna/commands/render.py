"""``mna render``, ``mna render-mesh`` and ``mna figure`` (Mitsuba 3 renders, heat maps, figure grids)."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from mnacore.errors import MnaError


def _positive_int(name: str):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name}: expected an integer, got {text!r}") from None
        if value < 1:
            raise argparse.ArgumentTypeError(f"{name}: expected a positive integer, got {value}")
        return value
    return parse


def _render_options(p: argparse.ArgumentParser) -> None:
    views = p.add_mutually_exclusive_group()
    views.add_argument("--views", default=None, metavar="V,V",
                       help="comma-separated preset views (default front,side,top,three_quarter)")
    views.add_argument("--turntable", type=_positive_int("--turntable"), default=None, metavar="N",
                       help="N views around the up axis instead")
    p.add_argument("--spp", type=_positive_int("--spp"), default=128, help="samples per pixel (default 128)")
    p.add_argument("--res", type=_positive_int("--res"), default=1024, help="image side in pixels (default 1024)")
    p.add_argument("--texture", default="checker", choices=["checker", "uvgrid", "bake", "procedural", "none"],
                   help="checker (default), uvgrid, bake (the mesh's own texture), procedural "
                        "(Mitsuba's checkerboard at the same 3D square size) or none")
    p.add_argument("--heatmap", default=None, metavar="K,K",
                   help="also render heat maps: metric, conformal, area, charts (comma-separated)")
    p.add_argument("--heat-max", type=float, default=None, metavar="X",
                   help="top of the distortion colour scale (default: shared 95th percentile)")
    p.add_argument("--preview", action="store_true", help="also write pyrender previews (EGL)")
    p.add_argument("--variant", default=None, help="Mitsuba variant (default: cuda_ad_rgb, llvm_ad_rgb, scalar_rgb)")
    p.add_argument("--preset", default=None, metavar="NAME|FILE",
                   help="scene preset: studio (default), plain, or a YAML/JSON file")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def register(subparsers) -> None:
    """Add ``render``, ``render-mesh`` and ``figure`` to the ``mna`` parser."""
    r = subparsers.add_parser("render", help="render a run's atlas and xatlas meshes with Mitsuba 3",
                              description="Render RUN/mesh.obj and RUN/xatlas/mesh.obj with identical cameras, "
                                          "lights and 3D checker size into RUN/renders/.")
    r.add_argument("run", metavar="RUN")
    _render_options(r)
    r.add_argument("--no-figure", action="store_true", help="do not compose RUN/renders/figure.png")
    r.set_defaults(func=run_render)

    m = subparsers.add_parser("render-mesh", help="render any UV-mapped mesh with Mitsuba 3",
                              description="Render MESH (OBJ/PLY/GLB with UVs) into the folder OUT.")
    m.add_argument("mesh", metavar="MESH")
    m.add_argument("-o", "--out", required=True, metavar="OUT", help="output folder")
    _render_options(m)
    m.set_defaults(func=run_render_mesh)

    f = subparsers.add_parser("figure", help="compose renders of runs into a labelled figure grid",
                              description="Rows: methods; columns: views (one RUN) or shapes (several RUNs).")
    f.add_argument("runs", metavar="RUN", nargs="+")
    f.add_argument("-o", "--out", required=True, metavar="PNG", help="figure file (.png)")
    f.add_argument("--rows", default="mna,xatlas", help="methods as rows (default mna,xatlas)")
    f.add_argument("--image", default="texture",
                   help="texture (default), heat_metric, heat_conformal, heat_area, heat_charts or preview")
    f.add_argument("--view", default=None, help="one view for every column")
    f.add_argument("--pdf", action="store_true", help="also write a vector PDF beside the PNG")
    f.set_defaults(func=run_figure)


def _split(text: str | None) -> tuple[str, ...]:
    return tuple(s.strip() for s in text.split(",") if s.strip()) if text else ()


def options_from_args(args: argparse.Namespace):
    from render.pipeline import RenderOptions

    opts = RenderOptions(views=_split(args.views) or None, turntable=args.turntable, spp=args.spp, res=args.res,
                         texture=args.texture, heatmaps=_split(args.heatmap), preview=args.preview,
                         variant=args.variant, preset=args.preset, seed=args.seed, heat_max=args.heat_max,
                         progress=not args.no_progress)
    opts.validate()
    return opts


def _say_variant(variant: str, warnings: list[str]) -> None:
    for w in warnings:
        print(f"mna render: warning: {w}", file=sys.stderr)
    print(f"mna render: Mitsuba variant {variant}", file=sys.stderr)


def run_render(args: argparse.Namespace) -> int:
    from render.figure import make_figure
    from render.pipeline import render_run

    opts = options_from_args(args)
    result = render_run(args.run, opts)
    first = next(iter(result.meshes.values()))
    _say_variant(result.variant, first.warnings)
    out = Path(args.run) / "renders"
    if not args.no_figure:
        make_figure([args.run], out / "figure.png", rows=tuple(result.meshes))
        for k in opts.heatmaps:
            make_figure([args.run], out / f"figure_heat_{k}.png", rows=tuple(result.meshes), image=f"heat_{k}")
    n = sum(len(r.images) for r in result.meshes.values())
    secs = sum(sum(r.seconds.values()) for r in result.meshes.values())
    print(f"wrote {n} images for {', '.join(result.meshes)} to {out} ({secs:.1f} s rendering)")
    return 0


def run_render_mesh(args: argparse.Namespace) -> int:
    from render.pipeline import render_mesh

    opts = options_from_args(args)
    if not Path(args.mesh).is_file():
        raise MnaError(f"mesh not found: {args.mesh}")
    result = render_mesh(args.mesh, args.out, opts)
    _say_variant(result.variant, result.warnings)
    print(f"wrote {len(result.images)} images to {args.out} ({sum(result.seconds.values()):.1f} s rendering)")
    return 0


def run_figure(args: argparse.Namespace) -> int:
    from render.figure import make_figure

    rows = _split(args.rows)
    if not rows:
        raise MnaError("--rows: give at least one method, e.g. mna,xatlas")
    res = make_figure(args.runs, args.out, rows=rows, image=args.image, view=args.view, pdf=args.pdf)
    print(f"wrote {res.png}" + (f" and {res.pdf}" if res.pdf else "")
          + f" ({len(res.rows)} x {len(res.columns)} cells)")
    return 0
