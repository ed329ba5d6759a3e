"""Feed-forward reconstruction writes `mna fit`'s run folder; export/extract/fit --resume take it; evaluate; bad input."""
from __future__ import annotations

import json

import numpy as np
import pytest
import torch
import trimesh

from mna import train_config
from mna.cli import main
from mna.run import load_model, load_run_config
from mna.train import train

RUN_FILES = ("config.yaml", "checkpoint.pt", "metrics.json", "points.ply", "charts.npz", "charts.ply")


@pytest.fixture(scope="session")
def trained(tmp_path_factory):
    """A tiny 3-chart model trained on one sphere (radius 2.5, off the unit ball) until its atlas is usable."""
    from train_helpers import write_meshes_layout

    base = tmp_path_factory.mktemp("trained")
    root = write_meshes_layout(base / "data", splits={"train": ["sphere"], "val": ["sphere"]})
    cfg = train_config.tiny()
    cfg.data.root, cfg.out, cfg.device = str(root), str(base / "train"), "cpu"
    cfg.model.charts, cfg.uv_samples, cfg.batch_size = 3, 1200, 1
    cfg.epochs, cfg.lr_milestones = 200, [200]
    train(cfg.validate(), progress=False, log=lambda s: None)
    return base / "train" / "checkpoint.pt", root / "sphere.ply"


def test_reconstruct_writes_the_fit_run_folder(trained, tmp_path, capsys):
    ckpt, mesh = trained
    run = tmp_path / "rec"
    assert main(["reconstruct", str(ckpt), str(mesh), "-o", str(run)]) == 0
    assert "reconstructed in" in capsys.readouterr().out
    assert all((run / f).is_file() for f in RUN_FILES)
    cfg, input_path = load_run_config(run)
    assert input_path == str(mesh) and cfg.model.latent == 0 and cfg.preset == "reconstruct"
    model, _, norm, state = load_model(run)
    assert 0 < float(model.c) <= 1 and state["reconstructed_from"]["latent"].shape == (32,)
    assert norm.scale == pytest.approx(2.5, rel=1e-3)
    m = json.loads((run / "metrics.json").read_text())
    assert m["fscore_mesh"] > 3 and m["chamfer_mesh"] < 0.05 and len(m["occupancy_rate"]) == 3
    assert m["reconstruct"]["encoder"] == "pointnet" and m["reconstruct"]["encoder_weights"] == "random"
    # outputs are in the input's frame: the sphere has radius 2.5 there
    pts = np.asarray(trimesh.load(run / "points.ply").vertices)
    assert np.median(np.linalg.norm(pts, axis=1)) == pytest.approx(2.5, rel=0.1)
    with np.load(run / "charts.npz") as z:
        assert z["xyz"].shape == (3, 32, 32, 3) and z["faces"].shape[1] == 3 and float(z["scale"]) == norm.scale


def test_reconstruction_flows_into_export_extract_and_fit_resume(trained, tmp_path):
    ckpt, mesh = trained
    run = tmp_path / "rec"
    assert main(["reconstruct", str(ckpt), str(mesh), "-o", str(run), "--grid", "48"]) == 0
    assert main(["export", str(run), "--size", "256"]) == 0
    assert (run / "mesh.obj").is_file() and (run / "mesh.glb").is_file()
    assert main(["compare", str(run), "--no-sweep", "--size", "256"]) == 0
    assert json.loads((run / "compare.json").read_text())
    assert main(["extract", str(run), "--points", "2000", "--grid", "32"]) == 0
    # the checkpoint is a fit checkpoint at step 0: `mna fit --resume` refines the shape per-shape
    assert main(["fit", str(mesh), "-o", str(run), "--resume", "--steps", "5", "--no-progress"]) == 0


def test_evaluate_split(trained, tmp_path, capsys):
    ckpt, _ = trained
    out = tmp_path / "eval.json"
    assert main(["evaluate", str(ckpt.parent), "--split", "val", "--no-progress", "-o", str(out)]) == 0
    printed = json.loads(capsys.readouterr().out)
    saved = json.loads(out.read_text())
    assert printed["items"] == 1 and saved["chamfer_pcl"] == pytest.approx(printed["chamfer_pcl"])
    assert 0 < saved["chamfer_pcl"] < 0.05 and saved["fscore_mesh"] > 3 and len(saved["per_item"]) == 1
    assert np.isfinite(saved["distortion_metric"])


def _one_line_exit_2(argv, capsys, message):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err, err


def test_bad_checkpoints_and_inputs(trained, tmp_path, capsys):
    ckpt, mesh = trained
    # a per-shape fit's checkpoint is not a training checkpoint
    fit_run = tmp_path / "fit"
    assert main(["fit", str(mesh), "-o", str(fit_run), "--preset", "tiny", "--steps", "2", "--no-progress"]) == 0
    capsys.readouterr()
    _one_line_exit_2(["reconstruct", str(fit_run / "checkpoint.pt"), str(mesh), "-o", str(tmp_path / "r1")],
                     capsys, "is not a training checkpoint")
    # weights from a different architecture than the checkpoint's config says
    state = torch.load(ckpt, weights_only=False)
    state["config"]["model"]["chart_width"] = 48
    torch.save(state, tmp_path / "other.pt")
    _one_line_exit_2(["reconstruct", str(tmp_path / "other.pt"), str(mesh), "-o", str(tmp_path / "r2")],
                     capsys, "different architecture")
    _one_line_exit_2(["evaluate", str(tmp_path / "other.pt")], capsys, "different architecture")
    img = tmp_path / "view.png"
    img.write_bytes(b"\x89PNG not really")
    _one_line_exit_2(["reconstruct", str(ckpt), str(img), "-o", str(tmp_path / "r3")], capsys, "encodes point clouds")
    _one_line_exit_2(["reconstruct", str(tmp_path / "none.pt"), str(mesh), "-o", str(tmp_path / "r4")],
                     capsys, "checkpoint not found")
    _one_line_exit_2(["evaluate", str(ckpt), "--split", "nosuch"], capsys, "no split file")


def test_resume_with_a_different_architecture(trained, tmp_path, capsys):
    ckpt, _ = trained
    saved = train_config.fit_config_mod.load_yaml(ckpt.parent / "config.yaml")
    saved["model"]["chart_width"] = 64
    path = tmp_path / "c.yaml"
    train_config.fit_config_mod.save_yaml(path, saved)
    _one_line_exit_2(["train", str(path), "--resume", "--no-progress"], capsys, "in model.chart_width")
    # the same through the state itself (config.yaml removed): load_state_dict refuses the weights
    out = tmp_path / "copy"
    out.mkdir()
    (out / "checkpoint.pt").write_bytes(ckpt.read_bytes())
    saved["out"] = str(out)
    train_config.fit_config_mod.save_yaml(path, saved)
    _one_line_exit_2(["train", str(path), "--resume", "--no-progress"], capsys, "different architecture")
