"""Datasets of shapes for the conditional atlas, in three on-disk layouts.

``meshes``  (any mesh / point-cloud files ``mna fit`` reads)::

    ROOT/<name>.obj|.ply|.off|...      ROOT/train.lst, val.lst, test.lst (one name a line,
                                       with or without the extension; subfolders allowed)

``shapenet`` (Occupancy Networks' preprocessed ShapeNet, as the paper used)::

    ROOT/metadata.yaml (optional)      ROOT/<synset>/{train,val,test}.lst
    ROOT/<synset>/<object>/pointcloud.npz         'points' (100000, 3) float16, 'normals', 'loc', 'scale'
    ROOT/<synset>/<object>/img_choy2016/000.jpg .. 023.jpg, cameras.npz ('world_mat_i', 'camera_mat_i')

``cloth3d`` (CLOTH3D++ preprocessed by the paper's script)::

    ROOT/<class>/{train,val,test}.lst  ROOT/<class>/<class>-<stage>-<seq>/pointcloud.npz
                                       ('points' (100000, 3), 'normals'), mesh.obj

An item is a dict: ``input`` (``(P_in, 3)`` points or ``(3, H, W)`` image in [0, 1]),
``target (T, 3)``, ``uv (K, N, 2)`` and ``index``. Points are in the unit-ball frame
(centre = bounding-box centre of the whole surface sample, max radius 1), input and target
alike. Every random draw is keyed by ``(seed, epoch, index)``, so an item does not depend on
the worker, rank or batch it lands in, and a resumed run sees exactly the same data.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch.utils.data import Dataset

from mna.data import MESH_EXTS, POINT_EXTS, Surface, load_surface
from mna.train_config import TrainConfig
from mnacore.errors import InputError, MnaError
from mnacore.frame import Normalization

POINTCLOUD_FILE = "pointcloud.npz"
POINTS_KEY = "points"
IMAGE_FOLDER = "img_choy2016"
CAMERAS_FILE = "cameras.npz"


@dataclass(frozen=True)
class Entry:
    """One object: its name (``class/object`` or file name) and path (file or object folder)."""

    name: str
    path: Path


def read_split(path: Path) -> list[str]:
    """Names listed in a ``.lst`` split file (blank lines ignored)."""
    try:
        return [line.strip() for line in path.read_text().splitlines() if line.strip()]
    except UnicodeDecodeError:
        raise MnaError(f"split file {path} is not text") from None


def _check_root(root: str | Path) -> Path:
    root = Path(root)
    if not root.is_dir():
        raise MnaError(f"dataset folder not found: {root}")
    if not any(root.iterdir()):
        raise MnaError(f"dataset folder is empty: {root}")
    return root


def _missing(missing: list[str], split_file: Path) -> MnaError:
    more = f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""
    return MnaError(f"split {split_file} names an object that is not in the dataset: {missing[0]}{more}")


def mesh_entries(root: str | Path, split: str) -> list[Entry]:
    """``meshes`` layout: the files named by ``ROOT/<split>.lst``."""
    root = _check_root(root)
    split_file = root / f"{split}.lst"
    if not split_file.is_file():
        raise MnaError(f"no split file {split_file} (one mesh name a line)")
    entries, missing = [], []
    files = {p.relative_to(root).as_posix(): p for p in root.rglob("*") if p.suffix.lower() in MESH_EXTS | POINT_EXTS}
    by_stem = {Path(k).with_suffix("").as_posix(): v for k, v in files.items()}
    for name in read_split(split_file):
        path = files.get(name) or by_stem.get(name)
        (entries.append(Entry(name, path)) if path is not None else missing.append(name))
    if missing:
        raise _missing(missing, split_file)
    return entries


def object_entries(root: str | Path, split: str, classes: list[str], need_images: bool = False) -> list[Entry]:
    """``shapenet`` / ``cloth3d`` layout: ``ROOT/<class>/<split>.lst`` naming object folders."""
    root = _check_root(root)
    if classes:
        for c in classes:
            if not (root / c).is_dir():
                raise MnaError(f"class folder not found: {root / c}")
        class_dirs = [root / c for c in classes]
    else:
        class_dirs = sorted(p for p in root.iterdir() if p.is_dir() and (p / f"{split}.lst").is_file())
        if not class_dirs:
            raise MnaError(f"no class folder in {root} has a {split}.lst split file (is this the dataset root?)")
    entries = []
    for cdir in class_dirs:
        split_file = cdir / f"{split}.lst"
        if not split_file.is_file():
            raise MnaError(f"no split file {split_file}")
        missing = []
        for name in read_split(split_file):
            obj = cdir / name
            ok = (obj / POINTCLOUD_FILE).is_file()
            if need_images:
                ok = ok and (obj / IMAGE_FOLDER / CAMERAS_FILE).is_file()
            (entries.append(Entry(f"{cdir.name}/{name}", obj)) if ok else missing.append(name))
        if missing:
            raise _missing(missing, split_file)
    return entries


def load_pointcloud(path: Path) -> np.ndarray:
    """``points (P, 3)`` float64 from an Occupancy-Networks style ``pointcloud.npz``."""
    try:
        with np.load(path, allow_pickle=False) as z:
            if POINTS_KEY not in z:
                raise MnaError(f"{path} has no '{POINTS_KEY}' array (has {', '.join(z.files) or 'nothing'})")
            pts = np.asarray(z[POINTS_KEY], dtype=np.float64)
    except MnaError:
        raise
    except Exception as exc:
        raise MnaError(f"cannot read {path}: {type(exc).__name__}") from None
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 16 or not np.isfinite(pts).all():
        raise MnaError(f"{path}: '{POINTS_KEY}' must be a finite (P >= 16, 3) array, got shape {pts.shape}")
    return pts


def load_view(obj: Path, view: int, size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``image (3, size, size)`` float32 in [0, 1], ``world_mat (3, 4)``, ``camera_mat (3, 3)``."""
    from PIL import Image

    folder = obj / IMAGE_FOLDER
    path = folder / f"{view:03d}.jpg"
    try:
        with Image.open(path) as im:
            im = im.convert("RGB").resize((size, size), Image.BILINEAR)
            image = np.asarray(im, dtype=np.float32).transpose(2, 0, 1) / 255.0
        with np.load(folder / CAMERAS_FILE, allow_pickle=False) as cams:
            world, cam = cams[f"world_mat_{view}"], cams[f"camera_mat_{view}"]
    except (OSError, KeyError) as exc:
        raise MnaError(f"cannot read view {view} of {obj}: {type(exc).__name__}: {str(exc).splitlines()[0]}") from None
    return image, np.asarray(world, np.float32), np.asarray(cam, np.float32)


