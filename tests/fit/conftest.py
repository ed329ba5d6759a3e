"""Fixtures for the fit stage: analytic atlases with known geometry, small shapes on disk."""
from __future__ import annotations

import numpy as np
import pytest
import torch
from torch import nn

from mna import shapes
from mna.model import ChartForward


class _HemisphereChart(nn.Module):
    """phi(u, v) = (u, v, sqrt(1 - u^2 - v^2)): orthographic parameterisation of the unit hemisphere."""

    charts = 1

    def forward(self, uv, z=None, jacobian=False):
        u, v = uv[..., 0], uv[..., 1]
        w = torch.sqrt(torch.clamp(1 - u**2 - v**2, min=1e-12))
        x = torch.stack([u, v, w], -1)
        jac = None
        if jacobian:
            one, zero = torch.ones_like(u), torch.zeros_like(u)
            du = torch.stack([one, zero, -u / w], -1)
            dv = torch.stack([zero, one, -v / w], -1)
            jac = torch.stack([du, dv], -1)
        return ChartForward(x, jac)


class AnalyticAtlas(nn.Module):
    """One hemisphere chart whose domain is the UV disk of radius ``radius`` (occupancy 1 inside, 0 out).

    Its surface area is the spherical cap ``2 pi (1 - sqrt(1 - radius^2))``.
    """

    def __init__(self, radius: float = 0.75):
        super().__init__()
        self.radius = radius
        self.charts = 1
        self.chart = _HemisphereChart()
        self.dummy = nn.Parameter(torch.zeros(1))  # gives the module a device

    def occupancy_value(self, uv, x, z=None):
        return ((uv**2).sum(-1) < self.radius**2).to(uv.dtype)

    def area(self) -> float:
        return 2 * np.pi * (1 - np.sqrt(1 - self.radius**2))


@pytest.fixture
def analytic_atlas() -> AnalyticAtlas:
    return AnalyticAtlas(0.75)


@pytest.fixture(scope="session")
def torus_file(tmp_path_factory) -> str:
    path = tmp_path_factory.mktemp("shapes") / "torus.ply"
    shapes.torus(sections=48, ring=24).export(path)
    return str(path)


@pytest.fixture(scope="session")
def sphere_file(tmp_path_factory) -> str:
    path = tmp_path_factory.mktemp("shapes") / "sphere.obj"
    shapes.sphere(subdivisions=3).export(path)
    return str(path)
