"""Synthetic datasets in exactly the real on-disk layouts, generated at test time (nothing committed).

- ``meshes``: ROOT/<name>.ply + train.lst / val.lst / test.lst
- ``shapenet`` (Occupancy Networks preprocessing): ROOT/metadata.yaml, ROOT/<synset>/{train,val,test}.lst,
  ROOT/<synset>/<object>/pointcloud.npz ('points' float16 (100000, 3), 'normals', 'loc', 'scale'),
  ROOT/<synset>/<object>/img_choy2016/000.jpg..023.jpg (137 x 137) + cameras.npz ('world_mat_i', 'camera_mat_i')
- ``cloth3d`` (CLOTH3D++ preprocessed by the paper's script): ROOT/<class>/{train,val,test}.lst,
  ROOT/<class>/<class>-<stage>-<seq>/pointcloud.npz ('points' (100000, 3) float32, 'normals') + mesh.obj
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh

from mna import shapes, train_config

torch.set_num_threads(1)

SYNSET = "02691156"
N_POINTS = 100_000
N_VIEWS = 24


def tiny_shapes() -> dict[str, trimesh.Trimesh]:
    """Four distinct small closed surfaces, each in its own frame (not unit-ball normalised)."""
    ellipsoid = shapes.sphere(subdivisions=2)
    ellipsoid.apply_scale([1.6, 0.8, 0.6])
    box = trimesh.creation.box(extents=[1.2, 0.6, 0.9])
    box = box.subdivide().subdivide()
    torus = shapes.torus(sections=32, ring=16)
    torus.apply_translation([3.0, -1.0, 0.5])
    sphere = shapes.sphere(radius=2.5, subdivisions=2)
    return {"ellipsoid": ellipsoid, "box": box, "torus": torus, "sphere": sphere}


def write_meshes_layout(root: Path, splits=None) -> Path:
    root.mkdir(parents=True, exist_ok=True)
    names = []
    for name, mesh in tiny_shapes().items():
        mesh.export(root / f"{name}.ply")
        names.append(name)
    splits = splits or {"train": names, "val": names[:2], "test": names[2:]}
    for split, members in splits.items():
        (root / f"{split}.lst").write_text("\n".join(members) + "\n")
    return root


def _pointcloud(mesh: trimesh.Trimesh, seed: int, dtype) -> dict:
    pts, face = trimesh.sample.sample_surface(mesh, N_POINTS, seed=seed)
    normals = mesh.face_normals[face]
    return {"points": pts.astype(dtype), "normals": normals.astype(dtype)}


def _cameras(views: int) -> dict:
    cams = {}
    for i in range(views):
        a = 2 * np.pi * i / views
        R = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
        cams[f"world_mat_{i}"] = np.concatenate([R, [[0], [0], [1.2]]], 1)
        cams[f"camera_mat_{i}"] = np.array([[149.8, 0, 68.5], [0, 149.8, 68.5], [0, 0, 1.0]])
    return cams


def write_shapenet_layout(root: Path, images: bool = True) -> Path:
    from PIL import Image

    cdir = root / SYNSET
    cdir.mkdir(parents=True, exist_ok=True)
    (root / "metadata.yaml").write_text(f"{SYNSET}:\n  id: '{SYNSET}'\n  name: airplane\n")
    names = []
    for k, (name, mesh) in enumerate(tiny_shapes().items()):
        obj = f"{k:02d}a1b2c3d4e5f60718293a4b5c6d7e8f"  # ShapeNet ids are 32 hex digits
        names.append(obj)
        odir = cdir / obj
        odir.mkdir()
        # Occupancy Networks: shapes in a unit cube, float16 points, with the applied loc/scale
        bounds = mesh.bounds
        loc, scale = bounds.mean(0), (bounds[1] - bounds[0]).max()
        unit = mesh.copy()
        unit.apply_translation(-loc)
        unit.apply_scale(1 / scale)
        pc = _pointcloud(unit, k, np.float16)
        np.savez(odir / "pointcloud.npz", **pc, loc=loc.astype(np.float32), scale=np.float32(scale))
        if images:
            img_dir = odir / "img_choy2016"
            img_dir.mkdir()
            rng = np.random.default_rng(k)
            for v in range(N_VIEWS):
                pix = (rng.random((137, 137, 3)) * 255).astype(np.uint8)
                Image.fromarray(pix).save(img_dir / f"{v:03d}.jpg")
            np.savez(img_dir / "cameras.npz", **_cameras(N_VIEWS))
    for split, members in {"train": names, "val": names[:2], "test": names[2:]}.items():
        (cdir / f"{split}.lst").write_text("\n".join(members))  # ONet files have no trailing newline
    return root


def write_cloth3d_layout(root: Path) -> Path:
    names = {"train": [], "val": [], "test": []}
    cls = "tshirt"
    cdir = root / cls
    stages = ["train", "train", "val", "test"]
    for k, (name, mesh) in enumerate(tiny_shapes().items()):
        sample = f"{cls}-{stages[k]}-{k:05d}"
        names[stages[k]].append(sample)
        sdir = cdir / sample
        sdir.mkdir(parents=True)
        mesh.export(sdir / "mesh.obj")
        np.savez(sdir / "pointcloud.npz", **_pointcloud(mesh, k, np.float32))
    for stage, members in names.items():
        (cdir / f"{stage}.lst").write_text("\n".join(members))
    return root


@pytest.fixture(scope="session")
def meshes_root(tmp_path_factory) -> Path:
    return write_meshes_layout(tmp_path_factory.mktemp("meshes_ds"))


@pytest.fixture(scope="session")
def shapenet_root(tmp_path_factory) -> Path:
    return write_shapenet_layout(tmp_path_factory.mktemp("shapenet_ds"))


@pytest.fixture(scope="session")
def cloth3d_root(tmp_path_factory) -> Path:
    return write_cloth3d_layout(tmp_path_factory.mktemp("cloth3d_ds"))


def tiny_config(root: Path, out: Path, **overrides) -> train_config.TrainConfig:
    """The ``tiny`` preset on a synthetic folder; ``overrides`` are top-level fields."""
    cfg = train_config.tiny()
    cfg.data.root, cfg.out = str(root), str(out)
    cfg.device = "cpu"
    for key, value in overrides.items():
        setattr(cfg, key, value)
    return cfg.validate()


@pytest.fixture
def free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def subprocess_env() -> dict:
    env = dict(os.environ)
    env.update(OMP_NUM_THREADS="1", OMP_WAIT_POLICY="PASSIVE", MASTER_ADDR="127.0.0.1")
    env["PYTHONPATH"] = str(Path(__file__).resolve().parents[2]) + os.pathsep + env.get("PYTHONPATH", "")
    return env