def subset(points: np.ndarray, n_input: int, n_target: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Input and target from one random subset of ``points``: the smaller is a prefix of the larger."""
    m = max(n_input, n_target)
    idx = rng.choice(len(points), size=m, replace=m > len(points))
    return points[idx[:n_input]], points[idx[:n_target]]


class ShapeDataset(Dataset):
    """Items of one split (see the module docstring); ``set_epoch`` re-keys the random draws."""

    def __init__(self, cfg: TrainConfig, split: str, root: str | None = None):
        d = cfg.data
        self.cfg, self.split = cfg, split
        self.root = Path(root or d.root)
        self.image = d.input == "image"
        if d.layout == "meshes":
            self.entries = mesh_entries(self.root, split)
        else:
            self.entries = object_entries(self.root, split, list(d.classes), need_images=self.image)
        if not self.entries:
            raise MnaError(f"split {split!r} of {self.root} is empty")
        self.views = d.views if self.image else 1
        self.epoch = 0
        self._surfaces: dict[int, Surface] = {}
        self._clouds: dict[int, tuple[np.ndarray, Normalization]] = {}

    def __len__(self) -> int:
        return len(self.entries) * self.views

    def set_epoch(self, epoch: int) -> None:
        self.epoch = int(epoch)

    def object_of(self, index: int) -> Entry:
        return self.entries[index // self.views]

    def cloud(self, obj: int) -> tuple[np.ndarray, Normalization]:
        """The object's full point sample in the unit-ball frame and its normalisation."""
        if obj not in self._clouds:
            pts = load_pointcloud(self.entries[obj].path / POINTCLOUD_FILE)
            norm = Normalization.fit(pts)
            self._clouds[obj] = (norm.apply(pts), norm)
        return self._clouds[obj]

    def surface(self, obj: int) -> Surface:
        if obj not in self._surfaces:
            try:
                self._surfaces[obj] = load_surface(self.entries[obj].path)
            except InputError as exc:
                raise MnaError(f"dataset item {self.entries[obj].name}: {exc}") from None
        return self._surfaces[obj]

    def points(self, index: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """``(input (P_in, 3), target (T, 3))`` float64, unit-ball frame."""
        d, obj = self.cfg.data, index // self.views
        if self.cfg.data.layout != "meshes":
            return subset(self.cloud(obj)[0], d.input_points, d.target_points, rng)
        surf = self.surface(obj)
        if d.mesh_cache_points and surf.is_mesh:
            if obj not in self._clouds:
                pts = surf.sample(d.mesh_cache_points, np.random.default_rng([self.cfg.seed, obj]))
                self._clouds[obj] = (pts, surf.normalization)
            return subset(self._clouds[obj][0], d.input_points, d.target_points, rng)
        pts = surf.sample(max(d.input_points, d.target_points), rng)
        return pts[: d.input_points], pts[: d.target_points]

    def normalization(self, index: int) -> Normalization:
        obj = index // self.views
        return self.surface(obj).normalization if self.cfg.data.layout == "meshes" else self.cloud(obj)[1]

    def __getitem__(self, index: int) -> dict:
        if not 0 <= index < len(self):
            raise IndexError(index)
        rng = np.random.default_rng([self.cfg.seed, self.epoch, index])
        inp, target = self.points(index, rng)
        K = self.cfg.model.charts
        uv = rng.random((K, self.cfg.uv_samples // K, 2), dtype=np.float32) * 2.0 - 1.0
        item = {"target": torch.from_numpy(target.astype(np.float32)), "uv": torch.from_numpy(uv),
                "index": index}
        if self.image:
            image, _, _ = load_view(self.object_of(index).path, index % self.views, self.cfg.data.image_size)
            item["input"] = torch.from_numpy(image)
        else:
            item["input"] = torch.from_numpy(inp.astype(np.float32))
        return item


def collate(items: list[dict]) -> dict:
    """Stack items; ``uv`` becomes ``(K, B, N, 2)`` as :func:`mna.objective.atlas_losses` wants."""
    return {
        "input": torch.stack([it["input"] for it in items]),
        "target": torch.stack([it["target"] for it in items]),
        "uv": torch.stack([it["uv"] for it in items], dim=1),
        "index": torch.tensor([it["index"] for it in items]),
    }


def build(cfg: TrainConfig, split: str, root: str | None = None, check: bool = True) -> ShapeDataset:
    """The dataset of ``split``; ``check`` loads its first item so a malformed folder fails now."""
    ds = ShapeDataset(cfg, split, root)
    if check:
        ds[0]
    return ds
