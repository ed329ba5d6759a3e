"""Training throughput of the conditional atlas: shapes per second, paper preset, and 2 processes vs 1.

    .venv/bin/python benchmarks/train_throughput.py [--steps 3] [--batch 32] [--no-write]

Builds a synthetic dataset in the Occupancy-Networks ShapeNet layout (procedural shapes,
100,000 points per object) in a temporary folder, then trains the ``paper`` preset (charts
3 x 4 x 512, label nets 4 x 512, D = 1024, 5,000 UV samples and 2,500 points per item) for
``1 + steps`` optimiser steps of the effective batch and reports the median throughput of
the timed steps (the first is warm-up): one process with 1 and with all CPU threads, and
2 processes (gloo, 1 thread each, DistributedDataParallel) sharing the same effective batch.
Writes the section ``## train_throughput`` of benchmarks/RESULTS.md (only that section).
"""
from __future__ import annotations

import argparse
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402
import torch  # noqa: E402
import trimesh  # noqa: E402

from mna import shapes, train_config  # noqa: E402
from mnacore.atomic import write_text  # noqa: E402
from mnacore.machine import cpu_name  # noqa: E402

SECTION = "## train_throughput"


def make_dataset(root: Path, objects: int) -> Path:
    """``objects`` procedural shapes in the ShapeNet layout (pointcloud.npz only; point-cloud input)."""
    cdir = root / "02691156"
    cdir.mkdir(parents=True)
    rng = np.random.default_rng(0)
    base = [shapes.sphere(subdivisions=3), shapes.torus(sections=48, ring=24), trimesh.creation.box(extents=[1, .6, .4])]
    names = []
    for i in range(objects):
        mesh = base[i % len(base)].copy()
        mesh.apply_scale(rng.uniform(0.5, 1.5, 3))
        pts, face = trimesh.sample.sample_surface(mesh, 100_000, seed=i)
        name = f"{i:032x}"
        (cdir / name).mkdir()
        np.savez(cdir / name / "pointcloud.npz", points=pts.astype(np.float16),
                 normals=mesh.face_normals[face].astype(np.float16))
        names.append(name)
    (cdir / "train.lst").write_text("\n".join(names))
    return root


def paper_config(root: Path, out: Path, steps: int, batch: int, threads: int) -> train_config.TrainConfig:
    cfg = train_config.paper()
    cfg.data.root, cfg.data.layout, cfg.out, cfg.device = str(root), "shapenet", str(out), "cpu"
    cfg.batch_size, cfg.epochs, cfg.val_every, cfg.log_every, cfg.threads = batch, 1 + steps, 0, 1, threads
    return cfg.validate()


def throughput(out: Path) -> tuple[float, list[float]]:
    """Median shapes/s over the timed steps (log rows after the first), from the run's log.csv."""
    rows = (out / "log.csv").read_text().splitlines()
    col = rows[0].split(",").index("shapes_per_second")
    rates = [float(r.split(",")[col]) for r in rows[2:]]
    return statistics.median(rates), rates


def run_one(root: Path, out: Path, steps: int, batch: int, threads: int, world: int) -> tuple[float, list[float]]:
    cfg = paper_config(root, out, steps, batch, threads)
    path = out.parent / f"{out.name}.yaml"
    train_config.fit_config_mod.save_yaml(path, train_config.to_dict(cfg))
    env = dict(os.environ, OMP_NUM_THREADS=str(threads), PYTHONPATH=str(REPO))
    if world == 1:
        cmd = [sys.executable, "-m", "mna.train", str(path), "--no-progress"]
    else:
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        cmd = [sys.executable, "-m", "torch.distributed.run", "--nnodes=1", f"--nproc_per_node={world}",
               "--master_addr=127.0.0.1", f"--master_port={port}", "-m", "mna.train", str(path), "--no-progress"]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    if proc.returncode:
        raise SystemExit(f"training failed ({' '.join(cmd)}):\n{proc.stderr[-3000:]}")
    print(f"  {world} process(es) x {threads} thread(s): {time.perf_counter() - t0:.0f} s wall", flush=True)
    return throughput(out)


