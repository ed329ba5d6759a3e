"""Training on CUDA: mixed precision lowers the training Chamfer like the CPU run, and the
checkpoint reconstructs on the CPU. Needs a CUDA GPU; skips without one (CI has none)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch

from mna import datasets, train_config
from mna.conditional import ConditionalAtlas
from mna.reconstruct import evaluate_items, reduce_mean
from mna.train import train

pytestmark = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA GPU")


def _cfg(root, out, device, **overrides) -> train_config.TrainConfig:
    cfg = train_config.tiny()
    cfg.data.root, cfg.out, cfg.device = str(root), str(out), device
    for key, value in overrides.items():
        setattr(cfg, key, value)
    return cfg.validate()


def _chamfer(model, cfg) -> float:
    ds = datasets.build(cfg, "train")
    rows = evaluate_items(model.cpu().eval(), ds, list(range(len(ds))), cfg, points=1000, full=False)
    return reduce_mean(rows, ("chamfer_pcl",))["chamfer_pcl"]


def test_amp_training_on_cuda_fits_like_the_cpu(meshes_root, tmp_path):
    kw = dict(epochs=150, lr=3e-3, lr_milestones=[105, 135])
    gpu_cfg = _cfg(meshes_root, tmp_path / "gpu", "cuda", amp=True, **kw)  # tiny() has amp off
    torch.manual_seed(gpu_cfg.seed)
    before = _chamfer(ConditionalAtlas.from_config(gpu_cfg), gpu_cfg)
    gpu = train(gpu_cfg, progress=False, log=lambda s: None)
    metrics = json.loads((Path(gpu_cfg.out) / "metrics.json").read_text())
    assert metrics["device"].startswith("cuda") and metrics["amp"] is True
    cpu_cfg = _cfg(meshes_root, tmp_path / "cpu", "cpu", **kw)
    cpu = train(cpu_cfg, progress=False, log=lambda s: None)
    after_gpu, after_cpu = _chamfer(gpu.model, gpu_cfg), _chamfer(cpu.model, cpu_cfg)
    assert before / after_gpu >= 5.0, (before, after_gpu)
    # float16 autocast and CUDA kernels change the path, not where it ends
    assert after_gpu == pytest.approx(after_cpu, rel=0.5), (after_gpu, after_cpu)
    # the checkpoint written on the GPU reloads on the CPU with the same weights
    state = torch.load(Path(gpu_cfg.out) / "checkpoint.pt", map_location="cpu", weights_only=False)
    model = ConditionalAtlas.from_config(gpu_cfg)
    model.load_state_dict(state["model"])
    for a, b in zip(model.state_dict().values(), gpu.model.cpu().state_dict().values()):
        assert torch.equal(a, b)
