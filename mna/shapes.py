"""Procedural test shapes (torch-free): the demo and tests must not need third-party meshes.

Every function returns a watertight-where-expected ``trimesh.Trimesh`` with a known
closed-form area where one exists, so tests can assert against it.
"""
from __future__ import annotations

import functools
from pathlib import Path

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
    n = resolution
    lin = np.linspace(-1.6, 1.6, n)
    x, y, z = np.meshgrid(lin, lin, lin, indexing="ij")

    def ring(cx):
        # signed distance-like field of a torus centred at (cx, 0, 0) lying in the xy-plane
        q = np.sqrt((x - cx) ** 2 + y**2) - 0.55
        return np.sqrt(q**2 + z**2) - 0.22

    # smooth-min radius 0.15: fuses the two tori into one genus-2 surface
    return _implicit(_smooth_min(ring(-0.6), ring(0.6), 0.15), lin)


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


def _smooth_min(a: np.ndarray, b: np.ndarray, k: float) -> np.ndarray:
    """Polynomial smooth minimum of two distance fields: a fillet of radius ~``k`` where
    their surfaces meet, so fused parts become one smooth surface."""
    h = np.clip(0.5 + 0.5 * (b - a) / k, 0.0, 1.0)
    return b * (1 - h) + a * h - k * h * (1 - h)


