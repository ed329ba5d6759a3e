"""Chart growth (mna.grow): when it fires, what a grown model keeps, exact resume."""
from __future__ import annotations

import numpy as np
import pytest
import torch
import trimesh
import yaml

from mna import config as C
from mna import grow
from mna.data import make_surface
from mna.grow import GAP_FACTOR, MIN_GAP, WINDOW, Growth, add_chart, gap_share
from mna.hard_targets import ErrorMap
from mna.model import NeuralAtlas


def _sphere_map(cells: int = 400) -> ErrorMap:
    s = trimesh.creation.icosphere(subdivisions=4, radius=2.0)
    return ErrorMap(make_surface(s.vertices, s.faces), cells)


def _observe(errors: ErrorMap, gap_cells: np.ndarray, far: float) -> None:
    d = np.where(np.isin(errors.cell_of, gap_cells), far, 0.01)
    errors.record(np.arange(len(errors.cell_of)), d)


def test_gap_share_is_the_area_of_cells_far_beyond_the_median():
    errors = _sphere_map()
    # the cells of the cap z > 0.8 (unit frame): area share of a spherical cap = (1 - 0.8) / 2 = 0.1
    cap = np.unique(errors.cell_of[errors.surface.element_centers[:, 2] > 0.8])
    _observe(errors, cap, 0.01 * GAP_FACTOR * 1.5)
    share, gap = gap_share(errors)
    assert share == pytest.approx(0.1, abs=0.02)
    assert set(np.flatnonzero(gap)) == set(cap)
    _observe(errors, cap, 0.01 * GAP_FACTOR * 0.5)  # closer than the factor: no gap (after the running mean)
    _observe(errors, cap, 0.01 * GAP_FACTOR * 0.5)
    _observe(errors, cap, 0.01 * GAP_FACTOR * 0.5)
    assert gap_share(errors)[0] == 0.0


def test_growth_waits_for_a_stall_then_points_at_the_worst_gap():
    errors = _sphere_map()
    cap = np.unique(errors.cell_of[errors.surface.element_centers[:, 2] > 0.8])
    _observe(errors, cap, 0.2)
    g = Growth(max_charts=5)
    fired = [s for s in range(50, 2000, 50) if g.due(s, 0.1, 3, errors) is not None]
    # a constant gap has stalled once a check WINDOW steps old exists: the first growth, then
    # the next only after another WINDOW of checks
    assert fired[:2] == [50 + WINDOW, 50 + WINDOW + 50 + WINDOW]
    center = Growth(5)
    for s in range(50, 50 + WINDOW + 1, 50):
        c = center.due(s, 0.1, 3, errors)
    assert c is not None and c[2] > 0.8  # inside the cap (unit frame)
    # no growth at the cap, late in the fit, or while the gap is small or shrinking
    assert all(Growth(3).due(s, 0.1, 3, errors) is None for s in range(50, 2000, 50))
    assert all(Growth(5).due(s, 0.6, 3, errors) is None for s in range(50, 2000, 50))
    small = _sphere_map(2000)
    tiny_cap = np.unique(small.cell_of[small.surface.element_centers[:, 2] > 1 - 2 * MIN_GAP * 0.25])
    _observe(small, tiny_cap, 0.2)
    assert gap_share(small)[0] < MIN_GAP
    assert all(Growth(5).due(s, 0.1, 3, small) is None for s in range(50, 2000, 50))


