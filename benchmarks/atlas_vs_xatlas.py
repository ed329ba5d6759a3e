"""Our packed atlas vs xatlas on the same reconstructed mesh; writes the ``## atlas_vs_xatlas`` section.

    .venv/bin/python benchmarks/atlas_vs_xatlas.py                         # all meshes, 300 s fit each
    .venv/bin/python benchmarks/atlas_vs_xatlas.py --only bunny --time-budget 120 --no-write

Per mesh in ../shared/data/meshes: ``mna fit`` (``--preset``, default ``mna fit``'s; 3 charts;
``--steps`` or ``--time-budget``),
``mna extract --grid G`` (default 128: xatlas's time grows quickly with the face count,
about a minute at G = 128 and five at G = 256 on 2 cores), then ``mna export`` and
``mna compare`` (texture.pipeline.export_run / texture.compare.compare_run), and the
harness numbers of our atlas, of xatlas on the same reconstruction and of xatlas on the
input mesh, with the time of every stage. Issue 3's targets are checked per mesh:
seam length <= 1/4 of xatlas's (same mesh), <= 6 islands on single-part meshes,
distortion_metric <= 0.5, flipped + folded < 0.1 % of the area, utilisation >= 0.6, and
export + packing + texturing faster than xatlas's unwrap of the same mesh.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mna.config import DEFAULT_PRESET  # noqa: E402
from mnacore.atomic import write_text  # noqa: E402
from mnacore.machine import cpu_summary  # noqa: E402

MESHES = Path(__file__).resolve().parents[2] / "shared" / "data" / "meshes"
RESULTS = ROOT / "benchmarks" / "RESULTS.md"
SECTION = "atlas_vs_xatlas"
SINGLE_PART = {"bunny", "spot", "bob_tri", "eight", "face", "inspired_mesh", "tshirt"}


def _mna(*args: str) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "mna.cli", *args], check=True, cwd=ROOT)
    return time.perf_counter() - t0


def run_one(mesh: Path, work: Path, budget: list[str], grid: int, sweep: bool, size: int, reuse: bool,
            preset: str) -> dict:
    """``budget``: the fit's ``--steps N`` or ``--time-budget S`` arguments."""
    from texture.compare import compare_run
    from texture.pipeline import export_run

    run = work / mesh.stem
    timing_file = run / "benchmark_fit_seconds.json"
    if reuse and timing_file.is_file() and (run / "charts.npz").is_file():
        t_fit, t_extract = json.loads(timing_file.read_text())
    else:
        t_fit = _mna("fit", str(mesh), "-o", str(run), "--preset", preset, "--charts", "3", *budget, "--no-progress")
        t_extract = _mna("extract", str(run), "--grid", str(grid))
        timing_file.write_text(json.dumps([t_fit, t_extract]))
    export = export_run(run, size=size, padding=8).to_json()
    cmp = compare_run(run, sweep=sweep, size=size, padding=8)
    fit_metrics = json.loads((run / "metrics.json").read_text())
    ft = fit_metrics.get("timings", {})
    return {"mesh": mesh.stem, "run": str(run), "fit_seconds": t_fit, "extract_seconds": t_extract,
            "fscore_mesh": fit_metrics.get("fscore_mesh"), "fit_steps": round(ft.get("fit", 0) * ft.get("steps_per_second", 0)),
            "fit_distortion_metric": fit_metrics.get("distortion_metric"),
            "harness_on_charts": harness_on_charts(run), "export": export, "compare": cmp}


def harness_on_charts(run: Path) -> float:
    """The harness's distortion_metric on the run's own chart grid mesh (to set beside the fit's)."""
    import numpy as np

    from mnacore.frame import Normalization
    from mnacore.uvmesh import make_uv_mesh
    from texture.harness import measure

    with np.load(run / "charts.npz") as z:
        mesh = make_uv_mesh(z["vertices"], z["faces"], z["vertex_uv"])
        norm = Normalization(z["center"], float(z["scale"]))
    return measure(mesh, normalization=norm, resolution=64).summary["distortion_metric"]


