"""Encoders and the conditional atlas: shapes, invariances, and baking z into a per-shape atlas exactly."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from mna import train_config
from mna.conditional import ConditionalAtlas, bake
from mna.encoders import PointNet, ResNet18
from mna.inference import uniform_uv
from mnacore.errors import MnaError


def test_pointnet_shape_and_permutation_invariance():
    torch.manual_seed(0)
    enc = PointNet(16, [8, 12, 24])
    pts = torch.randn(3, 50, 3)
    z = enc(pts)
    assert z.shape == (3, 16) and (z >= 0).all()
    perm = torch.randperm(50)
    torch.testing.assert_close(enc(pts[:, perm]), z)
    # no batch statistics: an item's code does not depend on the rest of the batch
    torch.testing.assert_close(enc(pts[1:2]), z[1:2])
    assert not any(isinstance(m, torch.nn.modules.batchnorm._BatchNorm) for m in enc.modules())


@pytest.mark.parametrize("atlasnet,octaves", [(False, 0), (True, 0), (False, 2)])
def test_bake_equals_the_conditional_atlas(atlasnet, octaves):
    """z enters as a bias: the baked latent-free atlas gives the same points, occupancy, Jacobians
    (also with the charts' input encoded, its window half open)."""
    cfg = train_config.tiny()
    cfg.model.charts, cfg.model.latent, cfg.model.chart_octaves = 2, 8, octaves
    cfg.ablation.atlasnet = atlasnet
    torch.manual_seed(1)
    model = ConditionalAtlas.from_config(cfg)
    if octaves:
        model.atlas.chart.window.fill_(1.5)
    z = torch.randn(1, 8)
    model.atlas.c.fill_(0.7)
    baked = bake(model.atlas, z)
    assert baked.latent == 0 and baked.chart.hidden[0].v.shape[1] == 2 * (1 + 2 * octaves)
    uv = uniform_uv(2, 300, torch.Generator().manual_seed(0))
    ref = model.atlas.chart(uv, z, jacobian=True)
    out = baked.chart(uv, None, jacobian=True)
    torch.testing.assert_close(out.x, ref.x, atol=2e-6, rtol=1e-5)
    torch.testing.assert_close(out.jac, ref.jac, atol=2e-6, rtol=1e-5)
    torch.testing.assert_close(baked.occupancy_value(uv, out.x), model.atlas.occupancy_value(uv, ref.x, z),
                               atol=2e-6, rtol=1e-5)
    assert float(baked.c) == pytest.approx(0.7)
    with pytest.raises(ValueError, match=r"\(1, 8\)"):
        bake(model.atlas, torch.randn(2, 8))


def test_batched_codes_condition_each_shape_separately():
    """Item b of a batch equals a batch of one with z_b (the model's (K, B, N) layout)."""
    cfg = train_config.tiny()
    cfg.model.charts = 2
    torch.manual_seed(2)
    model = ConditionalAtlas.from_config(cfg)
    z = model.encode(torch.randn(3, 40, 3))
    uv = uniform_uv(2, 64, torch.Generator().manual_seed(1), batch=3)
    x = model.atlas.chart(uv, z).x
    for b in range(3):
        torch.testing.assert_close(x[:, b:b + 1], model.atlas.chart(uv[:, b:b + 1], z[b:b + 1]).x)


def test_resnet18_encoder_or_clear_error():
    try:
        enc = ResNet18(16, pretrained=True)
    except MnaError as exc:
        assert "torchvision" in str(exc) and "pip install" in str(exc)
        pytest.skip(f"torchvision unusable here: {str(exc)[:200]}")
    z = enc(torch.rand(2, 3, 64, 64))
    assert z.shape == (2, 16)
    assert enc.weights.startswith("imagenet") or enc.weights.startswith("random")


class _TinyImageEncoder(torch.nn.Module):
    """Stands in for ResNet-18 where torchvision is unusable: same contract, (B, 3, H, W) -> (B, D)."""

    def __init__(self, latent: int):
        super().__init__()
        self.conv = torch.nn.Conv2d(3, 8, 5, stride=4)
        self.head = torch.nn.Linear(8, latent)
        self.weights = "stub"

    def forward(self, image):
        return torch.relu(self.head(torch.relu(self.conv(image)).mean((2, 3))))


def test_image_pipeline_trains_and_reconstructs(shapenet_root, tmp_path, monkeypatch, capsys):
    """ShapeNet views -> image encoder -> atlas, then `mna reconstruct IMAGE --reference CLOUD` (encoder stubbed)."""
    import json

    from mna import conditional, encoders
    from mna.cli import main
    from mna.train import train

    real = encoders.build_encoder
    monkeypatch.setattr(conditional, "build_encoder",
                        lambda kind, latent, *a: _TinyImageEncoder(latent) if kind == "resnet18" else real(kind, latent, *a))
    cfg = train_config.tiny()
    cfg.data.root, cfg.data.layout, cfg.data.input, cfg.encoder.kind = str(shapenet_root), "shapenet", "image", "resnet18"
    cfg.out, cfg.device, cfg.epochs, cfg.batch_size, cfg.data.views = str(tmp_path / "t"), "cpu", 1, 8, 4
    result = train(cfg.validate(), progress=False, log=lambda s: None)
    assert result.step == 2 and result.metrics["encoder_weights"] == "stub"  # 4 objects x 4 views / 8
    obj = next(p for p in (shapenet_root / "02691156").iterdir() if p.is_dir())
    run = tmp_path / "rec"
    argv = ["reconstruct", str(tmp_path / "t"), str(obj / "img_choy2016" / "003.jpg"), "-o", str(run)]
    assert main(argv) == 2 and "--reference" in capsys.readouterr().err
    assert main(argv + ["--reference", str(obj / "pointcloud.npz")]) == 0
    m = json.loads((run / "metrics.json").read_text())
    assert m["reconstruct"]["encoder"] == "resnet18" and np.isfinite(m["chamfer_pcl"])
