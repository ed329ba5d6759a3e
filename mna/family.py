"""A procedural family of shapes that differ in topology, for training and held-out tests.

The paper's central claim is that charts with learned domains reconstruct shapes of any
topology feed-forward, where AtlasNet's fixed squares cannot. ShapeNet is not on this
machine, so the benchmark makes a family whose members differ exactly in what the claim is
about: the number of components (1-3), genus (0-2) and open versus closed, each with random
proportions so no two members are alike. Members are written in the ``meshes`` dataset
layout (:mod:`mna.datasets`): ``ROOT/<name>.ply`` and ``train.lst`` / ``val.lst`` /
``test.lst``; the name starts with the topology, so per-topology scores can be read back.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from mna import shapes
from mnacore.atomic import write_text

#: topology -> (components, genus, closed); the benchmark reports a score per topology.
TOPOLOGIES = {
    "sphere": (1, 0, True),
    "torus": (1, 1, True),
    "genus2": (1, 2, True),
    "pair": (2, 0, True),
    "triple": (3, 0, True),
    "tube": (1, 0, False),
}


def _ellipsoid(rng: np.random.Generator, scale: float) -> trimesh.Trimesh:
    mesh = shapes.sphere(subdivisions=3)
    mesh.apply_scale(scale * rng.uniform(0.6, 1.0, 3))
    return mesh


def _spread(parts: list[trimesh.Trimesh], rng: np.random.Generator) -> trimesh.Trimesh:
    """Place parts along a random direction, gaps of 10-40 % of a part's size: disjoint."""
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    offset = 0.0
    placed = []
    for part in parts:
        half = float(np.max(part.extents)) / 2
        offset += half
        placed.append(part.copy())
        placed[-1].apply_translation(axis * offset)
        offset += half * (1 + rng.uniform(0.2, 0.8))
    return trimesh.util.concatenate(placed)


def member(topology: str, rng: np.random.Generator) -> trimesh.Trimesh:
    """One random member of ``topology`` (a key of :data:`TOPOLOGIES`)."""
    if topology == "sphere":
        mesh = _ellipsoid(rng, 1.0)
    elif topology == "torus":
        mesh = shapes.torus(major=1.0, minor=rng.uniform(0.2, 0.45), sections=64, ring=32)
        mesh.apply_scale([1.0, rng.uniform(0.6, 1.0), rng.uniform(0.7, 1.3)])
    elif topology == "genus2":
        mesh = shapes.genus2(resolution=56)
        mesh.apply_scale([1.0, rng.uniform(0.6, 1.0), rng.uniform(0.7, 1.3)])
    elif topology == "pair":
        mesh = _spread([_ellipsoid(rng, rng.uniform(0.5, 1.0)) for _ in range(2)], rng)
    elif topology == "triple":
        mesh = _spread([_ellipsoid(rng, rng.uniform(0.4, 0.8)) for _ in range(3)], rng)
    elif topology == "tube":
        # an open cylinder (no caps): a closed-surface prior puts spurious lids on it
        mesh = trimesh.creation.cylinder(radius=rng.uniform(0.3, 0.6), height=rng.uniform(1.0, 2.0), sections=48)
        keep = np.abs(mesh.face_normals[:, 2]) < 0.5
        mesh = trimesh.Trimesh(mesh.vertices, mesh.faces[keep], process=True)
        mesh = mesh.subdivide().subdivide()
    else:
        raise ValueError(f"unknown topology {topology!r}; choose from {', '.join(TOPOLOGIES)}")
    rot = trimesh.transformations.random_rotation_matrix(rng.random(3))
    mesh.apply_transform(rot)
    return mesh


def write_family(root: str | Path, per_topology: int, test_per_topology: int, seed: int = 0,
                 topologies: tuple[str, ...] = tuple(TOPOLOGIES)) -> dict[str, list[str]]:
    """Write ``per_topology`` members of each topology into ``root``; the last
    ``test_per_topology`` of each are held out (``test.lst``, also ``val.lst``).

    Deterministic in ``seed``. Returns the split lists.
    """
    if not 0 < test_per_topology < per_topology:
        raise ValueError("need 0 < test_per_topology < per_topology")
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    splits: dict[str, list[str]] = {"train": [], "test": []}
    for t_index, topology in enumerate(topologies):
        for i in range(per_topology):
            name = f"{topology}_{i:03d}"
            rng = np.random.default_rng([seed, t_index, i])
            path = root / f"{name}.ply"
            if not path.is_file():
                member(topology, rng).export(path)
            splits["test" if i >= per_topology - test_per_topology else "train"].append(name)
    for split, names in (("train", splits["train"]), ("val", splits["test"]), ("test", splits["test"])):
        write_text(root / f"{split}.lst", "\n".join(names) + "\n")
    return splits


def topology_of(name: str) -> str:
    """The topology a member's name starts with (``torus_003`` -> ``torus``)."""
    head = Path(name).stem.rsplit("_", 1)[0]
    if head not in TOPOLOGIES:
        raise ValueError(f"{name!r} is not a member of the procedural family")
    return head
