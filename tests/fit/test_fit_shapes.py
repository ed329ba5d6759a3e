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


def test_unseen_shapes_have_their_topology():
    """The unwrap benchmark's unseen shapes (``--unseen``): what each is said to hold, read
    back with mnacore.topology (which welds coincident points: parts that touched at a corner
    would fuse into one non-manifold part)."""
    from mnacore.topology import mesh_topology

    def topo(name):
        m = shapes.make(name)
        return mesh_topology(m.vertices, m.faces), m

    t, knot = topo("trefoil")
    assert (t.parts, t.genus, t.boundaries, t.manifold) == (1, (1,), (0,), True)
    # the tube's closed form: area = 2 pi r x the knot's length (the tube is thin beside its bends)
    w = np.linspace(0, 2 * np.pi, 20001)
    length = np.trapezoid(np.sqrt(17 + 8 * np.cos(3 * w) + 9 * np.cos(3 * w) ** 2), w)
    assert abs(knot.area - 2 * np.pi * 0.45 * length) / knot.area < 0.01
    t, chair = topo("chair")
    assert t.parts == 6 and t.genus == (0,) * 6 and t.boundaries == (0,) * 6 and t.manifold
    box = lambda a, b, c: 2 * (a * b + b * c + a * c)  # noqa: E731
    assert abs(chair.area - (box(2, 2, 0.2) + box(1.8, 0.2, 2) + 4 * box(0.2, 0.2, 1))) < 1e-9  # six boxes
    t, _ = topo("mug")
    assert t.parts == 2 and sorted(zip(t.genus, t.boundaries)) == [(0, 0), (0, 2)] and t.manifold
    t, saddle = topo("saddle_annulus")
    assert (t.parts, t.genus, t.boundaries) == (1, (0,), (2,))
    z = saddle.vertices[:, 2]
    np.testing.assert_allclose(z, 0.3 * (saddle.vertices[:, 0] ** 2 - saddle.vertices[:, 1] ** 2))
    t, star = topo("starfish")
    assert (t.parts, t.genus, t.boundaries) == (1, (0,), (0,))
    # five arms: the in-plane radius peaks 5 times around the centre, at 1 + 1.6 = 2.6
    rim = star.vertices[np.abs(star.vertices[:, 2]) < 1e-9]
    angle, radius = np.arctan2(rim[:, 1], rim[:, 0]), np.linalg.norm(rim[:, :2], axis=1)
    assert abs(radius.max() - 2.6) < 0.05
    assert len({int(np.round(a / (2 * np.pi / 5))) % 5 for a in angle[radius > 2.0]}) == 5