def _row(mesh, r, t_uv, t_total, extra=""):
    bad = r["flipped_area_percent"] + r["folded_area_percent"]
    return (f"| {mesh} | {r['method']} | {r['faces']} | {r['charts']} | {r['seam_length']:.2f} | "
            f"{r['distortion_metric']:.3f} | {r['distortion_conformal']:.3f} | {r['distortion_area']:.3f} | "
            f"{bad:.2f} | {r['orientation_undecided_area_percent']:.2f} | {r['uv_overlap_percent']:.2f} | "
            f"{r['utilization']:.2f} | {t_uv:.1f} | {t_total} | {extra} |")


def targets(mesh: str, ours: dict, xa: dict, export_seconds: float) -> str:
    checks = [("seam<=xatlas/4", ours["seam_length"] <= xa["seam_length"] / 4),
              ("distortion<=0.5", ours["distortion_metric"] <= 0.5),
              ("flip+fold<0.1%", ours["flipped_area_percent"] + ours["folded_area_percent"] < 0.1),
              ("util>=0.6", ours["utilization"] >= 0.6),
              ("faster", export_seconds < xa["seconds"])]
    if mesh in SINGLE_PART:
        checks.insert(1, ("islands<=6", ours["charts"] <= 6))
    return ", ".join(f"{name} {'yes' if ok else 'NO'}" for name, ok in checks)


def _relax_cell(a: dict) -> str:
    if "relax_energy_before" not in a:
        return "not relaxed; "
    text = (f"relaxed: energy excess {a['relax_energy_before']:.3f} -> {a['relax_energy_after']:.3f} "
            f"({a['relax_iterations_max']} iterations at most, {a['relax_stopped_by_crossing']} stopped by a crossing)")
    return text + "; "


def _halvings_cell(a: dict) -> str:
    cells = [f"{h['cut_length']:.2f} -> {h['utilization']:.2f}" for h in a.get("halvings", [])]
    return ", ".join(cells) or "none"


def section(results: list[dict], args) -> str:
    head = ("| mesh | method | faces | charts | seam length | distortion metric | conformal | area | "
            "flipped+folded % | undecided % | overlap % | utilization | UV time s | total s | targets |")
    lines = [f"## {SECTION}", "",
             f"`benchmarks/atlas_vs_xatlas.py` ({time.strftime('%Y-%m-%d')}): `mna fit` {args.preset} preset, 3 charts, "
             f"{_budget_text(args)}; `mna extract --grid {args.grid}`; texture {args.size}², padding 8. "
             "One harness (`texture.harness.measure`, unit-ball frame, input mesh as reference) for every row. "
             "`mna` = our packed atlas; `xatlas` = xatlas (defaults, unit-ball frame) on the *same* reconstructed "
             "mesh; `xatlas_input` = xatlas on the input mesh. UV time: ours = trim + orient + relax + pack, xatlas = its "
             "`generate`; total: ours = export (atlas + texture + write), plus fit and extract for the run.", "",
             f"Machine: {cpu_summary()}, "
             f"load average {os.getloadavg()[0]:.1f} at the end.", "", head, "|" + "---|" * 15]
    for res in results:
        cmp, exp = res["compare"], res["export"]
        ours, xa = cmp["methods"][0], cmp["methods"][1]
        total = exp["timings"]["export_total"]
        lines.append(_row(res["mesh"], ours, ours["seconds"], f"{total:.1f} (fit {res['fit_seconds']:.0f}, "
                          f"extract {res['extract_seconds']:.0f})", targets(res["mesh"], ours, xa, total)))
        for r in cmp["methods"][1:]:
            lines.append(_row(res["mesh"], r, r["seconds"], "", ""))
        a = exp["atlas"]
        lines.append(f"| {res['mesh']} | (atlas) | | {a['islands']} islands / {a['charts_used']} charts "
                     "| | | | | | | | | | "
                     f"| doubly covered {a['doubly_covered_percent']:.2f} % (before {a['doubly_covered_percent_before']:.1f} %),"
                     f" F-score drop {a.get('fscore_drop', float('nan')):.2f}; inside-out before orient "
                     f"{a.get('folded_percent_before_orient', float('nan')):.2f} %, reoriented "
                     f"{a.get('reoriented_percent', float('nan')):.2f} %, dropped {a.get('orient_dropped_percent', float('nan')):.3f} %; "
                     f"{_relax_cell(a)}"
                     f"packing: {a.get('islands_before_layout', '?')} islands packed "
                     f"{a.get('utilization_uncut', float('nan')):.2f} as they came, halvings (3D cut length -> "
                     f"utilisation) {_halvings_cell(a)}; "
                     f"fit: {res['fit_steps']} steps, fscore_mesh "
                     f"{res['fscore_mesh'] if res['fscore_mesh'] is not None else float('nan'):.1f}, distortion_metric "
                     f"{res['fit_distortion_metric']:.3f} (harness on charts.npz: {res['harness_on_charts']:.3f}) |")
    lines += ["", "Per-run details (sweep, per-file timings): RUN/compare.md and RUN/atlas.json of each run.", ""]
    return "\n".join(lines)