def write_section(text: str) -> None:
    path = REPO / "benchmarks" / "RESULTS.md"
    old = path.read_text() if path.is_file() else "# Benchmark results\n"
    lines = old.splitlines(keepends=True)
    start = next((i for i, line in enumerate(lines) if line.strip() == SECTION), None)
    if start is None:
        new = old.rstrip("\n") + "\n\n" + text
    else:
        end = next((i for i in range(start + 1, len(lines)) if lines[i].startswith("## ")), len(lines))
        new = "".join(lines[:start]) + text + ("\n" + "".join(lines[end:]) if end < len(lines) else "")
    write_text(path, new)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=3, help="timed optimiser steps per configuration (default 3)")
    p.add_argument("--batch", type=int, default=32, help="effective batch (paper: 32)")
    p.add_argument("--no-write", action="store_true", help="print only; leave RESULTS.md alone")
    args = p.parse_args()
    cores = os.cpu_count() or 1
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="mna-bench-") as tmp:
        tmp = Path(tmp)
        root = make_dataset(tmp / "data", args.batch)
        print(f"paper preset, batch {args.batch}, {args.steps} timed steps (+1 warm-up) per configuration", flush=True)
        results = {}
        for label, threads, world in (("1 process, 1 thread", 1, 1), (f"1 process, {cores} threads", cores, 1),
                                      ("2 processes (gloo), 1 thread each", 1, 2)):
            results[label] = run_one(root, tmp / label.replace(" ", "_").replace(",", "").replace("(", "")
                                     .replace(")", ""), args.steps, args.batch, threads, world)
            print(f"  {label}: {results[label][0]:.2f} shapes/s (steps: {', '.join(f'{r:.2f}' for r in results[label][1])})")
    load_after = os.getloadavg()[0]
    one = results["1 process, 1 thread"][0]
    best_one = max(one, results[f"1 process, {cores} threads"][0])
    two = results["2 processes (gloo), 1 thread each"][0]
    rows = "\n".join(f"| {k} | {v[0]:.2f} | {', '.join(f'{r:.2f}' for r in v[1])} |" for k, v in results.items())
    text = (
        f"{SECTION}\n\n"
        f"`benchmarks/train_throughput.py` ({time.strftime('%Y-%m-%d')}): training throughput of the conditional "
        f"atlas, `paper` preset (charts 3 x 4 x 512, label nets 4 x 512, latent 1024, PointNet encoder, 5,000 UV "
        f"samples and 2,500 input/target points per item), effective batch {args.batch}, synthetic ShapeNet-layout "
        f"data (100,000 points per object). Median over {args.steps} timed optimiser steps after 1 warm-up step, "
        f"data loading included (workers 0). Shapes/s = items of the effective batch per second.\n\n"
        f"Machine: {cpu_name()}, {cores} cores, no GPU, torch {torch.__version__}; load average "
        f"{load_before:.1f} before, {load_after:.1f} after (other processes shared the CPU"
        f"{'' if load_before > 1.5 else ': little'}).\n\n"
        f"| configuration | shapes/s | per timed step |\n|---|---|---|\n{rows}\n\n"
        f"Speed-up of 2 processes over 1: {two / one:.2f}x against 1 process with 1 thread, "
        f"{two / best_one:.2f}x against the faster single process (each rank works on half the batch, so "
        f"its activations stay smaller; with so few steps on a shared machine, expect +-30 % noise). No GPU was lent to this task, so there is no "
        f"GPU number (`mna train` uses CUDA, NCCL and mixed precision when one is present).\n"
    )
    print(text)
    if not args.no_write:
        write_section(text)


if __name__ == "__main__":
    main()
