"""Training config: the paper's numbers in the preset, strict YAML, round trips, one-line CLI errors."""
from __future__ import annotations

import pytest
import yaml

from mna import train_config
from mna.cli import main
from mnacore.errors import MnaError


def test_paper_preset_matches_the_paper():
    cfg = train_config.paper()
    assert (cfg.lr, cfg.epochs, cfg.lr_milestones, cfg.lr_gamma) == (1e-3, 150, [120, 140, 145], 0.1)
    assert (cfg.batch_size, cfg.data.input_points, cfg.uv_samples, cfg.model.latent) == (32, 2500, 5000, 1024)
    assert (cfg.model.chart_width, cfg.model.chart_depth) == (512, 4)
    assert cfg.encoder.kind == "pointnet" and cfg.encoder.pointnet_widths[-1] == 1024
    # 5,000 UV samples per item are split over the charts; the loss weights are the fit stage's
    fit = cfg.fit_config()
    assert fit.uv_samples * cfg.model.charts == 4998 and fit.model.latent == 1024
    assert (fit.loss.w_rec, fit.loss.w_occ, fit.loss.w_dist) == (1.0, 1.0, 1e-5)
    assert cfg.fit_config(latent=0).model.latent == 0 and cfg.model.latent == 1024  # no aliasing


def test_round_trip_and_preset_fill():
    cfg = train_config.tiny()
    cfg.data.root, cfg.data.classes = "/data", ["tshirt", "dress"]
    again = train_config.from_dict(yaml.safe_load(yaml.safe_dump(train_config.to_dict(cfg))))
    assert train_config.to_dict(again) == train_config.to_dict(cfg)
    partial = train_config.from_dict({"preset": "tiny", "epochs": 7, "data": {"root": "/x", "classes": "a, b"}})
    assert partial.epochs == 7 and partial.model.latent == train_config.tiny().model.latent
    assert partial.data.classes == ["a", "b"] and partial.lr_milestones == [24, 28]


@pytest.mark.parametrize("data, message", [
    ({"epochs": 3, "epoch": 2}, "unknown key(s) in config: epoch"),
    ({"model": {"chart_widht": 8}}, "unknown key(s) in config.model: chart_widht"),
    ({"epochs": "ten"}, "config.epochs must be int"),
    ({"amp": 1}, "config.amp must be true or false"),
    ({"lr_milestones": [1, "2"]}, "config.lr_milestones must be a list of int"),
    ({"data": {"classes": 5}}, "config.data.classes must be a list of str"),
    ({"data": 3}, "config.data must be a mapping"),
])
def test_strict_loading(data, message):
    with pytest.raises(MnaError) as info:
        train_config.from_dict(data)
    assert message in str(info.value)


def test_validate_rejects_inconsistent_values():
    cfg = train_config.tiny()
    cfg.data.root = "/x"
    cfg.data.input = "image"
    with pytest.raises(MnaError, match="needs encoder.kind resnet18"):
        cfg.validate()
    cfg = train_config.tiny()
    with pytest.raises(MnaError, match="data.root is empty"):
        cfg.validate()


@pytest.mark.parametrize("text, message", [
    ("preset: tiny\nepochs: 2\nfoo: 1\n", "unknown key(s) in config: foo"),
    ("preset: tiny\nbatch_size: 2.5\n", "config.batch_size must be int"),
    ("preset: tiny\nepochs: [\n", "is not valid YAML"),
])
def test_cli_bad_config_is_one_line_exit_2(tmp_path, capsys, text, message):
    path = tmp_path / "c.yaml"
    path.write_text(text)
    assert main(["train", str(path), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err and err.startswith("mna train: error:")
