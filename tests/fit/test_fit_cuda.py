"""The fit stage on CUDA gives the CPU's numbers: nearest neighbours, one optimiser step, a whole run.

These tests need a CUDA GPU and skip without one (CI has none); run them where one is present.
"""
from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from mna import config as C
from mna.data import load_surface
from mna.fit import Fitter
from mna.neighbors import nearest
from mna.run import extract_run, fit_run, load_model

pytestmark = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA GPU")
CUDA = torch.device("cuda")


def _tiny(steps: int, device: str) -> C.FitConfig:
    cfg = C.tiny()
    cfg.steps, cfg.device = steps, device
    return cfg


def test_nearest_on_cuda_matches_ckdtree():
    g = torch.Generator().manual_seed(0)
    query, reference = torch.rand(9000, 3, generator=g), torch.rand(5000, 3, generator=g)
    cpu = nearest(query, reference)
    gpu = nearest(query.to(CUDA), reference.to(CUDA))
    # the CUDA path uses cdist's matrix-product form: ties apart, the same neighbour
    same = (gpu.index.cpu() == cpu.index).float().mean().item()
    assert same > 0.999, same
    # exact distance to the chosen neighbour is the nearest distance, to float32 accuracy
    d2 = ((query - reference[gpu.index.cpu()]) ** 2).sum(1)
    np.testing.assert_allclose(d2.numpy(), cpu.dist2.numpy(), rtol=0, atol=1e-6)
    np.testing.assert_allclose(gpu.dist2.cpu().numpy(), cpu.dist2.numpy(), rtol=0, atol=1e-5)


def test_optimiser_steps_on_cuda_match_cpu(torus_file):
    surface = load_surface(torus_file)
    runs = {}
    for dev in ("cpu", "cuda"):
        fitter = Fitter(_tiny(5, dev), surface, torch.device(dev))
        losses = [fitter.train_step() for _ in range(5)]
        runs[dev] = (losses, [p.detach().cpu() for p in fitter.model.parameters()])
    (loss_c, par_c), (loss_g, par_g) = runs["cpu"], runs["cuda"]
    # same seeds, same samples (drawn on the CPU): the losses agree to float32 round-off
    for a, b in zip(loss_c, loss_g):
        assert b.positives == a.positives
        assert b.total == pytest.approx(a.total, rel=2e-3)
        assert b.rec == pytest.approx(a.rec, rel=2e-3)
    assert loss_g[-1].total != loss_g[0].total  # the steps did move the model
    for a, b in zip(par_c, par_g):
        np.testing.assert_allclose(b.numpy(), a.numpy(), rtol=0, atol=2e-4)


def test_fit_run_on_cuda_loads_and_extracts_on_cpu(torus_file, tmp_path):
    run = tmp_path / "run"
    res = fit_run(torus_file, run, _tiny(60, "cuda"), progress_bar=False, log=lambda s: None)
    assert not res.interrupted and res.steps == 60
    m = json.loads((run / "metrics.json").read_text())
    assert m["device"].startswith("cuda")
    # the checkpoint written on the GPU opens on the CPU and gives the same surface
    model, cfg, _, _ = load_model(run, "cpu")
    assert next(model.parameters()).device.type == "cpu"
    again = extract_run(run, model=model, cfg=cfg)
    assert again["fscore_mesh"] == pytest.approx(m["fscore_mesh"], abs=0.5)
    assert again["chamfer_mesh"] == pytest.approx(m["chamfer_mesh"], rel=0.05)