def _rounded_slab(x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Signed distance of a 2 x 2 x 0.4 plate with edges rounded by 0.08 (the plates' body)."""
    q = np.stack([np.abs(x) - 0.95, np.abs(y) - 0.95, np.abs(z) - 0.12])
    return np.linalg.norm(np.maximum(q, 0), axis=0) + np.minimum(q.max(0), 0) - 0.08


def _implicit(field, lin: np.ndarray) -> trimesh.Trimesh:
    """The zero level set of ``field`` sampled on ``lin``^3 (marching cubes), outward normals."""
    from skimage.measure import marching_cubes

    verts, faces, _, _ = marching_cubes(field, level=0.0, spacing=(lin[1] - lin[0],) * 3)
    mesh = trimesh.Trimesh(verts + lin[0], faces[:, ::-1], process=True)
    mesh.fix_normals()
    return mesh


def genus4(resolution: int = 96) -> trimesh.Trimesh:
    """A rounded plate with four round holes: genus 4 (Euler number -6)."""
    lin = np.linspace(-1.3, 1.3, resolution)
    x, y, z = np.meshgrid(lin, lin, lin, indexing="ij")
    slab = _rounded_slab(x, y, z)
    holes = np.min([np.hypot(x - cx, y - cy) - 0.28 for cx in (-0.5, 0.5) for cy in (-0.5, 0.5)], axis=0)
    return _implicit(np.maximum(slab, -holes), lin)


def pretzel(rings: int = 3, resolution: int = 112) -> trimesh.Trimesh:
    """``rings`` tori in a row, fused by a smooth minimum: genus ``rings`` (a pretzel), a
    different kind of handle from :func:`genus4`'s plate (thin round tubes, not holes in a slab)."""
    span = 0.6 * (rings - 1)
    lin = np.linspace(-span - 1.0, span + 1.0, resolution)
    x, y, z = np.meshgrid(lin, lin, lin, indexing="ij")
    field = None
    for cx in np.linspace(-span, span, rings):
        q = np.sqrt((x - cx) ** 2 + y**2) - 0.5
        d = np.sqrt(q**2 + z**2) - 0.17
        # smooth-min radius 0.12: fuses neighbouring rings into one surface
        field = d if field is None else _smooth_min(field, d, 0.12)
    return _implicit(field, lin)


def plate(holes: tuple[int, int] = (2, 3), resolution: int = 112) -> trimesh.Trimesh:
    """A rounded plate with a grid of ``rows x cols`` round holes: genus ``rows * cols``."""
    rows, cols = holes
    lin = np.linspace(-1.3, 1.3, resolution)
    x, y, z = np.meshgrid(lin, lin, lin, indexing="ij")
    slab = _rounded_slab(x, y, z)
    centres = [(cx, cy) for cx in np.linspace(-0.55, 0.55, rows) for cy in np.linspace(-0.6, 0.6, cols)]
    radius = 0.5 / max(rows, cols)
    holes_f = np.min([np.hypot(x - cx, y - cy) - radius for cx, cy in centres], axis=0)
    return _implicit(np.maximum(slab, -holes_f), lin)


def bumpy(subdivisions: int = 6, amplitude: float = 0.04, frequency: float = 14.0) -> trimesh.Trimesh:
    """A sphere with fine relief: radius 1 + a sin(f x) sin(f y) sin(f z). The bumps are about
    1/f wide: fine detail at the scale of the F-score's 0.02 tolerance. Genus 0."""
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions)
    v = mesh.vertices
    r = 1 + amplitude * np.sin(frequency * v[:, 0]) * np.sin(frequency * v[:, 1]) * np.sin(frequency * v[:, 2])
    return trimesh.Trimesh(v * r[:, None], mesh.faces, process=False)


def limbs(resolution: int = 112) -> trimesh.Trimesh:
    """A body with six thin limbs (capsules of radius 0.07, about 7 % of the body's size),
    smoothly joined: thin features a chart must stretch into. Genus 0."""
    lin = np.linspace(-1.5, 1.5, resolution)
    p = np.stack(np.meshgrid(lin, lin, lin, indexing="ij"), -1)
    field = np.linalg.norm(p / [0.6, 0.45, 0.4], axis=-1) * 0.45 - 0.45  # the body, roughly an ellipsoid
    tips = np.array([[1.3, 0.4, 0.2], [-1.3, 0.3, -0.2], [0.3, 1.3, 0.1], [-0.2, -1.3, 0.3], [0.2, 0.2, 1.3],
                     [0.4, -0.9, -1.0]])
    for tip in tips:
        t = np.clip((p @ tip) / (tip @ tip), 0, 1)[..., None]
        capsule = np.linalg.norm(p - t * tip, axis=-1) - 0.07
        field = _smooth_min(field, capsule, 0.08)  # a fillet where a limb meets the body
    return _implicit(field, lin)


def assembly(parts: int = 12, seed: int = 0) -> trimesh.Trimesh:
    """``parts`` disjoint solids (boxes, cylinders, spheres, capsules) of varied size on a
    jittered grid: many parts for few charts."""
    rng = np.random.default_rng(seed)
    makers = (lambda s: trimesh.creation.box(extents=s * rng.uniform(0.5, 1.0, 3)),
              lambda s: trimesh.creation.cylinder(radius=0.3 * s, height=s, sections=32),
              lambda s: trimesh.creation.icosphere(subdivisions=3, radius=0.45 * s),
              lambda s: trimesh.creation.capsule(height=0.6 * s, radius=0.2 * s, count=[16, 16]))
    side = int(np.ceil(np.sqrt(parts)))
    meshes = []
    for i in range(parts):
        m = makers[i % len(makers)](rng.uniform(0.5, 0.8))
        m.apply_transform(trimesh.transformations.random_rotation_matrix(rng.random(3)))
        m.apply_translation([i % side, i // side, rng.uniform(-0.3, 0.3)])
        meshes.append(m)
    return trimesh.util.concatenate(meshes)


def _periodic_grid(surface, n_u: int, n_v: int, closed_u: bool = True) -> trimesh.Trimesh:
    """Quads of ``surface(u, v) -> (..., 3)``, split in two triangles each: v over [0, 1)
    (periodic), u over [0, 1) where ``closed_u`` (a torus) or over [0, 1] (an open tube)."""
    u, v = np.meshgrid(np.arange(n_u) / (n_u if closed_u else n_u - 1), np.arange(n_v) / n_v, indexing="ij")
    i, j = np.meshgrid(np.arange(n_u if closed_u else n_u - 1), np.arange(n_v), indexing="ij")
    a, b = i * n_v + j, (i + 1) % n_u * n_v + j
    c, d = (i + 1) % n_u * n_v + (j + 1) % n_v, i * n_v + (j + 1) % n_v
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return trimesh.Trimesh(surface(u, v).reshape(-1, 3), faces, process=False)


def _tube(centre, tangent, radius: float, up=(0.0, 0.0, 1.0)):
    """``surface(u, v)`` of a tube of ``radius`` around the curve ``centre(t)`` (t in [0, 1]),
    framed by its ``tangent(t)`` and the fixed axis ``up``, which the tangent must never
    run along."""
    def surface(u, v):
        c, t = centre(u), tangent(u)
        t = t / np.linalg.norm(t, axis=-1, keepdims=True)
        n = np.cross(t, up)
        n /= np.linalg.norm(n, axis=-1, keepdims=True)
        s = 2 * np.pi * v[..., None]
        return c + radius * (np.cos(s) * n + np.sin(s) * np.cross(t, n))
    return surface


def trefoil(sections: int = 300, ring: int = 24) -> trimesh.Trimesh:
    """A tube (radius 0.45) around a trefoil knot: genus 1, long and knotted."""
    w = 2 * np.pi

    def centre(u):
        return np.stack([np.sin(w * u) + 2 * np.sin(2 * w * u), np.cos(w * u) - 2 * np.cos(2 * w * u),
                         -np.sin(3 * w * u)], -1)

    def tangent(u):  # its xy part never vanishes (squared length 17 + 8 cos 3wu): z serves as up
        return np.stack([np.cos(w * u) + 4 * np.cos(2 * w * u), -np.sin(w * u) + 4 * np.sin(2 * w * u),
                         -3 * np.cos(3 * w * u)], -1)

    mesh = _periodic_grid(_tube(centre, tangent, 0.45), sections, ring)
    mesh.fix_normals()
    return mesh


def chair() -> trimesh.Trimesh:
    """Six boxes (seat, back, four legs) that pass into one another, each subdivided 3 times:
    sharp edges, flat faces, six parts, as a game asset is built. No corner of one box lies
    on another's surface (that would weld the parts into a non-manifold one)."""
    boxes = [([2, 2, 0.2], [0, 0, 1]), ([1.8, 0.2, 2], [0, 0.8, 2.05])]
    boxes += [([0.2, 0.2, 1], [x, y, 0.45]) for x in (-0.83, 0.83) for y in (-0.83, 0.83)]
    mesh = trimesh.util.concatenate([trimesh.creation.box(e, trimesh.transformations.translation_matrix(t))
                                     for e, t in boxes])
    for _ in range(3):
        mesh = mesh.subdivide()
    return mesh


def mug() -> trimesh.Trimesh:
    """A thick-walled cup (a revolved profile: genus 0, sharp rims) and a handle (an open
    tube whose ends pass through the wall, as in many game assets): two parts, mostly
    developable."""
    profile = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 2.0], [0.9, 2.0], [0.9, 0.1], [0.0, 0.1]])
    cup = trimesh.creation.revolve(profile, sections=96).subdivide_to_size(0.2)

    def centre(u):  # an arc of radius 0.6 in the xz plane, its ends inside the wall (x < 0.95)
        a = 1.1 * np.pi * (u - 0.5)
        return np.stack([1.0 + 0.6 * np.cos(a), np.zeros_like(u), 1.0 + 0.6 * np.sin(a)], -1)

    def tangent(u):  # in the xz plane: y serves as up
        a = 1.1 * np.pi * (u - 0.5)
        return np.stack([-np.sin(a), np.zeros_like(u), np.cos(a)], -1)

    handle = _periodic_grid(_tube(centre, tangent, 0.1, up=(0.0, 1.0, 0.0)), 60, 16, closed_u=False)
    return trimesh.util.concatenate([cup, handle])


