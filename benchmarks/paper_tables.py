"""The paper's claims at our scale: ablations, charts vs squares, feed-forward topology.

    make bench-paper                                         # default sizes (see SIZES)
    .venv/bin/python benchmarks/paper_tables.py --size full --device cuda --jobs 1  # GPU sizes

Two settings, as issue 19 asks:
- ``conditional``: ``mna train`` over a procedural family (:mod:`mna.family`: spheres, tori,
  genus-2 surfaces, two and three parts, open tubes, random proportions), scored with
  ``mna evaluate`` on held-out members; the paper's own setting for its ablations.
- ``per-shape``: ``mna fit`` per shape (procedural shapes, and shared meshes when present).
Each run's metrics are kept as JSON under ``--work`` (a rerun skips finished runs), then the
tables, the verdict per claim (:mod:`mna.paper`) and a figure (PNG + PDF) are written:
section ``## paper`` of benchmarks/RESULTS.md and benchmarks/paper_figure.{png,pdf}.
Budgets are in epochs and steps, never seconds, so a busy machine gets the same numbers.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from mna import paper  # noqa: E402
from mnacore.machine import cpu_summary  # noqa: E402

MESHES = ROOT.parent / "shared" / "data" / "meshes"


@dataclass(frozen=True)
class Sizes:
    per_topology: int          # family members per topology (train + held out)
    held_out: int              # of which held out (test split)
    epochs: int                # conditional training epochs
    batch: int
    width: int                 # chart / label MLP width (conditional)
    latent: int
    points: int                # encoder input = target points per item
    uv: int                    # UV samples per item (split over the charts)
    seeds: tuple[int, ...]     # conditional ablation seeds
    fit_steps: int             # per-shape fit steps
    fit_shapes: tuple[str, ...]
    square_shapes: tuple[str, ...]   # per-shape charts-vs-squares shapes (K = 10 is the cost)
    ks: tuple[int, ...]
    eval_points: int
    grid: int


SIZES = {
    # the tests' smoke size: every code path, numbers meaningless
    "tiny": Sizes(2, 1, 2, 4, 16, 16, 128, 120, (0,), 3, ("torus",), ("torus",), (1, 3), 500, 8),
    # this 2-core CPU: 36 training members, 1,500 steps a network; 300-step fits
    "default": Sizes(8, 2, 300, 8, 64, 64, 512, 900, (0, 1, 2), 300, ("torus", "two_spheres", "bunny"),
                     ("torus",), (1, 2, 3, 10), 5000, 64),
    # a GPU: the paper's widths and point counts, more members and steps
    "full": Sizes(40, 8, 400, 32, 512, 1024, 2500, 5000, (0, 1, 2), 4000,
                  ("torus", "genus2", "two_spheres", "bunny", "spot", "bob_tri", "eight"),
                  ("torus", "two_spheres", "bunny", "spot"), (1, 2, 3, 10, 25), 25000, 256),
}
#: topologies that are not one closed genus-0 surface: where squares should fail
HARD = ("torus", "genus2", "pair", "triple", "tube")


def run_specs(s: Sizes) -> list[dict]:
    """Every run of the benchmark, once: the charts-vs-squares grid reuses the ablation rows
    it shares (3 charts, MNA, with and without L_dist)."""
    specs = []
    for v in paper.VARIANTS:
        specs += [dict(setting="conditional", variant=v, method="mna", charts=3, ldist=v != "no_ldist",
                       seed=seed, shape="family") for seed in s.seeds]
        specs += [dict(setting="per-shape", variant=v, method="mna", charts=3, ldist=v != "no_ldist",
                       seed=0, shape=shape) for shape in s.fit_shapes]
    squares = []
    for setting, shapes in (("conditional", ("family",)), ("per-shape", s.square_shapes)):
        for k in s.ks:
            for method in ("mna", "atlasnet"):
                for ldist in (True, False):
                    if method == "mna" and k == 3:
                        continue  # the ablation rows "full" and "no_ldist"
                    squares += [dict(setting=setting, variant="full", method=method, charts=k, ldist=ldist,
                                     seed=0, shape=shape) for shape in shapes]
    # the comparisons the claims read first (3 squares, then the most squares), so a run cut
    # short by --report-only still decides them; the other K fill in the curves
    order = {3: 0, max(s.ks): 1}
    specs += sorted(squares, key=lambda x: (order.get(x["charts"], 2), x["charts"]))
    return specs


def key(spec: dict) -> str:
    return (f"{spec['setting']}-{spec['shape']}-{spec['variant']}-{spec['method']}-k{spec['charts']}-"
            f"{'ld' if spec['ldist'] else 'nold'}-s{spec['seed']}")


def shape_path(name: str, work: Path) -> Path:
    """A per-shape input: a procedural shape (written once) or a shared mesh by stem."""
    from mna import shapes

    if name in shapes.SHAPES:
        return shapes.shape_file(name, work / "shapes")
    found = sorted(MESHES.glob(f"{name}.*"))
    if not found:
        raise SystemExit(f"paper_tables: mesh {name!r} not found in {MESHES}")
    return found[0]


def conditional_run(spec: dict, s: Sizes, family_root: Path, out: Path, device: str) -> dict:
    from mna import family, train_config
    from mna.reconstruct import evaluate_split
    from mna.train import train

    cfg = train_config.tiny()
    cfg.preset = "paper-tables"
    m = cfg.model
    m.chart_width = m.label_width = s.width
    m.label_depth, m.octaves, m.latent = 3, 6, s.latent
    cfg.encoder.pointnet_widths = [s.width, 2 * s.width, 4 * s.width]
    d = cfg.data
    d.layout, d.root, d.input_points, d.target_points = "meshes", str(family_root), s.points, s.points
    d.mesh_cache_points = 16 * s.points
    cfg.uv_samples, cfg.batch_size, cfg.epochs, cfg.lr = s.uv, s.batch, s.epochs, 3e-3
    cfg.lr_milestones = [int(s.epochs * 0.8), int(s.epochs * 0.9)]
    cfg.eval_points = cfg.val_points = s.eval_points
    cfg.eval_uv_samples = cfg.c_samples = s.eval_points
    cfg.grid, cfg.device, cfg.seed, cfg.val_every, cfg.threads = s.grid, device, spec["seed"], 0, 0
    cfg = paper.configure(cfg, spec["variant"], spec["method"], spec["charts"], spec["ldist"])
    cfg.out = str(out)
    t0 = time.perf_counter()
    result = train(cfg, resume=(out / "checkpoint.pt").is_file(), progress=False, log=lambda _: None)
    train_s = time.perf_counter() - t0
    if result.interrupted:  # a stopped training is not a row; a rerun resumes it
        raise SystemExit(f"paper_tables: {out.name} interrupted at step {result.step}")
    ev = evaluate_split(out / "checkpoint.pt", "test", device=device, progress=False)
    per_topology: dict[str, list[dict]] = {}
    for item in ev["per_item"]:
        per_topology.setdefault(family.topology_of(item["name"]), []).append(item)
    degenerate = [i["degenerate_charts"] for i in ev["per_item"]]
    return {**{k: ev[k] for k in paper.METRICS if k in ev}, "degenerate_charts": sum(degenerate) / len(degenerate),
            "per_topology": {t: {k: sum(i[k] for i in v) / len(v) for k in ("chamfer_mesh", "fscore_mesh")}
                             for t, v in per_topology.items()}, "steps": result.step,
            "seconds": train_s, "items": ev["items"]}


def per_shape_run(spec: dict, s: Sizes, work: Path, out: Path, device: str) -> dict:
    from mna import config as C
    from mna.run import fit_run

    cfg = C.fast()
    cfg.steps, cfg.seed, cfg.device = s.fit_steps, spec["seed"], device
    # mna extensions, not the paper's method: off for every variant
    cfg.loss.w_orient = cfg.loss.w_surface = 0.0
    cfg.model.chart_octaves = 0
    cfg = paper.configure(cfg, spec["variant"], spec["method"], spec["charts"], spec["ldist"])
    t0 = time.perf_counter()
    res = fit_run(str(shape_path(spec["shape"], work)), out, cfg, progress_bar=False, log=lambda _: None,
                  overwrite=True)
    if res.interrupted:
        raise SystemExit(f"paper_tables: {out.name} interrupted at step {res.steps}")
    m = res.metrics
    occ = m["occupancy_rate"]
    return {**{k: m[k] for k in paper.METRICS if k in m}, "occupancy_mean": sum(occ) / len(occ),
            "steps": res.steps, "seconds": time.perf_counter() - t0}


def run_one(args: tuple) -> dict:
    spec, s, work, device, threads = args
    import torch

    if threads:
        torch.set_num_threads(threads)
    path = work / "rows" / f"{key(spec)}.json"
    if path.is_file():
        return json.loads(path.read_text())
    out = work / "runs" / key(spec)
    if spec["setting"] == "conditional":
        metrics = conditional_run(spec, s, work / "family", out, device)
    else:
        metrics = per_shape_run(spec, s, work, out, device)
    row = {**spec, **metrics}
    from mnacore.atomic import write_json

    write_json(path, row)
    return row


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", choices=list(SIZES), default="default")
    ap.add_argument("--work", type=Path, default=ROOT / "benchmarks" / "runs" / "paper")
    ap.add_argument("--jobs", type=int, default=2, help="runs in parallel (default 2: one per core)")
    ap.add_argument("--threads", type=int, default=1, help="torch threads per run (default 1)")
    ap.add_argument("--device", default="cpu", choices=["cpu", "cuda"])
    ap.add_argument("--no-write", action="store_true", help="print the section, leave RESULTS.md alone")
    ap.add_argument("--figure", type=Path, default=ROOT / "benchmarks" / "paper_figure")
    ap.add_argument("--report-only", action="store_true",
                    help="run nothing: tables from the runs already finished under --work")
    args = ap.parse_args(argv)
    s = SIZES[args.size]
    from mna import family

    work = args.work / args.size
    family.write_family(work / "family", s.per_topology, s.held_out)
    specs = run_specs(s)
    load = os.getloadavg()[0]
    jobs = [(spec, s, work, args.device, args.threads) for spec in specs]
    rows = []
    from tqdm.auto import tqdm

    if args.report_only:
        done = [work / "rows" / f"{key(spec)}.json" for spec in specs]
        rows = [json.loads(p.read_text()) for p in done if p.is_file()]
        print(f"{len(rows)} of {len(specs)} runs finished", file=sys.stderr)
    else:
        with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
            for row in tqdm(pool.map(run_one, jobs), total=len(jobs), desc="paper runs", dynamic_ncols=True):
                rows.append(row)
    text = section(rows, s, args, load)
    print(text)
    write_figure(rows, args.figure, s)
    if not args.no_write:
        from fit_quality import write_section

        write_section("paper", text)
    return 0


def section(rows: list[dict], s: Sizes, args, load: float) -> str:
    from paper_report import render_section

    return render_section(rows, asdict(s) | {"size": args.size, "jobs": args.jobs, "threads": args.threads,
                                            "device": args.device, "machine": cpu_summary(), "load": load}, HARD)


def write_figure(rows: list[dict], stem: Path, s: Sizes) -> None:
    from paper_report import figure

    figure(rows, stem, s.ks)


if __name__ == "__main__":
    sys.exit(main())
