"""``mna unwrap`` vs xatlas on the same input mesh; writes the ``## unwrap_vs_xatlas`` section.

    .venv/bin/python benchmarks/unwrap_vs_xatlas.py                       # shared meshes + procedural shapes
    .venv/bin/python benchmarks/unwrap_vs_xatlas.py --only bunny eight --steps 1000 --no-write
    .venv/bin/python benchmarks/unwrap_vs_xatlas.py --reuse               # keep existing fits in --work

Per mesh (``../shared/data/meshes`` when present, plus procedural shapes from
``mna.shapes``: sphere, torus (genus 1), genus-2, two spheres, a wavy open sheet): a fit
(``mna fit``, fast preset, 3 charts, ``--steps``), then the unwrap of the input mesh with
its charts (:func:`texture.unwrap_run.unwrap_to_folder`, time per stage), and xatlas on
the same mesh as ``mna unwrap`` reads it: defaults, and the sweep point
(``texture.compare.SWEEP_*``) with the fewest charts. One harness
(:func:`texture.harness.measure`, unit-ball frame of the fit, reference = the input) for
every row. Targets of issue 17 checked per mesh: islands <= 8 on a single-part mesh
(<= 1.5 per part and <= half of xatlas's on many-part meshes), seam <= 1/2 of xatlas's,
distortion_metric <= 0.15, 0 flipped faces, 0 overlap, utilisation >= 0.6.
"""
from __future__ import annotations

import argparse
import json
import platform
import re
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mnacore.atomic import write_text  # noqa: E402

MESHES = Path(__file__).resolve().parents[2] / "shared" / "data" / "meshes"
RESULTS = ROOT / "benchmarks" / "RESULTS.md"
SECTION = "unwrap_vs_xatlas"
PROCEDURAL = ("sphere", "torus", "genus2", "two_spheres", "wavy_sheet")


def _inputs(work: Path, only: list[str] | None) -> list[Path]:
    from mna import shapes

    paths = sorted(p for p in MESHES.glob("*") if p.suffix in (".obj", ".off", ".ply")) if MESHES.is_dir() else []
    work.mkdir(parents=True, exist_ok=True)
    for name in PROCEDURAL:
        path = work / f"{name}.ply"
        if not path.is_file():
            mesh = shapes.sheet(amplitude=0.3) if name == "wavy_sheet" else shapes.make(name)
            mesh.export(path)
        paths.append(path)
    return [p for p in paths if not only or p.stem in only]


def _fit(mesh: Path, run: Path, steps: int, reuse: bool) -> float:
    stamp = run / "benchmark_fit_seconds.json"
    if reuse and stamp.is_file() and (run / "charts.npz").is_file():
        return json.loads(stamp.read_text())
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "mna.cli", "fit", str(mesh), "-o", str(run), "--preset", "fast",
                    "--charts", "3", "--steps", str(steps), "--no-progress"], check=True, cwd=ROOT)
    seconds = time.perf_counter() - t0
    stamp.write_text(json.dumps(seconds))
    return seconds


def _xatlas_rows(inp, norm, size: int) -> tuple[dict, dict]:
    """(defaults row, fewest-charts sweep row), harness summaries + seconds."""
    import trimesh

    from texture.compare import SWEEP_MAX_COST, SWEEP_MAX_ITERATIONS
    from texture.harness import measure
    from texture.xatlas_uv import XatlasOptions, unwrap

    ref = trimesh.Trimesh(inp.vertices, inp.faces, process=False)

    def row(opts):
        r = unwrap(inp.vertices, inp.faces, opts, check=False)
        return {**measure(r.mesh, reference=ref, normalization=norm).summary, "seconds": r.seconds,
                "max_cost": opts.max_cost, "max_iterations": opts.max_iterations}

    default = row(XatlasOptions(resolution=size, padding=8))
    sweep = [row(XatlasOptions(max_cost=c, max_iterations=i, resolution=size, padding=8))
             for i in SWEEP_MAX_ITERATIONS for c in SWEEP_MAX_COST]
    return default, min(sweep, key=lambda r: (r["charts"], r["distortion_metric"]))


