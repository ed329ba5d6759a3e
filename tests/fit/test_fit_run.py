"""End-to-end fits on a small torus: run-folder contract, determinism, resume, Ctrl-C."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh

from mna import config as C
from mna.run import fit_run, load_model
from mnacore.machine import cpu_summary


def _tiny(steps: int = 40) -> C.FitConfig:
    cfg = C.tiny()
    cfg.steps = steps
    cfg.device = "cpu"
    return cfg


def _metrics(run: Path) -> dict:
    m = json.loads((run / "metrics.json").read_text())
    m.pop("timings")
    return m


def test_run_folder_contract(torus_file, tmp_path):
    run = tmp_path / "run"
    res = fit_run(torus_file, run, _tiny(), progress_bar=False, log=lambda s: None)
    assert not res.interrupted and res.steps == 40
    names = sorted(p.name for p in run.iterdir())
    assert names == ["charts.npz", "charts.ply", "checkpoint.pt", "config.yaml", "metrics.json", "points.ply"]
    m = json.loads((run / "metrics.json").read_text())
    for key in ("chamfer_pcl", "fscore_pcl", "chamfer_mesh", "fscore_mesh", "distortion_metric",
                "distortion_conformal", "distortion_area", "occupancy_rate", "degenerate_charts", "timings"):
        assert key in m
    assert len(m["occupancy_rate"]) == 3 and all(0 <= r <= 100 for r in m["occupancy_rate"])
    assert m["input_topology"] == {"parts": 1, "genus": 1, "genus_per_part": [1], "boundaries": 0, "manifold": True}
    assert m["charts"] == 3 and m["charts_rule"] == "fixed"
    assert m["machine"] == cpu_summary()  # the CPU model: fits repeat on one CPU, not across CPUs
    # outputs are in the input's frame: the point cloud overlaps the input's bounding box
    src = trimesh.load(torus_file, process=False)
    pts = trimesh.load(run / "points.ply").vertices
    assert abs(len(pts) - 4000) <= 120
    lo, hi = src.bounds
    assert np.all(pts.min(0) > lo - 0.5 * (hi - lo)) and np.all(pts.max(0) < hi + 0.5 * (hi - lo))
    charts = np.load(run / "charts.npz")
    K, G = 3, 48
    assert charts["xyz"].shape == (K, G, G, 3) and charts["occ"].shape == (K, G, G)
    inside = charts["occ"].reshape(-1)[charts["grid_index"]] > float(charts["tau"])
    assert inside.all()
    np.testing.assert_allclose(charts["vertices"], charts["xyz"].reshape(-1, 3)[charts["grid_index"]])
    # the saved config reproduces the run
    cfg2 = C.from_dict({k: v for k, v in __import__("yaml").safe_load((run / "config.yaml").read_text()).items()
                        if k != "input"})
    assert C.to_dict(cfg2) == C.to_dict(_tiny())


def test_same_seed_gives_identical_metrics(torus_file, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    fit_run(torus_file, a, _tiny(), progress_bar=False, log=lambda s: None)
    fit_run(torus_file, b, _tiny(), progress_bar=False, log=lambda s: None)
    assert _metrics(a) == _metrics(b)
    cfg = _tiny()
    cfg.seed = 1
    fit_run(torus_file, tmp_path / "c", cfg, progress_bar=False, log=lambda s: None)
    assert _metrics(tmp_path / "c")["chamfer_mesh"] != _metrics(a)["chamfer_mesh"]


@pytest.mark.parametrize("octaves", [0, 2])
def test_resume_after_interrupt_equals_uninterrupted(torus_file, tmp_path, octaves):
    """Also with the charts' input encoded, interrupted while its octaves open (step 13 of 30,
    the window 20-80 % of the run)."""

    def cfg():
        c = _tiny(30)
        c.model.chart_octaves, c.chart_octaves_from, c.chart_octaves_until = octaves, 0.2, 0.8
        return c

    full, part = tmp_path / "full", tmp_path / "part"
    fit_run(torus_file, full, cfg(), progress_bar=False, log=lambda s: None)
    r = fit_run(torus_file, part, cfg(), callback=lambda step: step == 13, progress_bar=False, log=lambda s: None)
    assert r.interrupted and r.steps == 13 and not (part / "metrics.json").exists()
    r2 = fit_run(torus_file, part, cfg(), resume=True, progress_bar=False, log=lambda s: None)
    assert not r2.interrupted and r2.steps == 30
    ma, _, _, _ = load_model(full)
    mb, _, _, _ = load_model(part)
    for (na, pa), (nb, pb) in zip(ma.state_dict().items(), mb.state_dict().items()):
        assert na == nb and torch.equal(pa, pb), na
    assert _metrics(full) == _metrics(part)


def test_a_run_too_short_for_the_encoding_is_the_plain_fit(torus_file, tmp_path):
    """With 2 chart octaves (and a late distortion weight, exclusive labels) but ``chart_octaves_min_steps``
    above its 30 steps, a fresh fit is built and saved without either and ends exactly as the
    plain fit does. A run that opened the encoding keeps it when resumed with fewer steps
    than that minimum."""

    def cfg(octaves, min_steps, steps=30):
        c = _tiny(steps)
        c.model.chart_octaves, c.chart_octaves_from, c.chart_octaves_until = octaves, 0.2, 0.8
        c.chart_octaves_min_steps = min_steps
        c.late_w_dist = 0.5 if octaves else 0.0
        c.exclusive_labels = bool(octaves)
        return c

    fit_run(torus_file, tmp_path / "plain", cfg(0, 31), progress_bar=False, log=lambda s: None)
    fit_run(torus_file, tmp_path / "short", cfg(2, 31), progress_bar=False, log=lambda s: None)
    saved = C.load_yaml(tmp_path / "short" / "config.yaml")
    assert saved["model"]["chart_octaves"] == 0 and saved["late_w_dist"] == 0.0 and not saved["exclusive_labels"]
    assert "chart.window" not in load_model(tmp_path / "short")[0].state_dict()
    assert _metrics(tmp_path / "short") == _metrics(tmp_path / "plain")
    run = tmp_path / "opened"
    fit_run(torus_file, run, cfg(2, 30), callback=lambda step: step == 13, progress_bar=False, log=lambda s: None)
    r = fit_run(torus_file, run, cfg(2, 30, steps=20), resume=True, progress_bar=False, log=lambda s: None)
    assert r.steps == 20 and float(load_model(run)[0].chart.window) == 2.0


def test_point_cloud_input(tmp_path):
    from mna import shapes

    pts, _ = trimesh.sample.sample_surface(shapes.sphere(), 3000, seed=0)
    np.save(tmp_path / "cloud.npy", np.asarray(pts))
    res = fit_run(str(tmp_path / "cloud.npy"), tmp_path / "run", _tiny(20), progress_bar=False, log=lambda s: None)
    assert res.metrics["fscore_pcl"] >= 0 and (tmp_path / "run" / "points.ply").is_file()
    assert res.metrics["input_topology"] is None  # a cloud has no faces to count


def test_atlasnet_mode_has_full_squares(torus_file, tmp_path):
    cfg = _tiny(10)
    cfg.ablation.atlasnet = True
    res = fit_run(torus_file, tmp_path / "run", cfg, progress_bar=False, log=lambda s: None)
    assert res.metrics["occupancy_rate"] == [100.0, 100.0, 100.0]


def test_ctrl_c_saves_a_checkpoint_and_resume_continues(torus_file, tmp_path):
    run = tmp_path / "run"
    mna = [sys.executable, "-m", "mna.cli"]
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(mna + ["fit", torus_file, "-o", str(run), "--preset", "tiny", "--steps", "100000",
                                   "--no-progress", "--device", "cpu"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    deadline = time.time() + 60
    while not (run / "checkpoint.pt").exists() and time.time() < deadline:
        time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "checkpoint saved" in out
    step = torch.load(run / "checkpoint.pt", weights_only=True)["step"]
    assert step >= 50 and not (run / "metrics.json").exists()
    res = subprocess.run(mna + ["fit", torus_file, "-o", str(run), "--resume", "--steps", str(step + 20),
                                "--no-progress"], capture_output=True, text=True, env=env, timeout=120)
    assert res.returncode == 0, res.stderr
    assert f"resuming from step {step}" in res.stdout
    assert torch.load(run / "checkpoint.pt", weights_only=True)["step"] == step + 20
    assert (run / "metrics.json").is_file()


def _denormals_flushed() -> bool:
    return (torch.tensor([1e-39], dtype=torch.float32) * 1.0).item() == 0.0


def test_flush_to_zero_is_scoped(torus_file, tmp_path):
    """FTZ speeds up Softplus(100) but is a process-wide mode: it must not outlive the torch work."""
    from mna.model import flush_denormals

    assert not _denormals_flushed()
    with flush_denormals():
        assert _denormals_flushed()
        with flush_denormals(False):
            assert not _denormals_flushed()
        assert _denormals_flushed()
    assert not _denormals_flushed()
    fit_run(torus_file, tmp_path / "run", _tiny(5), progress_bar=False, log=lambda s: None)
    assert not _denormals_flushed()


def test_collapsed_fit_writes_an_empty_cloud_and_zero_scores(torus_file, tmp_path):
    """A fit whose domains hold no UV point (the naive classifier's collapse) is a result, not
    a crash: points.ply is a readable PLY of 0 points, F-score 0, Chamfer null (infinite)."""
    from mna.run import extract_run

    run = tmp_path / "run"
    fit_run(torus_file, run, _tiny(3), progress_bar=False, log=lambda s: None)
    model, cfg, _, _ = load_model(run)
    model.c.fill_(1e9)  # o_k = l_k / c < tau everywhere: empty domains
    metrics = extract_run(run, model=model, cfg=cfg)
    assert metrics["fscore_pcl"] == 0.0 and not np.isfinite(metrics["chamfer_pcl"])
    head = (run / "points.ply").read_bytes().split(b"end_header")[0].decode()
    assert "element vertex 0" in head and "property float x" in head
    saved = json.loads((run / "metrics.json").read_text())
    assert saved["fscore_pcl"] == 0.0 and saved["chamfer_pcl"] is None
