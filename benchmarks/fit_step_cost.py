"""Where a ``fast`` fit step's time goes (issue 18: "the cost per step: where does it go?").

    .venv/bin/python benchmarks/fit_step_cost.py [MESH] [--steps 60] [--threads 2]

Fits MESH (default: the shared bunny; else the built-in torus) with the ``fast`` preset and
times each phase of :meth:`mna.fit.Fitter.train_step` with wall-clock timers around the
functions it calls (``torch.set_num_threads`` as given; CPU): target sampling, the charts
without gradient at all UV samples, the nearest-sample search, the charts with gradient and
Jacobians at the positives, the label network, the losses, backward, the optimiser step.
The first 10 steps are warm-up. Prints a markdown table (ms per step, share) for RESULTS.md.
"""
from __future__ import annotations

import argparse
import sys
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import mna  # noqa: E402,F401  (sets the OpenMP wait policy before torch loads)

MESH = Path(__file__).resolve().parents[2] / "shared" / "data" / "meshes" / "bunny.off"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mesh", nargs="?", default=str(MESH) if MESH.is_file() else "torus")
    ap.add_argument("--steps", type=int, default=60)
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()

    import torch

    from mna import objective
    from mna.config import preset
    from mna.data import load_surface
    from mna.fit import Fitter
    from mna.model import ChartNet, NeuralAtlas

    torch.set_num_threads(args.threads)
    spent: dict[str, float] = defaultdict(float)

    def timed(name, fn):
        def wrapper(*a, **k):
            t0 = time.perf_counter()
            out = fn(*a, **k)
            spent[name] += time.perf_counter() - t0
            return out
        return wrapper

    # phases: wrap what train_step calls (the wrappers nest: chart calls inside the objective
    # are split into the no-grad pass over all samples and the gradient pass at the positives)
    chart = ChartNet.forward

    def chart_timed(self, *a, **k):
        name = "charts with grad (+Jacobian) at positives" if torch.is_grad_enabled() else "charts, no grad, all UV samples"
        return timed(name, chart)(self, *a, **k)

    ChartNet.forward = chart_timed
    NeuralAtlas.label_logits = timed("label network (occupancy)", NeuralAtlas.label_logits)
    objective.nearest = timed("nearest sample search", objective.nearest)
    cfg = preset("fast")
    path = Path(args.mesh)
    if not path.is_file():  # a built-in shape by name
        import tempfile

        from mna import shapes

        path = Path(tempfile.mkdtemp()) / f"{args.mesh}.ply"
        shapes.make(args.mesh).export(path)
    surface = load_surface(path)
    fitter = Fitter(cfg, surface, torch.device("cpu"))
    fitter.surface.sample_elements = timed("target sampling", fitter.surface.sample_elements)
    objective_fn = objective.atlas_losses
    import mna.fit as fit_module

    fit_module.atlas_losses = timed("objective (all of it)", objective_fn)
    backward = torch.Tensor.backward
    torch.Tensor.backward = lambda self, *a, **k: timed("backward", backward)(self, *a, **k)
    step = fitter.optimizer.step
    fitter.optimizer.step = timed("optimiser step", step)
    for _ in range(10):
        fitter.train_step()
    spent.clear()
    t0 = time.perf_counter()
    for _ in range(args.steps):
        fitter.train_step()
    total = time.perf_counter() - t0
    inner = ["charts, no grad, all UV samples", "nearest sample search", "charts with grad (+Jacobian) at positives",
             "label network (occupancy)"]
    spent["losses and bookkeeping in the objective"] = spent.pop("objective (all of it)", 0.0) - sum(spent[k] for k in inner)
    spent["rest of the step"] = total - sum(spent.values())
    print(f"fast preset, {args.steps} steps after 10 warm-up, {args.threads} threads, {Path(args.mesh).stem}: "
          f"{1000 * total / args.steps:.0f} ms per step ({args.steps / total:.1f} steps/s)\n")
    print("| phase | ms per step | share |\n|---|---|---|")
    for name, sec in sorted(spent.items(), key=lambda kv: -kv[1]):
        print(f"| {name} | {1000 * sec / args.steps:.1f} | {100 * sec / total:.0f} % |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