def run_one(mesh: Path, work: Path, steps: int, size: int, reuse: bool) -> dict:
    from mnacore.charts import load_charts
    from texture.meshprep import face_components
    from texture.unwrap_run import load_unwrap_input, unwrap_to_folder

    run = work / f"{mesh.stem}_run"
    fit_seconds = _fit(mesh, run, steps, reuse)
    inp = load_unwrap_input(mesh)
    doc = unwrap_to_folder(inp, run, run / "unwrap", size=size, padding=8)
    norm = load_charts(run / "charts.npz").normalization
    xa, sweep = _xatlas_rows(inp, norm, size)
    fit_metrics = json.loads((run / "metrics.json").read_text())
    return {"mesh": mesh.stem, "faces": len(inp.faces), "parts": int(face_components(inp.faces).max()) + 1,
            "fit_seconds": fit_seconds, "fit_steps": steps, "fscore_mesh": fit_metrics["fscore_mesh"],
            "ours": {**doc["uv_metrics"], "islands": doc["islands"], "timings": doc["timings"],
                     "fallback_area_fraction": doc["assignment"]["fallback_area_fraction"],
                     "far_area_fraction": doc["assignment"]["far_area_fraction"]},
            "xatlas": xa, "xatlas_fewest": sweep, "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def targets(r: dict) -> dict:
    o, x = r["ours"], r["xatlas"]
    isl = o["islands"] <= 8 if r["parts"] == 1 else (o["islands"] <= 1.5 * r["parts"] and o["islands"] <= x["charts"] / 2)
    return {"islands": isl, "seam": o["seam_length"] <= 0.5 * x["seam_length"],
            "distortion": o["distortion_metric"] <= 0.15, "flips": o["flipped_faces"] == 0,
            "overlap": o["uv_overlap_percent"] == 0.0, "utilisation": o["utilization"] >= 0.6}


def section(results: list[dict], args) -> str:
    lines = [f"## {SECTION}", "",
             f"`benchmarks/unwrap_vs_xatlas.py --steps {args.steps}` on {platform.machine()} "
             f"({platform.processor() or 'cpu'}), {time.strftime('%Y-%m-%d')}. Per mesh: fit (fast preset, 3 charts, "
             f"{args.steps} steps), `mna unwrap` of the input mesh with those charts, xatlas (defaults, and the "
             "sweep point with the fewest charts) on the same mesh; one harness (unit-ball frame of the fit, "
             f"reference = the input), texture {args.size}, padding 8. Time: the UV step only (ours: after the fit; "
             "per stage in the second table)."
             + (" Fits reused from earlier runs of the same fit command (`--reuse`; fit s = their wall time)."
                if args.reuse else "")
             + " Peak RSS is the benchmark process's so far (cumulative), not per mesh.", "",
             "| mesh | faces | parts | fit F-score | islands (ours / xatlas / xatlas fewest) | seam | distortion_metric | "
             "flipped | overlap % | utilisation | time s | fallback area | targets missed |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        o, x, s = r["ours"], r["xatlas"], r["xatlas_fewest"]
        missed = [k for k, ok in targets(r).items() if not ok]
        lines.append(
            f"| {r['mesh']} | {r['faces']} | {r['parts']} | {r['fscore_mesh']:.1f} | {o['islands']} / {x['charts']} / "
            f"{s['charts']} | {o['seam_length']:.2f} / {x['seam_length']:.2f} / {s['seam_length']:.2f} | "
            f"{o['distortion_metric']:.3f} / {x['distortion_metric']:.3f} / {s['distortion_metric']:.3f} | "
            f"{o['flipped_faces']} / {x['flipped_faces']} | {o['uv_overlap_percent']:.3f} / {x['uv_overlap_percent']:.3f} | "
            f"{o['utilization']:.2f} / {x['utilization']:.2f} | {o['timings']['unwrap_total']:.1f} / {x['seconds']:.1f} | "
            f"{o['fallback_area_fraction']:.3f} | {', '.join(missed) or 'none'} |")
    stages = ("prepare", "assign", "clean", "whole", "flatten", "relax", "slits", "split", "pack")
    lines += ["", "Ours, seconds per stage (after the fit):", "",
              "| mesh | fit s | " + " | ".join(stages) + " | texture | write | peak RSS MB |",
              "|---|---|" + "---|" * (len(stages) + 3)]
    for r in results:
        t = r["ours"]["timings"]
        lines.append(f"| {r['mesh']} | {r['fit_seconds']:.0f} | " + " | ".join(f"{t.get('unwrap_' + k, 0):.2f}" for k in stages)
                     + f" | {t['texture']:.2f} | {t['write']:.2f} | {r['peak_rss_mb']:.0f} |")
    met = {k: sum(targets(r)[k] for r in results) for k in targets(results[0])} if results else {}
    lines += ["", "Targets met (meshes out of " + str(len(results)) + "): "
              + ", ".join(f"{k} {v}" for k, v in met.items()) + ".", ""]
    return "\n".join(lines)


def write_section(text: str) -> None:
    """Replace (or append) our section of RESULTS.md, re-read just before writing."""
    current = RESULTS.read_text() if RESULTS.is_file() else "# Benchmark results\n"
    pattern = re.compile(rf"^## {SECTION}\n.*?(?=^## |\Z)", re.S | re.M)
    new = pattern.sub(lambda _: text + "\n", current) if pattern.search(current) else current.rstrip() + "\n\n" + text
    write_text(RESULTS, new.rstrip() + "\n")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", default=str(Path(__file__).resolve().parent / "runs" / "unwrap"),
                    help="fits and outputs go here (default benchmarks/runs/unwrap, git-ignored)")
    ap.add_argument("--only", nargs="*", default=None, help="mesh stems to run")
    ap.add_argument("--steps", type=int, default=1000, help="fit steps per mesh (default 1000)")
    ap.add_argument("--size", type=int, default=2048)
    ap.add_argument("--reuse", action="store_true", help="reuse fits already in --work")
    ap.add_argument("--no-write", action="store_true", help="print the section instead of writing RESULTS.md")
    args = ap.parse_args()
    work = Path(args.work)
    results = []
    for mesh in _inputs(work, args.only):
        print(f"== {mesh.stem}", flush=True)
        results.append(run_one(mesh, work, args.steps, args.size, args.reuse))
        (work / "results.json").write_text(json.dumps(results, indent=1, default=float))
    text = section(results, args)
    print(text)
    if not args.no_write:
        write_section(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
