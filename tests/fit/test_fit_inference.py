"""Extraction on an analytic atlas with a known domain: counts, areas, domains, grid layout."""
from __future__ import annotations

import numpy as np
import pytest
import torch
import trimesh

from mna.inference import extract_grid, rejection_sample
from mna.metrics import atlas_distortion
from mnacore.grid import grid_faces, grid_uv


@pytest.mark.parametrize("count", [1000, 5000, 20000])
def test_rejection_sampling_lands_within_3_percent(analytic_atlas, count):
    sample = rejection_sample(analytic_atlas, count, torch.Generator().manual_seed(0), tau=0.5)
    assert abs(len(sample.points) - count) <= 0.03 * count
    # every accepted point is in-domain and on the unit sphere
    assert ((sample.uv**2).sum(1) < 0.75**2).all()
    np.testing.assert_allclose(np.linalg.norm(sample.points, axis=1), 1.0, atol=1e-6)
    # acceptance rate estimates the disk's share of the square, pi r^2 / 4
    assert sample.acceptance == pytest.approx(np.pi * 0.75**2 / 4, abs=0.03)


def test_rejection_sampling_of_an_empty_domain_returns_nothing(analytic_atlas):
    analytic_atlas.radius = 0.0
    sample = rejection_sample(analytic_atlas, 100, torch.Generator().manual_seed(0))
    assert len(sample.points) == 0 and sample.acceptance == 0.0


def test_extracted_mesh_recovers_the_cap_area(analytic_atlas):
    grid = extract_grid(analytic_atlas, 256, tau=0.5)
    area = trimesh.Trimesh(grid.vertices, grid.faces, process=False).area
    assert area == pytest.approx(analytic_atlas.area(), rel=0.02)
    # kept triangles have all three vertices inside the domain
    assert ((grid.vertex_uv**2).sum(1) < 0.75**2).all()
    assert grid.face_chart.tolist() == [0] * len(grid.faces)


def test_grid_layout_and_orientation():
    uv = grid_uv(3)
    assert uv[0, 0].tolist() == [-1, -1] and uv[0, 2].tolist() == [1, -1] and uv[2, 0].tolist() == [-1, 1]
    tri = grid_faces(3)
    assert len(tri) == 2 * 2 * 2
    flat = uv.reshape(-1, 2)
    a, b, c = flat[tri[:, 0]], flat[tri[:, 1]], flat[tri[:, 2]]
    signed = (b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0]
    assert (signed > 0).all()  # counter-clockwise in UV
    assert np.abs(signed).sum() / 2 == pytest.approx(4.0)  # covers the square (-1, 1)^2


def test_analytic_distortion_of_the_hemisphere_cap(analytic_atlas):
    # orthographic hemisphere chart: singular values 1 and 1/sqrt(1 - r^2) at radius r.
    # UV-uniform expectations over the disk of radius R have closed forms:
    R = 0.75
    r2 = np.linspace(0, R**2, 200001)  # r^2 is uniform over the disk
    s2 = 1 / (1 - r2)
    trg, trinv = np.mean(1 + s2), np.mean(1 + 1 / s2)
    expected = 2 * np.sqrt(trg * trinv) - 4
    d = atlas_distortion(analytic_atlas, 200000, torch.Generator().manual_seed(0), eps=0.0)
    assert d.distortion_metric == pytest.approx(expected, rel=0.01)
    assert d.distortion_conformal == pytest.approx(np.mean(np.sqrt(s2) + 1 / np.sqrt(s2)) - 2, rel=0.01)
    assert d.occupancy_rate[0] == pytest.approx(100 * np.pi * R**2 / 4, abs=0.5)
    assert d.degenerate_charts == 0
