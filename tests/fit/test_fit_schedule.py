"""The learning-rate schedule (constant, then a cosine down to the final fraction) and the UV samples that follow it."""
from __future__ import annotations

import numpy as np
import pytest
import torch
import trimesh

import mna.fit as F
from mna import config as C
from mna.data import make_surface
from mna.fit import lr_factor
from mnacore.errors import MnaError


def test_constant_before_decay_start():
    assert [lr_factor(p, 0.55, 0.02) for p in (0.0, 0.3, 0.55)] == [1.0, 1.0, 1.0]


def test_cosine_values():
    assert lr_factor(1.0, 0.5, 0.02) == pytest.approx(0.02)
    assert lr_factor(0.75, 0.5, 0.02) == pytest.approx((1 + 0.02) / 2)  # half way: cos(pi/2) = 0
    assert lr_factor(0.625, 0.5, 0.0) == pytest.approx(0.5 * (1 + 2**-0.5))  # cos(pi/4)


def test_no_decay_when_start_is_one():
    assert lr_factor(1.0, 1.0, 0.02) == 1.0


def test_late_uv_samples_start_with_the_decay(monkeypatch):
    """A 10-step fit decaying from half way draws ``uv_samples`` per chart for steps 1-5 and
    ``late_uv_samples`` from step 6 (progress 0.5) on; 0 keeps ``uv_samples`` throughout."""
    s = trimesh.creation.icosphere(subdivisions=3, radius=2.5)
    surface = make_surface(s.vertices, s.faces)
    drawn = []
    real = F.uniform_uv

    def spy(charts, count, generator, batch=1, device="cpu"):
        uv = real(charts, count, generator, batch, device)
        drawn.append(tuple(uv.shape))
        return uv

    monkeypatch.setattr(F, "uniform_uv", spy)
    for late, want in ((700, [300] * 5 + [700] * 5), (0, [300] * 10)):
        cfg = C.tiny()
        cfg.model.charts, cfg.uv_samples, cfg.late_uv_samples = 2, 300, late
        cfg.steps, cfg.lr_decay_start = 10, 0.5
        fitter = F.Fitter(cfg.validate(), surface, torch.device("cpu"))
        drawn.clear()
        while not fitter.done():
            fitter.train_step()
        assert [shape[2] for shape in drawn] == want
        assert all(shape[0] == 2 for shape in drawn)
    assert np.isfinite(fitter.model.chart(real(2, 10, torch.Generator(), 1, "cpu")).x.detach().numpy()).all()


def test_late_uv_samples_must_be_a_count():
    cfg = C.tiny()
    cfg.late_uv_samples = -1
    with pytest.raises(MnaError, match="late_uv_samples"):
        cfg.validate()


def test_surface_term_ends_where_the_lr_decays(monkeypatch):
    """A 10-step fit decaying from 0.3 adds w_surface * L_surf (> 0) to steps 1-3 and
    leaves it out from step 4 (progress 0.3) on; the total is the other terms' sum there."""
    s = trimesh.creation.icosphere(subdivisions=3, radius=2.5)
    surface = make_surface(s.vertices, s.faces)
    cfg = C.tiny()
    cfg.steps, cfg.lr_decay_start, cfg.loss.w_surface, cfg.surface_samples = 10, 0.3, 0.5, 200
    seen = []
    real = F.atlas_losses

    def spy(*a, **k):
        t = real(*a, **k)
        w = cfg.loss
        rest = w.w_rec * t.rec + w.w_occ * t.occ + w.w_dist * t.dist + w.w_orient * t.orient
        seen.append((float(t.surface.detach()), float((t.total - rest).detach())))
        return t

    monkeypatch.setattr(F, "atlas_losses", spy)
    fitter = F.Fitter(cfg.validate(), surface, torch.device("cpu"))
    while not fitter.done():
        fitter.train_step()
    assert all(l_surf > 1e-4 and extra == pytest.approx(0.5 * l_surf, rel=1e-5) for l_surf, extra in seen[:3])
    assert all(l_surf == 0.0 and extra == 0.0 for l_surf, extra in seen[3:])


