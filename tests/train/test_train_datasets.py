"""Each dataset layout loads from its synthetic fixture: shapes, unit-ball frame, keyed randomness, bad input."""
from __future__ import annotations

import numpy as np
import pytest
import torch
from train_helpers import N_POINTS, SYNSET, tiny_config, write_meshes_layout

from mna import datasets
from mna.cli import main
from mnacore.errors import MnaError


def _unit_ball(points: np.ndarray) -> tuple[np.ndarray, float]:
    lo, hi = points.min(0), points.max(0)
    center = (lo + hi) / 2
    return center, float(np.linalg.norm(points - center, axis=1).max())


def test_meshes_layout(meshes_root, tmp_path):
    cfg = tiny_config(meshes_root, tmp_path)
    ds = datasets.build(cfg, "train")
    assert [e.name for e in ds.entries] == ["ellipsoid", "box", "torus", "sphere"] and len(ds) == 4
    item = ds[2]
    K, N = cfg.model.charts, cfg.uv_samples // cfg.model.charts
    assert item["input"].shape == (cfg.data.input_points, 3) and item["target"].shape == (cfg.data.target_points, 3)
    assert item["uv"].shape == (K, N, 2) and item["uv"].abs().max() < 1
    # the mesh's vertices define the frame: bounding-box centre at 0, max radius exactly 1
    center, radius = _unit_ball(ds.surface(2).points)
    assert np.abs(center).max() < 1e-12 and radius == pytest.approx(1.0, abs=1e-12)
    assert item["target"].norm(dim=1).max() <= 1 + 1e-5
    assert ds.normalization(2).scale > 1.0  # the torus is larger than the unit ball in its own frame


def test_shapenet_layout_points_and_images(shapenet_root, tmp_path):
    cfg = tiny_config(shapenet_root, tmp_path)
    cfg.data.layout = "shapenet"
    ds = datasets.build(cfg, "train")
    assert len(ds) == 4 and ds.entries[0].name.startswith(f"{SYNSET}/")
    pts, norm = ds.cloud(1)
    assert pts.shape == (N_POINTS, 3)
    center, radius = _unit_ball(pts)
    assert np.abs(center).max() < 1e-9 and radius == pytest.approx(1.0, abs=1e-9)
    item = ds[1]
    assert item["input"].shape == (cfg.data.input_points, 3) and item["input"].dtype == torch.float32
    # input and target come from one random subset: the smaller is a prefix of the larger
    assert torch.equal(item["input"], item["target"][: cfg.data.input_points])

    cfg.data.input, cfg.encoder.kind = "image", "resnet18"
    images = datasets.build(cfg, "val")
    assert len(images) == 2 * 24  # every rendered view is an item
    item = images[25]  # object 1, view 1
    assert item["input"].shape == (3, cfg.data.image_size, cfg.data.image_size)
    assert 0 <= float(item["input"].min()) and float(item["input"].max()) <= 1
    assert images.object_of(25).name == images.entries[1].name
    _, world, cam = datasets.load_view(images.entries[1].path, 1, 32)
    assert world.shape == (3, 4) and cam.shape == (3, 3)


def test_cloth3d_layout(cloth3d_root, tmp_path):
    cfg = tiny_config(cloth3d_root, tmp_path)
    cfg.data.layout, cfg.data.classes = "cloth3d", ["tshirt"]
    train = datasets.build(cfg, "train")
    assert [e.name for e in train.entries] == ["tshirt/tshirt-train-00000", "tshirt/tshirt-train-00001"]
    assert len(datasets.build(cfg, "test")) == 1
    pts, _ = train.cloud(0)
    assert pts.shape == (N_POINTS, 3)
    assert _unit_ball(pts)[1] == pytest.approx(1.0, abs=1e-12)
    assert train[0]["target"].shape == (cfg.data.target_points, 3)


def test_draws_are_keyed_by_seed_epoch_and_item(meshes_root, tmp_path):
    cfg = tiny_config(meshes_root, tmp_path)
    cfg.data.mesh_cache_points = 5000
    ds = datasets.build(cfg, "train")
    a = ds[1]
    ds[3]  # other items in between change nothing
    b = ds[1]
    assert torch.equal(a["target"], b["target"]) and torch.equal(a["uv"], b["uv"])
    ds.set_epoch(1)
    c = ds[1]
    assert not torch.equal(a["target"], c["target"]) and not torch.equal(a["uv"], c["uv"])
    batch = datasets.collate([ds[0], ds[1], ds[2]])
    assert batch["uv"].shape == (cfg.model.charts, 3, cfg.uv_samples // cfg.model.charts, 2)
    assert batch["target"].shape == (3, cfg.data.target_points, 3)


def _write_config(tmp_path, root, layout="meshes"):
    path = tmp_path / "c.yaml"
    path.write_text(f"preset: tiny\nout: {tmp_path / 'out'}\ndevice: cpu\ndata:\n  root: {root}\n  layout: {layout}\n")
    return path


def _bad_shapenet(tmp_path):
    from train_helpers import write_shapenet_layout

    root = write_shapenet_layout(tmp_path / "sn", images=False)
    obj = next(p for p in (root / SYNSET).iterdir() if p.is_dir())
    np.savez(obj / "pointcloud.npz", normals=np.zeros((10, 3)))
    return root


@pytest.mark.parametrize("case, message", [
    ("missing", "dataset folder not found"),
    ("empty", "dataset folder is empty"),
    ("no_split", "no split file"),
    ("missing_object", "names an object that is not in the dataset: ghost"),
    ("malformed_npz", "has no 'points' array"),
    ("malformed_mesh", "dataset item"),
])
def test_bad_dataset_is_one_line_exit_2(tmp_path, capsys, case, message):
    layout = "meshes"
    root = tmp_path / "ds"
    if case == "empty":
        root.mkdir()
    elif case == "no_split":
        write_meshes_layout(root)
        (root / "train.lst").unlink()
    elif case == "missing_object":
        write_meshes_layout(root, splits={"train": ["sphere", "ghost"]})
    elif case == "malformed_npz":
        root, layout = _bad_shapenet(tmp_path), "shapenet"
    elif case == "malformed_mesh":
        root.mkdir()
        (root / "broken.obj").write_text("this is not a mesh\n")
        (root / "train.lst").write_text("broken\n")
    assert main(["train", str(_write_config(tmp_path, root, layout)), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err, err


def test_missing_class_and_split_errors(shapenet_root, tmp_path):
    cfg = tiny_config(shapenet_root, tmp_path)
    cfg.data.layout, cfg.data.classes = "shapenet", ["99999999"]
    with pytest.raises(MnaError, match="class folder not found"):
        datasets.build(cfg, "train")
    cfg.data.classes = []
    with pytest.raises(MnaError, match="has a nosuch.lst"):
        datasets.build(cfg, "nosuch")
