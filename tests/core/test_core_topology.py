"""mnacore.topology: parts, genus and boundary loops against trimesh's Euler number and
shapes whose topology is known by construction."""
from __future__ import annotations

import numpy as np
import trimesh

from mna import shapes
from mnacore.topology import mesh_topology


def _trimesh_genus(mesh) -> int:
    """Closed parts only: g = (2 parts - chi) / 2 with trimesh's own Euler number."""
    parts = len(mesh.split(only_watertight=False))
    return (2 * parts - mesh.euler_number) // 2


def test_closed_shapes_match_trimesh_euler_number():
    for mesh, genus in ((shapes.sphere(), 0), (shapes.torus(), 1), (shapes.genus2(), 2),
                        (shapes.pretzel(3, resolution=80), 3), (shapes.genus4(resolution=72), 4)):
        topo = mesh_topology(mesh.vertices, mesh.faces)
        assert topo.parts == 1 and topo.manifold and topo.boundaries == (0,)
        assert topo.genus == (genus,) == (_trimesh_genus(mesh),)


def test_plate_with_a_grid_of_holes_has_that_genus():
    m = shapes.plate((2, 3), resolution=96)
    assert m.is_watertight and mesh_topology(m.vertices, m.faces).genus == (6,)


def test_parts_are_ordered_by_size_and_counted_separately():
    big = trimesh.creation.torus(1.0, 0.3, major_sections=48, minor_sections=24)
    small = trimesh.creation.icosphere(subdivisions=1, radius=0.2)
    small.apply_translation([3, 0, 0])
    both = trimesh.util.concatenate([small, big])
    topo = mesh_topology(both.vertices, both.faces)
    assert topo.parts == 2 and topo.genus == (1, 0) and topo.total_genus == 1


def test_boundaries_of_open_surfaces():
    sheet = shapes.sheet()
    assert mesh_topology(sheet.vertices, sheet.faces).boundaries == (1,)
    # an open tube (annulus): two boundary loops, genus 0, chi = 0
    tube = trimesh.creation.cylinder(radius=0.5, height=2.0, sections=32)
    keep = np.abs(tube.face_normals[:, 2]) < 0.5  # drop the caps
    topo = mesh_topology(tube.vertices, tube.faces[keep])
    assert topo.boundaries == (2,) and topo.genus == (0,)


def test_a_triangle_soup_is_welded_first():
    """Every face with its own three vertices (as after UV seams): still one closed torus."""
    t = shapes.torus()
    soup_v = t.vertices[t.faces].reshape(-1, 3) * 250.0  # and not in the unit frame
    soup_f = np.arange(len(soup_v)).reshape(-1, 3)
    topo = mesh_topology(soup_v, soup_f)
    assert topo.parts == 1 and topo.genus == (1,) and topo.boundaries == (0,)


def test_non_manifold_edges_are_flagged():
    s = shapes.sphere(subdivisions=1)
    fin = np.array([[*s.faces[0][:2], len(s.vertices)]])  # a third face on an existing edge
    v = np.vstack([s.vertices, [[2.0, 2.0, 2.0]]])
    topo = mesh_topology(v, np.vstack([s.faces, fin]))
    assert not topo.manifold and topo.parts == 1