def test_late_distortion_weight_starts_with_the_decay(monkeypatch):
    """A 10-step fit decaying from 0.3 weighs L_dist by ``loss.w_dist`` (1e-3) at steps 1-3
    and by ``late_w_dist`` (0.25, 250x: a wrong weight shows) from step 4 on; 0 keeps w_dist."""
    s = trimesh.creation.icosphere(subdivisions=3, radius=2.5)
    surface = make_surface(s.vertices, s.faces)
    real = F.atlas_losses
    for late, want in ((0.25, [1e-3] * 3 + [0.25] * 7), (0.0, [1e-3] * 10)):
        cfg = C.tiny()
        cfg.steps, cfg.lr_decay_start, cfg.loss.w_surface = 10, 0.3, 0.0
        cfg.loss.w_dist, cfg.late_w_dist = 1e-3, late
        seen = []

        def spy(*a, **k):
            t = real(*a, **k)
            w = cfg.loss
            rest = w.w_rec * t.rec + w.w_occ * t.occ + w.w_orient * t.orient
            seen.append(float((t.total - rest).detach()) / float(t.dist.detach()))
            return t

        monkeypatch.setattr(F, "atlas_losses", spy)
        fitter = F.Fitter(cfg.validate(), surface, torch.device("cpu"))
        while not fitter.done():
            fitter.train_step()
        assert seen == pytest.approx(want, rel=1e-3)


def test_late_distortion_weight_needs_the_term():
    cfg = C.tiny()
    cfg.loss.w_dist, cfg.late_w_dist = 0.0, 1e-4
    with pytest.raises(MnaError, match="late_w_dist"):
        cfg.validate()
    cfg.late_w_dist = -1.0
    with pytest.raises(MnaError, match="late_w_dist"):
        cfg.validate()


def test_chart_octaves_open_over_their_window(monkeypatch):
    """A 10-step fit with 3 chart octaves opening from 0.2 to 0.6 of the run: shut at steps 1-3
    (progress 0-0.2), 3 (p - 0.2) / 0.4 open between, all from step 7 (progress 0.6) on; the
    window the model ends with is saved and loaded with it."""
    s = trimesh.creation.icosphere(subdivisions=3, radius=2.5)
    surface = make_surface(s.vertices, s.faces)
    cfg = C.tiny()
    cfg.model.charts, cfg.model.chart_octaves = 2, 3
    cfg.steps, cfg.chart_octaves_from, cfg.chart_octaves_until = 10, 0.2, 0.6
    fitter = F.Fitter(cfg.validate(), surface, torch.device("cpu"))
    seen = []
    real = F.uniform_uv

    def spy(*args, **kwargs):
        seen.append(float(fitter.model.chart.window))
        return real(*args, **kwargs)

    monkeypatch.setattr(F, "uniform_uv", spy)
    while not fitter.done():
        fitter.train_step()
    want = [0.0, 0.0, 0.0, 0.75, 1.5, 2.25, 3.0, 3.0, 3.0, 3.0]
    assert seen == pytest.approx(want)
    again = F.Fitter(cfg, surface, torch.device("cpu"))
    again.model.chart.window.fill_(0.0)
    again.load_state_dict(fitter.state_dict())
    assert float(again.model.chart.window) == 3.0


def test_chart_octaves_window_must_be_ordered():
    cfg = C.tiny()
    cfg.chart_octaves_from, cfg.chart_octaves_until = 0.6, 0.2
    with pytest.raises(MnaError, match="chart_octaves_until"):
        cfg.validate()


def _octave_fitter(surface, min_steps, **cfg_fields):
    cfg = C.tiny()
    cfg.model.charts, cfg.model.chart_octaves = 2, 2
    cfg.chart_octaves_from, cfg.chart_octaves_until, cfg.chart_octaves_min_steps = 0.1, 0.5, min_steps
    for name, value in cfg_fields.items():
        setattr(cfg, name, value)
    return F.Fitter(cfg.validate(), surface, torch.device("cpu"))