def _budget(args) -> list[str]:
    return ["--steps", str(args.steps)] if args.steps else ["--time-budget", str(args.time_budget)]


def _budget_text(args) -> str:
    return f"{args.steps} steps" if args.steps else f"{args.time_budget:g} s budget"


def write_section(text: str) -> None:
    """Replace (or append) our section of RESULTS.md, re-read just before writing."""
    current = RESULTS.read_text() if RESULTS.is_file() else "# Benchmark results\n"
    pattern = re.compile(rf"^## {SECTION}\n.*?(?=^## |\Z)", re.S | re.M)
    body = text.rstrip() + "\n\n"
    new = pattern.sub(lambda _: body, current) if pattern.search(current) else current.rstrip() + "\n\n" + body
    write_text(RESULTS, new.rstrip() + "\n")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", type=Path, default=MESHES, help=f"mesh folder (default {MESHES})")
    ap.add_argument("--only", default="", help="comma-separated mesh stems (default: all)")
    ap.add_argument("--preset", default=DEFAULT_PRESET, help=f"mna fit --preset (default {DEFAULT_PRESET}, mna fit's)")
    budget = ap.add_mutually_exclusive_group()
    budget.add_argument("--time-budget", type=float, default=300.0, help="fit seconds per mesh (default 300)")
    budget.add_argument("--steps", type=int, default=None,
                        help="fit steps per mesh instead (the same fit on any machine; `detail` opens its encoding "
                        "from 2,400)")
    ap.add_argument("--grid", type=int, default=128, help="mna extract --grid (default 128)")
    ap.add_argument("--size", type=int, default=2048, help="texture size (default 2048)")
    ap.add_argument("--sweep", action="store_true", help="also run compare's xatlas sweep")
    ap.add_argument("--work", type=Path, default=ROOT / "benchmarks" / "runs", help="run folders (git-ignored)")
    ap.add_argument("--reuse", action="store_true", help="reuse fitted runs in --work (skip fit and extract)")
    ap.add_argument("--no-write", action="store_true", help="print the section instead of writing RESULTS.md")
    args = ap.parse_args(argv)
    if not args.meshes.is_dir():
        print(f"mesh folder not found: {args.meshes}", file=sys.stderr)
        return 2
    only = {s for s in args.only.split(",") if s}
    meshes = sorted(p for p in args.meshes.iterdir() if p.suffix in (".obj", ".off", ".ply") and
                    (not only or p.stem in only))
    results = []
    for mesh in meshes:
        print(f"== {mesh.name}", flush=True)
        results.append(run_one(mesh, args.work, _budget(args), args.grid, args.sweep, args.size, args.reuse,
                               args.preset))
        text = section(results, args)
        if not args.no_write:
            write_section(text)  # after every mesh, so a long run leaves partial results
    print(section(results, args))
    return 0


if __name__ == "__main__":
    sys.exit(main())
