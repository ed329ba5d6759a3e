"""Procedural test shapes (torch-free): the demo and tests must not need third-party meshes.

Every function returns a watertight-where-expected ``trimesh.Trimesh`` with a known
closed-form area where one exists, so tests can assert against it.
"""
from __future__ import annotations

import numpy as np
import trimesh


def sphere(radius: float = 1.0, subdivisions: int = 4) -> trimesh.Trimesh:
    """Icosphere; area -> 4 pi r^2 as subdivisions grow. Genus 0."""
    return trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)


def torus(major: float = 1.0, minor: float = 0.4, sections: int = 96, ring: int = 48) -> trimesh.Trimesh:
    """Torus of revolution; area = 4 pi^2 R r. Genus 1."""
    return trimesh.creation.torus(major_radius=major, minor_radius=minor,
                                  major_sections=sections, minor_sections=ring)


def genus2(resolution: int = 72) -> trimesh.Trimesh:
    """A genus-2 surface (two fused tori) from marching cubes on an implicit function."""
    from skimage.measure import marching_cubes

    n = resolution
    lin = np.linspace(-1.6, 1.6, n)
    x, y, z = np.meshgrid(lin, lin, lin, indexing="ij")

    def ring(cx):
        # signed distance-like field of a torus centred at (cx, 0, 0) lying in the xy-plane
        q = np.sqrt((x - cx) ** 2 + y**2) - 0.55
        return np.sqrt(q**2 + z**2) - 0.22

    d1, d2 = ring(-0.6), ring(0.6)
    k = 0.15  # smooth-min radius: fuses the two tori into one genus-2 surface
    h = np.clip(0.5 + 0.5 * (d2 - d1) / k, 0.0, 1.0)
    field = d2 * (1 - h) + d1 * h - k * h * (1 - h)
    verts, faces, _, _ = marching_cubes(field, level=0.0, spacing=(lin[1] - lin[0],) * 3)
    verts = verts + lin[0]
    mesh = trimesh.Trimesh(verts, faces[:, ::-1], process=True)
    mesh.fix_normals()
    return mesh


def two_spheres(radius: float = 0.5, gap: float = 0.4, subdivisions: int = 3) -> trimesh.Trimesh:
    """Two disjoint spheres: a shape of several components."""
    a = sphere(radius, subdivisions)
    b = a.copy()
    a.apply_translation([-(radius + gap / 2), 0, 0])
    b.apply_translation([radius + gap / 2, 0, 0])
    return trimesh.util.concatenate([a, b])


def sheet(size: float = 2.0, resolution: int = 48, amplitude: float = 0.0) -> trimesh.Trimesh:
    """Open square sheet, optionally wavy: z = a sin(pi x) cos(pi y). Area = size^2 when flat."""
    lin = np.linspace(-size / 2, size / 2, resolution)
    x, y = np.meshgrid(lin, lin, indexing="xy")
    z = amplitude * np.sin(np.pi * x) * np.cos(np.pi * y)
    verts = np.stack([x, y, z], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(resolution - 1), np.arange(resolution - 1), indexing="ij")
    a = (i * resolution + j).ravel()
    b, c, d = a + 1, a + resolution + 1, a + resolution
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return trimesh.Trimesh(verts, faces, process=False)


SHAPES = {"sphere": sphere, "torus": torus, "genus2": genus2, "two_spheres": two_spheres, "sheet": sheet}


def make(name: str) -> trimesh.Trimesh:
    """Build a shape by name (one of ``SHAPES``)."""
    if name not in SHAPES:
        raise ValueError(f"unknown built-in shape {name!r}; choose from {', '.join(SHAPES)}")
    return SHAPES[name]()
