"""Closed forms for the distortion formulas (numpy and torch share one implementation)."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from mnacore import distortion as D


def _jac(a: float, b: float, shear: float = 0.0, n: int = 7, lib=np):
    """Constant Jacobian of (u, v) -> (a u + shear v, b v, 0), repeated n times."""
    J = np.zeros((n, 3, 2))
    J[:, 0, 0], J[:, 0, 1], J[:, 1, 1] = a, shear, b
    return J if lib is np else torch.from_numpy(J)


@pytest.mark.parametrize("scale", [0.01, 1.0, 3.7, 250.0])
@pytest.mark.parametrize("lib", [np, torch])
def test_isometry_has_zero_distortion_at_any_uniform_scale(scale, lib):
    g = D.metric_tensor(_jac(scale, scale, lib=lib))
    d = D.all_distortions(g, eps=0.0)
    assert d.metric == pytest.approx(0.0, abs=1e-12)
    assert d.conformal == pytest.approx(0.0, abs=1e-9)
    assert d.area == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("a,b", [(2.0, 1.0), (3.0, 0.5), (1.0, 4.0)])
def test_anisotropic_stretch_closed_forms(a, b):
    # singular values a, b: tr g = a^2 + b^2, tr g^-1 = 1/a^2 + 1/b^2, det = a^2 b^2
    g = D.metric_tensor(_jac(a, b))
    ssde = 2 * np.sqrt((a**2 + b**2) * (1 / a**2 + 1 / b**2))
    assert float(D.scaled_symmetric_dirichlet(g, eps=0.0)) == pytest.approx(ssde, rel=1e-12)
    assert float(D.distortion_metric(g, eps=0.0)) == pytest.approx(ssde - 4, rel=1e-12)
    assert float(D.distortion_conformal(g)) == pytest.approx((a**2 + b**2) / (a * b) - 2, rel=1e-9)
    assert float(D.distortion_area(g)) == pytest.approx(0.0, abs=1e-9)  # constant area factor


def test_stretch_two_one_values():
    g = D.metric_tensor(_jac(2.0, 1.0))
    d = D.all_distortions(g, eps=0.0)
    assert (d.metric, d.conformal, d.area) == pytest.approx((1.0, 0.5, 0.0), abs=1e-9)


def test_shear_is_rotation_invariant():
    # a shear's singular values come from the 2x2 block; the metric must not see a 3D rotation
    J = _jac(1.0, 1.0, shear=0.8)
    rot = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]]) @ np.array([[1, 0, 0], [0, 0.6, -0.8], [0, 0.8, 0.6]])
    g1, g2 = D.metric_tensor(J), D.metric_tensor(rot @ J)
    s = np.linalg.svd(J[0, :2, :], compute_uv=False)
    expected = 2 * np.sqrt((s**2).sum() * (1 / s**2).sum()) - 4
    assert float(D.distortion_metric(g1, eps=0.0)) == pytest.approx(expected, rel=1e-12)
    assert float(D.distortion_metric(g2, eps=0.0)) == pytest.approx(expected, rel=1e-12)


def test_area_distortion_mixed_scales():
    # half the samples scaled by 1, half by 2 (isotropic): A in {1, 4}; 2 sqrt(E[A] E[1/A]) - 2
    J = np.concatenate([_jac(1, 1, n=5), _jac(2, 2, n=5)])
    expected = 2 * np.sqrt(2.5 * (1 + 0.25) / 2) - 2
    assert float(D.distortion_area(D.metric_tensor(J))) == pytest.approx(expected, rel=1e-9)


def test_weights_equal_repetition():
    J = np.concatenate([_jac(1, 1, n=1), _jac(3, 1, n=1)])
    Jrep = np.concatenate([_jac(1, 1, n=1), _jac(3, 1, n=3)])
    w = np.array([1.0, 3.0])
    a = D.all_distortions(D.metric_tensor(J), weights=w)
    b = D.all_distortions(D.metric_tensor(Jrep))
    assert a == pytest.approx(b, rel=1e-12)


def test_eps_regularises_singular_jacobians():
    J = _jac(1.0, 0.0)  # rank one: tr g^-1 is infinite without eps
    v = float(D.scaled_symmetric_dirichlet(D.metric_tensor(J), eps=1e-4))
    # (1 + 2e-4) * (tr(g+eps)/det(g+eps)) = (1.0002) * (1.0002 / ((1.0001)(1e-4)))
    expected = 2 * np.sqrt(1.0002 * 1.0002 / (1.0001 * 1e-4))
    assert np.isfinite(v) and v == pytest.approx(expected, rel=1e-9)


def test_reported_distortions_of_rotated_isometries_are_zero_not_below():
    # 50 faces each turned its own way, one scale: an isometry up to scale, where rounding in
    # 2 sqrt(E[tr g] E[tr g^-1]) - 4 left -4.4e-16 on a third of such maps ("-0.000" in reports)
    rng = np.random.default_rng(0)
    for _ in range(50):
        th, s = rng.uniform(0, 2 * np.pi, 50), rng.uniform(0.1, 10)
        rot = np.stack([np.stack([np.cos(th), -np.sin(th)], -1), np.stack([np.sin(th), np.cos(th)], -1)], -2)
        jac = np.concatenate([rot, np.zeros((50, 1, 2))], 1) * s  # (50, 3, 2)
        d = D.all_distortions(D.metric_tensor(jac), weights=rng.uniform(0.1, 1, 50))
        assert 0.0 <= d.metric < 1e-12 and 0.0 <= d.conformal < 1e-12 and 0.0 <= d.area < 1e-12
    assert np.isnan(D.all_distortions(D.metric_tensor(np.full((2, 3, 2), np.nan))).metric)
