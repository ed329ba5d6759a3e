"""--charts auto: the chart count from the input's topology (mna.chart_count), saved
resolved, resumable, refused where it cannot apply."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh
import yaml

from mna import config as C
from mna import shapes
from mna.chart_count import AUTO_MAX_CHARTS, BASE_CHARTS, FREE_HANDLES, charts_for, resolve_charts
from mna.cli import main
from mna.data import make_surface
from mnacore.topology import Topology


def _topo(*genus: int) -> Topology:
    return Topology(parts=len(genus), genus=genus, boundaries=(0,) * len(genus), manifold=True)


def test_rule_adds_one_chart_per_handle_beyond_the_free_ones_up_to_the_cap():
    assert [charts_for(_topo(g)) for g in range(8)] == [3, 3, 3, 4, 5, 6, 6, 6]
    assert BASE_CHARTS == 3 and FREE_HANDLES == 2 and AUTO_MAX_CHARTS == 6
    # handles add up over parts: two genus-2 parts are four handles
    assert charts_for(_topo(2, 2)) == charts_for(_topo(4)) == 5
    assert charts_for(_topo(*([0] * 13))) == 3  # many genus-0 parts: no more charts


def test_resolve_sets_the_model_and_leaves_fixed_configs_alone():
    m = shapes.pretzel(3, resolution=72)
    mesh = make_surface(m.vertices, m.faces)
    cfg = C.tiny()
    cfg.charts_rule = "topology"
    note = resolve_charts(cfg, mesh)
    assert cfg.model.charts == 4 and "genus 3" in note
    fixed = C.tiny()
    fixed.model.charts = 2
    assert resolve_charts(fixed, mesh) is None and fixed.model.charts == 2
    pts = trimesh.sample.sample_surface(m, 500, seed=0)[0]
    cloud_cfg = C.tiny()
    cloud_cfg.charts_rule, cloud_cfg.model.charts = "topology", 5
    assert "point cloud" in resolve_charts(cloud_cfg, make_surface(pts, None)) and cloud_cfg.model.charts == 3


def test_cli_auto_fits_a_genus_four_mesh_with_five_charts_and_resumes(tmp_path, capsys):
    src = tmp_path / "g4.ply"
    shapes.genus4(resolution=56).export(src)
    run = tmp_path / "run"
    argv = ["fit", str(src), "-o", str(run), "--preset", "tiny", "--charts", "auto", "--steps", "8",
            "--no-progress", "--device", "cpu", "--grid", "16"]
    assert main(argv) == 0
    saved = yaml.safe_load((run / "config.yaml").read_text())
    assert saved["model"]["charts"] == 5 and saved["charts_rule"] == "topology"
    assert np.load(run / "charts.npz")["xyz"].shape[0] == 5
    # resuming keeps K; asking for another fixed K is refused
    assert main(["fit", str(src), "-o", str(run), "--resume", "--steps", "10", "--no-progress"]) == 0
    capsys.readouterr()
    assert main(["fit", str(src), "-o", str(run), "--resume", "--charts", "3", "--no-progress"]) == 2
    assert "cannot resume" in capsys.readouterr().err


@pytest.mark.parametrize("value", ["many", "2.5", ""])
def test_bad_charts_value_is_one_line(tmp_path, capsys, value):
    src = tmp_path / "s.ply"
    shapes.sphere(subdivisions=1).export(src)
    out = tmp_path / "run"
    assert main(["fit", str(src), "-o", str(out), "--charts", value]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--charts must be an integer or auto" in err
    assert not out.exists() or not any(out.iterdir())


def test_paper_comparisons_keep_a_fixed_k():
    from mna import paper

    cfg = C.fast()
    cfg.charts_rule = "topology"
    assert paper.configure(cfg, charts=3).charts_rule == "fixed"