def test_chart_octaves_stay_shut_in_a_run_shorter_than_their_minimum():
    """A 20-step run opens the encoding when ``chart_octaves_min_steps`` is 20 (one of its 2
    octaves at step 6: progress 0.3 of the 0.1-0.5 window) and keeps it shut throughout when it is 21."""
    s = trimesh.creation.icosphere(subdivisions=2, radius=2.5)
    surface = make_surface(s.vertices, s.faces)
    for min_steps, want in ((20, [0.0, 0.0, 0.5, 1.0, 1.5, 2.0, 2.0]), (21, [0.0] * 7)):
        fitter = _octave_fitter(surface, min_steps, steps=20)
        got = []
        for step in (0, 2, 4, 6, 8, 10, 19):
            fitter.step = step
            got.append(fitter.octaves_open())
        assert got == pytest.approx(want)
        assert fitter.encoding is (min_steps == 20)


def test_time_budget_estimates_the_run_length_once_as_the_window_opens():
    """With a 100 s budget and the window from 0.1: 40 steps in 11 s is a pace of 364 steps in
    the run, enough for a minimum of 360 (0.025 * 2 octaves open at progress 0.11), too few
    for 370. The decision is kept when the pace changes afterwards, and a checkpoint carries it;
    the late distortion weight and the exclusive labels (from the decay at 0.6) go with the encoding."""
    s = trimesh.creation.icosphere(subdivisions=2, radius=2.5)
    surface = make_surface(s.vertices, s.faces)
    for min_steps, opens in ((360, True), (370, False)):
        fitter = _octave_fitter(surface, min_steps, time_budget=100.0, late_w_dist=0.5, exclusive_labels=True)
        fitter.step, fitter.elapsed = 5, 9.0  # progress 0.09: before the window, nothing decided
        assert fitter.octaves_open() == 0.0 and fitter.encoding is None
        fitter.step, fitter.elapsed = 40, 11.0
        assert fitter.octaves_open() == pytest.approx(0.05 if opens else 0.0)
        fitter.step, fitter.elapsed = 4000 if not opens else 41, 30.0  # another pace: no second decision
        assert fitter.octaves_open() == pytest.approx(1.0 if opens else 0.0)
        assert fitter.dist_weight() is None and not fitter.exclusive()  # progress 0.3: before the decay
        fitter.elapsed = 70.0
        assert fitter.dist_weight() == (0.5 if opens else None)
        assert fitter.exclusive() is opens
        again = _octave_fitter(surface, min_steps, time_budget=100.0)
        again.load_state_dict(fitter.state_dict())
        assert again.encoding is opens


def test_detail_is_fast_with_the_encoding_opened_only_in_long_enough_fresh_runs(tmp_path):
    """``detail`` differs from ``fast`` in the chart encoding, its window (with a minimum run
    length below its 3,000 steps), a stronger L_dist and exclusive labels in the decay;
    :func:`mna.config.settle_encoding` builds a
    shorter steps run without it, leaves a time budget's to the fitter, and the settled
    config survives the config.yaml round trip every run saves."""
    fast, detail = C.to_dict(C.preset("fast")), C.to_dict(C.preset("detail"))
    differ = {k for k in fast if fast[k] != detail[k]}
    assert {"preset", "model", "chart_octaves_min_steps", "late_w_dist", "exclusive_labels"} <= differ <= {
        "preset", "model", "chart_octaves_from", "chart_octaves_until", "chart_octaves_min_steps", "late_w_dist",
        "exclusive_labels"}
    assert detail["late_w_dist"] > detail["loss"]["w_dist"] == fast["loss"]["w_dist"]
    assert {k for k in fast["model"] if fast["model"][k] != detail["model"][k]} == {"chart_octaves"}
    cfg = C.preset("detail").validate()
    assert cfg.model.chart_octaves == 2 and 0 < cfg.chart_octaves_min_steps <= cfg.steps
    assert C.settle_encoding(C.preset("detail")).model.chart_octaves == 2 and cfg.late_w_dist > 0
    short = C.preset("detail")
    short.steps = cfg.chart_octaves_min_steps - 1
    assert C.settle_encoding(short).model.chart_octaves == 0 and short.late_w_dist == 0.0
    assert cfg.exclusive_labels and not short.exclusive_labels
    timed = C.preset("detail")
    timed.steps, timed.time_budget = 1, 60.0
    assert C.settle_encoding(timed).model.chart_octaves == 2
    C.save_yaml(tmp_path / "config.yaml", C.to_dict(short.validate()))
    assert C.to_dict(C.from_dict(C.load_yaml(tmp_path / "config.yaml"))) == C.to_dict(short)


