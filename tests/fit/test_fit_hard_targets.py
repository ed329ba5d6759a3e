"""Hard-example targets (mna.hard_targets): cell sizes, error-weighted draws, the objective's
``labelled`` split, and exact resume."""
from __future__ import annotations

import numpy as np
import pytest
import torch
import trimesh

from mna import config as C
from mna.data import make_surface
from mna.hard_targets import EMA, ErrorMap, HardTargets, cell_labels
from mna.run import fit_run, load_model
from mnacore.errors import MnaError


def _sphere(subdivisions: int = 4):
    s = trimesh.creation.icosphere(subdivisions=subdivisions, radius=3.7)  # not unit: the frame normalises
    return make_surface(s.vertices, s.faces)


@pytest.mark.parametrize("wanted", [200, 3000])
def test_cells_are_sized_for_the_wanted_count(wanted):
    """About ``wanted`` occupied cells on a closed surface and on a flat sheet (area 4 pi vs ~2)."""
    sphere = _sphere(5)
    sheet = trimesh.creation.box(extents=(2.0, 2.0, 1e-3)).subdivide_to_size(0.01)
    sheet = make_surface(sheet.vertices, sheet.faces)
    for surface in (sphere, sheet):
        cells = cell_labels(surface.element_centers, wanted)
        occupied = len(np.unique(cells))
        assert 0.6 * wanted <= occupied <= 1.5 * wanted, (wanted, occupied)


def _upper_share(points: np.ndarray) -> float:
    return float((points[:, 2] > 0).mean())


def test_draws_follow_area_times_error():
    """Error 1 on the upper hemisphere and 0.01 below: the upper share of the draws is
    A_up / (A_up + 0.01 A_low) = 1 / 1.01, not the area-uniform 1/2."""
    surface = _sphere()
    hard = HardTargets(ErrorMap(surface, 1000), 20000)
    rng = np.random.default_rng(0)
    before, _, _ = hard.draw(rng)
    assert _upper_share(before) == pytest.approx(0.5, abs=0.02)  # nothing recorded: area-uniform
    elements = np.arange(surface.element_count)
    up = surface.element_centers[:, 2] > 0
    hard.errors.record(elements, np.where(up, 1.0, 0.01))
    pts, normals, faces = hard.draw(rng)
    assert pts.shape == (20000, 3) and normals.shape == (20000, 3) and faces.shape == (20000,)
    # a cell straddling the equator mixes both errors; the equator band is a small share of the area
    assert _upper_share(pts) == pytest.approx(1 / 1.01, abs=0.01)
    np.testing.assert_allclose(normals, surface.face_normals[faces])


def test_record_is_a_running_mean_per_cell():
    surface = _sphere(2)
    hard = ErrorMap(surface, 50)
    elements, dist = np.array([0, 0, 1]), np.array([0.2, 0.4, 0.9])
    cell0 = hard.cell_of[0]
    hard.record(elements, dist)
    # the first observation of a cell is the mean of its targets' distances
    members = [d for i, d in zip(elements, dist) if hard.cell_of[i] == cell0]
    first0 = hard.error[cell0]
    assert len(members) >= 2 and first0 == pytest.approx(np.mean(members))
    hard.record(np.array([0]), np.array([0.1]))
    assert hard.error[cell0] == pytest.approx((1 - EMA) * first0 + EMA * 0.1)
    assert hard.seen.sum() == len({hard.cell_of[i] for i in elements})


def test_cloud_input_draws_by_weight():
    rng = np.random.default_rng(1)
    pts = rng.normal(size=(4000, 3))
    pts /= np.linalg.norm(pts, axis=1, keepdims=True)
    surface = make_surface(pts * 5.0, None)
    w = np.where(surface.points[:, 0] > 0, 9.0, 1.0)
    drawn, normals, idx = surface.sample_elements(30000, rng, weight=w)
    assert normals is None
    share = (w[idx] == 9.0).mean()
    frac = (w == 9.0).mean()
    assert share == pytest.approx(9 * frac / (9 * frac + (1 - frac)), abs=0.01)


def test_only_labelled_targets_make_positives():
    """Extra (hard) targets change L_rec but not the occupancy labels; distances are exact."""
    from mna.model import NeuralAtlas
    from mna.objective import atlas_losses

    torch.manual_seed(0)
    cfg = C.tiny()
    model = NeuralAtlas.from_config(cfg.model, cfg.ablation).double()
    uv = torch.rand(3, 1, 60, 2, dtype=torch.float64) * 2 - 1
    uniform = torch.randn(1, 40, 3, dtype=torch.float64) * 0.5
    extra = torch.randn(1, 25, 3, dtype=torch.float64) * 0.5
    both = torch.cat([uniform, extra], 1)
    alone = atlas_losses(model, uv, uniform, cfg)
    mixed = atlas_losses(model, uv, both, cfg, labelled=40)
    assert mixed.occ.item() == pytest.approx(alone.occ.item(), rel=1e-12)
    unlabelled = atlas_losses(model, uv, both, cfg)
    assert unlabelled.occ.item() != pytest.approx(alone.occ.item(), rel=1e-6)
    x = model.chart(uv).x[:, 0].reshape(-1, 3).detach()
    d = torch.cdist(both[0], x).min(1).values
    torch.testing.assert_close(mixed.distance[0], d)
    assert mixed.rec.item() == pytest.approx((d**2).mean().item(), rel=1e-9)


def _tiny(steps: int) -> C.FitConfig:
    cfg = C.tiny()
    cfg.steps, cfg.device, cfg.hard_targets = steps, "cpu", 300
    return cfg


def test_resume_with_hard_targets_equals_uninterrupted(torus_file, tmp_path):
    full, part = tmp_path / "full", tmp_path / "part"
    fit_run(torus_file, full, _tiny(24), progress_bar=False, log=lambda s: None)
    r = fit_run(torus_file, part, _tiny(24), callback=lambda step: step == 11, progress_bar=False, log=lambda s: None)
    assert r.interrupted and r.steps == 11
    fit_run(torus_file, part, _tiny(24), resume=True, progress_bar=False, log=lambda s: None)
    ma, _, _, _ = load_model(full)
    mb, _, _, _ = load_model(part)
    for (na, pa), (nb, pb) in zip(ma.state_dict().items(), mb.state_dict().items()):
        assert torch.equal(pa, pb), na
    # and the hard draws did change the fit (the option is live)
    cfg = _tiny(24)
    cfg.hard_targets = 0
    fit_run(torus_file, tmp_path / "plain", cfg, progress_bar=False, log=lambda s: None)
    mc, _, _, _ = load_model(tmp_path / "plain")
    assert not torch.equal(next(iter(mc.parameters())), next(iter(ma.parameters())))


def test_negative_hard_targets_is_refused():
    cfg = C.fast()
    cfg.hard_targets = -1
    with pytest.raises(MnaError, match="hard_targets"):
        cfg.validate()