def test_a_grown_model_keeps_its_charts_and_their_adam_state():
    torch.manual_seed(0)
    cfg = C.tiny()
    model = NeuralAtlas.from_config(cfg.model, cfg.ablation)
    opt = torch.optim.Adam(model.parameters(), lr=1e-3)
    uv = torch.rand(3, 1, 50, 2) * 2 - 1
    for _ in range(3):
        opt.zero_grad()
        (model.chart(uv).x ** 2).sum().backward()
        opt.step()
    before = model.chart(uv).x.detach()
    center = np.array([0.3, -0.2, 0.5])
    grown, opt2 = add_chart(model, opt, cfg, center)
    assert grown.charts == 4 and cfg.model.charts == 4
    uv4 = torch.cat([uv, torch.rand(1, 1, 50, 2) * 2 - 1])
    x = grown.chart(uv4).x.detach()
    torch.testing.assert_close(x[:3], before)
    # the newborn is a small patch around its centre
    spread = (x[3, 0] - x[3, 0].mean(0)).norm(dim=-1).max()
    assert (x[3, 0].mean(0) - torch.tensor(center, dtype=x.dtype)).norm() < 0.1 and spread < 0.2
    for p_old, p_new in zip(model.parameters(), grown.parameters()):
        s_old, s_new = opt.state[p_old], opt2.state[p_new]
        if not s_old:  # the label nets got no gradient from this toy loss
            assert not s_new
            continue
        torch.testing.assert_close(s_new["exp_avg"][:3], s_old["exp_avg"])
        assert torch.count_nonzero(s_new["exp_avg"][3:]) == 0 and s_new["step"] == s_old["step"]


def test_grow_rule_fit_resumes_exactly_and_saves_the_grown_count(torus_file, tmp_path, monkeypatch):
    from mna.run import fit_run, load_model

    # a short fit: check often and call every gap a stall, so that growth happens both before
    # the interruption and after it
    monkeypatch.setattr(grow, "WINDOW", 6)
    monkeypatch.setattr(grow, "CHECK_EVERY", 3)
    monkeypatch.setattr(grow, "MIN_GAP", 0.0)
    monkeypatch.setattr(grow, "GAP_FACTOR", 1.0)  # every cell above the median is a gap
    monkeypatch.setattr(grow, "SHRINK", 1.1)
    monkeypatch.setattr(grow, "GROW_UNTIL", 1.0)

    def cfg():
        c = C.tiny()
        c.steps, c.device, c.charts_rule, c.max_charts = 30, "cpu", "grow", 5
        c.model.charts = 2
        return c

    full, part = tmp_path / "full", tmp_path / "part"
    fit_run(torus_file, full, cfg(), progress_bar=False, log=lambda s: None)
    saved = yaml.safe_load((full / "config.yaml").read_text())
    assert saved["model"]["charts"] == 5 and np.load(full / "charts.npz")["xyz"].shape[0] == 5
    r = fit_run(torus_file, part, cfg(), callback=lambda step: step == 14, progress_bar=False, log=lambda s: None)
    assert r.interrupted
    fit_run(torus_file, part, cfg(), resume=True, progress_bar=False, log=lambda s: None)
    ma, _, _, _ = load_model(full)
    mb, _, _, _ = load_model(part)
    for (na, pa), (nb, pb) in zip(ma.state_dict().items(), mb.state_dict().items()):
        assert torch.equal(pa, pb), na


def test_cli_charts_auto_grows_from_three_and_bad_values_are_one_line(torus_file, tmp_path, capsys):
    from mna.cli import main

    run = tmp_path / "run"
    argv = ["fit", torus_file, "-o", str(run), "--preset", "tiny", "--charts", "auto", "--steps", "6",
            "--no-progress", "--device", "cpu"]
    assert main(argv) == 0
    saved = yaml.safe_load((run / "config.yaml").read_text())
    assert saved["charts_rule"] == "grow" and saved["model"]["charts"] == 3 and saved["max_charts"] == 6
    capsys.readouterr()
    assert main(["fit", torus_file, "-o", str(run), "--resume", "--charts", "2", "--no-progress"]) == 2
    assert "cannot resume" in capsys.readouterr().err
    for value in ("many", "2.5", ""):
        out = tmp_path / f"bad{value}"
        assert main(["fit", torus_file, "-o", str(out), "--charts", value]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "--charts must be an integer or auto" in err
        assert not out.exists() or not any(out.iterdir())


def test_paper_comparisons_keep_a_fixed_k():
    from mna import paper

    cfg = C.fast()
    cfg.charts_rule = "grow"
    assert paper.configure(cfg, charts=3).charts_rule == "fixed"
