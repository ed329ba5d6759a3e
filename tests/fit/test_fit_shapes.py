"""The built-in shapes have the topology and size their docstrings promise (fit-fidelity
benchmarks rest on it: a "genus-4" shape that is not genus 4 would measure nothing)."""
from __future__ import annotations

import numpy as np

from mna import shapes


def _genus(mesh) -> int:
    parts = len(mesh.split(only_watertight=False))
    return (2 * parts - mesh.euler_number) // 2


def test_closed_forms_of_the_basic_shapes():
    s = shapes.sphere(radius=2.0, subdivisions=5)
    assert abs(s.area - 4 * np.pi * 4.0) / (16 * np.pi) < 2e-3
    t = shapes.torus(major=1.5, minor=0.3, sections=192, ring=96)
    assert abs(t.area - 4 * np.pi**2 * 1.5 * 0.3) / (4 * np.pi**2 * 0.45) < 2e-3
    assert _genus(t) == 1 and _genus(shapes.genus2()) == 2


def test_hard_shapes_have_their_topology():
    g4 = shapes.genus4()
    assert g4.is_watertight and _genus(g4) == 4 and len(g4.split(only_watertight=False)) == 1
    limbs = shapes.limbs()
    assert limbs.is_watertight and _genus(limbs) == 0 and len(limbs.split(only_watertight=False)) == 1
    # six limbs reach out to their tips (|tip| 1.3-1.4 from the centre): not fused into the body
    assert np.linalg.norm(limbs.vertices, axis=1).max() > 1.3
    parts = shapes.assembly(parts=12)
    pieces = parts.split(only_watertight=False)
    assert len(pieces) == 12 and all(p.is_watertight for p in pieces)
    assert len(shapes.assembly(parts=5, seed=1).split(only_watertight=False)) == 5


def test_bumpy_relief_has_its_amplitude():
    m = shapes.bumpy(subdivisions=5, amplitude=0.05, frequency=10.0)
    r = np.linalg.norm(m.vertices, axis=1)
    assert m.is_watertight and _genus(m) == 0
    # r = 1 + a sin sin sin: the product reaches +-1 only near points where all three are +-1,
    # which lie off the sphere at this frequency; the extremes come within 20 % of it
    assert 0.8 * 0.05 < r.max() - 1 <= 0.05 + 1e-9 and 0.8 * 0.05 < 1 - r.min() <= 0.05 + 1e-9