def test_mna_fit_without_a_preset_fits_detail_and_a_short_run_is_the_fast_fit():
    """``mna fit`` with no ``--preset`` builds ``detail`` (the default budget opens its
    encoding); a run shorter than its minimum (the demo's 1,200 steps) settles to ``fast``'s
    config in every field a fit reads (only the name and the shut window's bounds differ)."""
    from mna.cli import build_parser
    from mna.commands.fit import build_config

    def config(*argv):
        return build_config(build_parser().parse_args(["fit", "in.ply", "-o", "run", *argv]))

    assert C.to_dict(config()) == C.to_dict(C.preset("detail").validate())
    assert C.settle_encoding(config()).model.chart_octaves == 2
    short = C.to_dict(C.settle_encoding(config("--steps", "1200")))
    fast = C.to_dict(C.settle_encoding(config("--steps", "1200", "--preset", "fast")))
    assert short["steps"] == fast["steps"] == 1200 and short["preset"] == "detail"
    assert {k for k in fast if fast[k] != short[k]} <= {"preset", "chart_octaves_from", "chart_octaves_until",
                                                        "chart_octaves_min_steps"}


def test_the_fit_log_says_whether_the_chart_encoding_is_on():
    """A default run says its encoding is on; one too short for it says it is the plain fit
    (with the settled minimum); ``fast`` says nothing of it."""
    long = C.settle_encoding(C.preset("detail"))
    assert C.encoding_summary(long) == "chart encoding: 2 octaves"
    short = C.preset("detail")
    short.steps = 1200
    assert C.encoding_summary(C.settle_encoding(short)) == \
        "chart encoding: off (runs under 2,400 steps are the plain fit)"
    timed = C.preset("detail")
    timed.time_budget = 60.0
    assert "if the budget's pace reaches 2,400 steps" in C.encoding_summary(C.settle_encoding(timed))
    resumed = C.settle_encoding(short)
    resumed.steps = 3000  # ``--resume --steps 3000`` of that run: still the plain fit
    assert C.encoding_summary(resumed) == "chart encoding: off (the run was started without it; resuming keeps that)"
    assert C.encoding_summary(C.preset("fast")) == ""


def test_chart_octaves_min_steps_must_be_a_count():
    cfg = C.tiny()
    cfg.chart_octaves_min_steps = -5
    with pytest.raises(MnaError, match="chart_octaves_min_steps"):
        cfg.validate()


def test_exclusive_labels_is_a_switch():
    """``exclusive_labels`` takes true/false only: from YAML (strict types) and in code."""
    cfg = C.tiny()
    cfg.exclusive_labels = 1
    with pytest.raises(MnaError, match="exclusive_labels"):
        cfg.validate()
    with pytest.raises(MnaError, match="exclusive_labels"):
        C.from_dict({"exclusive_labels": "yes"})
    assert C.from_dict({"exclusive_labels": True, "lr_decay_start": 0.5}).validate().exclusive_labels is True


def test_exclusive_labels_start_with_the_decay(monkeypatch):
    """A 10-step fit decaying from 0.3 with ``exclusive_labels`` picks its positives the
    exclusive way at steps 4-10 (one shape: one call a step), the nearest way before; without
    the switch never. A fit without a decay cannot have them."""
    import mna.objective as O

    s = trimesh.creation.icosphere(subdivisions=3, radius=2.5)
    surface = make_surface(s.vertices, s.faces)
    real = O._exclusive_positives
    for on, want in ((True, list(range(3, 10))), (False, [])):
        cfg = C.tiny()
        cfg.steps, cfg.lr_decay_start, cfg.exclusive_labels = 10, 0.3, on
        fitter = F.Fitter(cfg.validate(), surface, torch.device("cpu"))
        seen = []
        monkeypatch.setattr(O, "_exclusive_positives", lambda *a: (seen.append(fitter.step), real(*a))[1])
        while not fitter.done():
            fitter.train_step()
        assert seen == want
    cfg = C.tiny()
    cfg.lr_decay_start, cfg.exclusive_labels = 1.0, True
    with pytest.raises(MnaError, match="exclusive_labels needs lr_decay_start"):
        cfg.validate()