def saddle_annulus(rings: int = 40, sections: int = 160) -> trimesh.Trimesh:
    """An annulus (radii 0.5 to 1.5) on the saddle z = 0.3 (x^2 - y^2): open, two border
    loops, negative curvature."""
    def surface(u, v):
        r, a = 0.5 + u, 2 * np.pi * v
        x, y = r * np.cos(a), r * np.sin(a)
        return np.stack([x, y, 0.3 * (x * x - y * y)], -1)
    return _periodic_grid(surface, rings, sections, closed_u=False)


def starfish(subdivisions: int = 5) -> trimesh.Trimesh:
    """A flattened sphere with five long arms (radius up to 2.6 in the plane): limbs that
    taper to their tips. Genus 0."""
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions)
    v = np.array(mesh.vertices)
    arm = np.maximum(0.0, np.cos(5 * np.arctan2(v[:, 1], v[:, 0]))) ** 6 * (1 - np.abs(v[:, 2])) ** 2
    v[:, :2] *= 1 + 1.6 * arm[:, None]
    v[:, 2] *= 0.5
    return trimesh.Trimesh(v, mesh.faces, process=False)


SHAPES = {"sphere": sphere, "torus": torus, "genus2": genus2, "two_spheres": two_spheres, "sheet": sheet}
#: shapes that are hard for a 3-chart fit (issue 18): handles (genus 3, 4, 6), fine relief, thin limbs, many parts
HARD_SHAPES = {"genus4": genus4, "pretzel3": functools.partial(pretzel, 3), "plate6": functools.partial(plate, (2, 3)),
               "bumpy": bumpy, "limbs": limbs, "assembly": assembly}
#: shapes no rule of the unwrap was tuned on (benchmarks/unwrap_vs_xatlas.py --unseen): a knotted
#: tube, boxes with sharp edges, a cup and handle, a saddle annulus, tapering arms
UNSEEN_SHAPES = {"trefoil": trefoil, "chair": chair, "mug": mug, "saddle_annulus": saddle_annulus,
                 "starfish": starfish}


def shape_file(name: str, folder: str | Path) -> Path:
    """``folder/<name>.ply`` holding the built-in shape ``name``, written on first use
    (benchmarks feed shapes to commands that read files)."""
    path = Path(folder) / f"{name}.ply"
    if not path.is_file():
        path.parent.mkdir(parents=True, exist_ok=True)
        make(name).export(path)
    return path


def make(name: str) -> trimesh.Trimesh:
    """Build a shape by name (one of ``SHAPES``, ``HARD_SHAPES`` or ``UNSEEN_SHAPES``)."""
    makers = {**SHAPES, **HARD_SHAPES, **UNSEEN_SHAPES}
    if name not in makers:
        raise ValueError(f"unknown built-in shape {name!r}; choose from {', '.join(makers)}")
    return makers[name]()
