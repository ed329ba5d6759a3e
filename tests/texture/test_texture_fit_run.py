"""Against a real (tiny) ``mna fit`` run: the harness reproduces the fit's analytic distortions,
and ``mna export`` works on the fit stage's own charts.npz."""
from __future__ import annotations

import json

import numpy as np
import pytest

from mna import shapes
from mna.cli import main
from mnacore.frame import Normalization
from mnacore.uvmesh import make_uv_mesh
from texture.harness import measure

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    work = tmp_path_factory.mktemp("fit")
    src = work / "sphere.ply"
    shapes.sphere(subdivisions=3).export(src)
    run = work / "run"
    code = main(["fit", str(src), "-o", str(run), "--preset", "tiny", "--charts", "2", "--steps", "60",
                 "--no-progress", "--seed", "0"])
    assert code == 0
    return run


def test_harness_matches_fit_distortions_within_5_percent(tiny_run):
    # the fit reports E[.] over in-domain UV samples (UV-area weighted); the harness, per face of
    # the extracted grid mesh with chart-local UVs: the same quantity, discretised
    with np.load(tiny_run / "charts.npz") as z:
        mesh = make_uv_mesh(z["vertices"], z["faces"], z["vertex_uv"])
        norm = Normalization(z["center"], float(z["scale"]))
    fit = json.loads((tiny_run / "metrics.json").read_text())
    s = measure(mesh, normalization=norm, resolution=64).summary
    assert s["distortion_metric"] == pytest.approx(fit["distortion_metric"], rel=0.05)
    assert s["distortion_conformal"] == pytest.approx(fit["distortion_conformal"], rel=0.05, abs=2e-3)
    assert s["distortion_area"] == pytest.approx(fit["distortion_area"], rel=0.05, abs=2e-3)


def test_export_on_fit_run(tiny_run):
    assert main(["export", str(tiny_run), "--size", "128", "--padding", "2"]) == 0
    info = json.loads((tiny_run / "atlas.json").read_text())
    assert info["uv_metrics"]["uv_overlap_percent"] == 0.0
    assert info["uv_metrics"]["uv_inside_unit_square"]
    assert info["atlas"]["islands"] >= 1 and (tiny_run / "mesh.glb").stat().st_size > 0


def test_export_on_folded_single_chart_torus_fit(tmp_path):
    # one chart cannot cover a torus: a short fit folds and its one island fills the whole
    # atlas; export used to fail with "packed island 0 is not a rigid copy of its input"
    from texture.export import read_back
    from texture.islands import uv_islands
    from texture.verify import verify_packing

    src = tmp_path / "torus.ply"
    shapes.torus().export(src)
    run = tmp_path / "run"
    assert main(["fit", str(src), "-o", str(run), "--preset", "tiny", "--charts", "1", "--steps", "60",
                 "--no-progress", "--seed", "0", "--threads", "1"]) == 0
    assert main(["export", str(run), "--size", "256"]) == 0
    info = json.loads((run / "atlas.json").read_text())
    assert info["uv_metrics"]["uv_overlap_percent"] == 0.0 and info["uv_metrics"]["uv_inside_unit_square"]
    assert info["atlas"]["utilization"] > 0.5
    back = read_back(run / "mesh.obj")
    assert back.uv.min() >= 0 and back.uv.max() <= 1
    assert verify_packing(back.uv, back.faces, uv_islands(back.faces, back.uv), 256)[0] == 0
