"""Run-level entry points: ``export_run`` (charts -> textured asset) and ``uv_mesh_file`` (xatlas).

These are what ``mna export`` / ``mna uv`` (and ``mna demo``) call. ``compare_run`` lives
in :mod:`texture.compare`.
"""
from __future__ import annotations

import dataclasses
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mnacore.atomic import write_json
from mnacore.charts import load_charts
from mnacore.errors import InputError
from mnacore.frame import Normalization, unit_ball_normalization
from mnacore.uvmesh import UVMesh, load_uv_mesh

from .atlas import AtlasConfig, build_atlas
from .atlas_stats import AtlasStats
from .export import export_textured
from .export_config import TEXTURES, ExportConfig
from .harness import measure
from .orient import Reference
from .relax import RelaxConfig
from .textures import (
    MIN_TEXELS_PER_SQUARE,
    SQUARE_SIZE,
    bake,
    check_size,
    checker_image,
    source_colors,
    squares_per_uv_unit,
    uv_grid_image,
    uv_length_scale,
)
from .xatlas_uv import XatlasOptions, check_mesh, unwrap


def load_input(run: str | os.PathLike):
    """The run's input from ``RUN/config.yaml`` key ``input``: ``(trimesh | None, points | None)``, input frame.

    A mesh file gives a trimesh (with its colours/texture); a point cloud gives points;
    a missing or unreadable input gives ``(None, None)`` (the input is optional here).
    """
    import trimesh
    import yaml

    cfg_path = Path(run) / "config.yaml"
    if not cfg_path.is_file():
        return None, None
    try:
        cfg = yaml.safe_load(cfg_path.read_text()) or {}
    except yaml.YAMLError as exc:
        raise InputError(f"cannot parse {cfg_path}: {exc}") from exc
    path = cfg.get("input") if isinstance(cfg, dict) else None
    if not path:
        return None, None
    # `mna fit` stores the path as given: relative to where it ran (usually the run's parent)
    candidates = [Path(path), Path(run) / path, Path(run).parent / path]
    path = next((c for c in candidates if c.is_file()), None)
    if path is None:
        return None, None
    try:
        loaded = trimesh.load(path, process=False)
    except Exception:  # not a format trimesh reads (e.g. .xyz/.npy point clouds)
        return None, _read_points(Path(path))
    if isinstance(loaded, trimesh.Scene):
        loaded = loaded.to_mesh() if hasattr(loaded, "to_mesh") else loaded.dump(concatenate=True)
    if isinstance(loaded, trimesh.Trimesh) and len(loaded.faces):
        return loaded, None
    if isinstance(loaded, trimesh.PointCloud):
        return None, np.asarray(loaded.vertices, np.float64)
    return None, None


def _read_points(path: Path) -> np.ndarray | None:
    try:
        if path.suffix == ".npy":
            pts = np.load(path)
        elif path.suffix == ".npz":
            with np.load(path) as z:
                pts = z[z.files[0]]
        else:
            pts = np.loadtxt(path)
    except (OSError, ValueError):
        return None
    pts = np.asarray(pts, np.float64)
    return pts[:, :3] if pts.ndim == 2 and pts.shape[1] >= 3 else None


def reference_points(mesh, points, norm: Normalization, count: int = 25000, seed: int = 0) -> np.ndarray | None:
    """Unit-frame samples of the input surface (mesh: area-uniform; cloud: as given)."""
    from .geometry import sample_surface

    if mesh is not None:
        vertices = np.asarray(mesh.vertices, np.float64)
        if 1e-30 <= norm.scale <= 1e30:
            pts, _ = sample_surface(vertices, np.asarray(mesh.faces), count, seed)
            return norm.apply(pts)
        # triangle areas of a 1e200 (or 1e-200) mesh overflow (underflow) in its own units;
        # area-uniform sampling is scale-invariant, so sample it in the unit-ball frame
        pts, _ = sample_surface(norm.apply(vertices), np.asarray(mesh.faces), count, seed)
        return pts
    if points is not None:
        return norm.apply(points)
    return None


def square_size_for(mesh_unit: UVMesh, size: int, requested: float | None = None) -> float:
    """The checker square side (unit-ball frame): ``requested``, or by default ``SQUARE_SIZE``
    grown to the smallest square the texture can draw (``MIN_TEXELS_PER_SQUARE`` texels), so a
    small texture still gets a true checker, just a coarser one. A requested size that the
    texture cannot draw is refused by :func:`texture.textures.check_frequency`."""
    if requested is not None:
        return float(requested)
    s = uv_length_scale(mesh_unit.vertices, mesh_unit.faces, mesh_unit.uv)
    return max(SQUARE_SIZE, s * MIN_TEXELS_PER_SQUARE / size * (1 + 1e-9))


def make_texture(kind: str, mesh_unit: UVMesh, size: int, padding: int, source=None,
                 square_size: float | None = None) -> np.ndarray:
    """``checker`` / ``uvgrid`` (3D-size-matched, see textures) or ``bake`` (needs ``source``, unit frame).

    ``square_size`` is the checker square's side in the unit-ball frame (``None``: see
    :func:`square_size_for`).
    """
    if kind not in TEXTURES:
        raise InputError(f"unknown texture {kind!r}; choose from {', '.join(TEXTURES)}")
    if kind in ("checker", "uvgrid"):
        freq = squares_per_uv_unit(mesh_unit.vertices, mesh_unit.faces, mesh_unit.uv,
                                   square_size_for(mesh_unit, size, square_size))
        return checker_image(freq, size) if kind == "checker" else uv_grid_image(freq, size)
    if source is None:
        raise InputError("--texture bake needs the run's input mesh (RUN/config.yaml 'input'), which is not a readable mesh")
    return bake(mesh_unit, source, size, padding)


@dataclass
class ExportReport:
    """What :func:`export_run` did: ``atlas.json``'s content, typed.

    Attributes:
        config: the resolved :class:`ExportConfig` (every option of every stage), so
            ``mna export RUN --config atlas.json`` reproduces the export.
        checker_square_size: the checker square drawn (unit-ball frame).
        atlas: the atlas stages' measurements.
        uv_metrics: the harness summary of the exported mesh.
        timings: seconds per step (``atlas_*`` per atlas stage, ``export_total``).
        files: written paths.
    """

    texture: str
    size: int
    padding: int
    relax: int
    config: dict
    checker_square_size: float
    atlas: AtlasStats
    uv_metrics: dict
    timings: dict
    files: dict

    def to_json(self) -> dict:
        """The ``atlas.json`` content."""
        return {"texture": self.texture, "size": self.size, "padding": self.padding, "relax": self.relax,
                "config": self.config, "checker_square_size": self.checker_square_size,
                "atlas": self.atlas.to_json(timings=False), "uv_metrics": self.uv_metrics,
                "timings": self.timings, "files": self.files}


def export_run(run: str | os.PathLike, texture: str = "checker", size: int | str = 2048, padding: int = 8,
               square_size: float | None = None, max_islands: int = AtlasConfig.max_islands,
               relax: int = RelaxConfig.iterations, config: ExportConfig | None = None) -> ExportReport:
    """Charts of ``RUN/charts.npz`` -> ``RUN/mesh.obj``, ``mesh.mtl``, ``mesh_texture.png``, ``mesh.glb``, ``atlas.json``.

    The options are ``mna export``'s, or a whole :class:`ExportConfig` (``config``, e.g. the
    one an earlier ``atlas.json`` saved), validated once here. Returns what ``atlas.json``
    holds (:class:`ExportReport`): atlas stats (trim, coverage, packing), harness summary,
    timings (seconds), written paths, and the config.
    """
    run = Path(run)
    cfg = (config.validate() if config is not None else
           ExportConfig.from_options(texture, size, padding, square_size, max_islands, relax))
    if not run.is_dir():
        raise InputError(f"run folder not found: {run}")
    charts = load_charts(run / "charts.npz")
    t0 = time.perf_counter()
    mesh_in, points_in = load_input(run)
    if cfg.texture == "bake":
        if mesh_in is None:
            raise InputError("--texture bake needs the run's input mesh (RUN/config.yaml 'input'), "
                             "which is not a readable mesh")
        source_colors(mesh_in)  # fail before the slow part when there is nothing to bake
    norm = charts.normalization
    ref = reference_points(mesh_in, points_in, norm)
    surface = Reference.from_trimesh(mesh_in, norm) if mesh_in is not None else None
    atlas = build_atlas(charts, cfg.atlas, ref, surface)
    t1 = time.perf_counter()
    source = None
    if cfg.texture == "bake":
        source = mesh_in.copy()
        source.vertices = norm.apply(mesh_in.vertices)
    square = square_size_for(atlas.mesh_unit, cfg.size, cfg.square_size)  # drawn, and recorded in atlas.json
    image = make_texture(cfg.texture, atlas.mesh_unit, cfg.size, cfg.padding, source, square)
    t2 = time.perf_counter()
    paths = export_textured(run, atlas.mesh, image)
    t3 = time.perf_counter()
    metrics = measure(atlas.mesh, reference=mesh_in, normalization=norm,
                      reference_is_closed=mesh_in is None)
    timings = {"atlas": t1 - t0, **{f"atlas_{k}": v for k, v in atlas.report.timings.items()},
               "texture": t2 - t1, "write": t3 - t2, "harness": time.perf_counter() - t3}
    timings["export_total"] = t3 - t0
    report = ExportReport(cfg.texture, cfg.size, cfg.padding, cfg.atlas.relax.iterations, dataclasses.asdict(cfg),
                          square, atlas.report, metrics.summary, timings, paths)
    write_json(run / "atlas.json", report.to_json())
    return report


def uv_mesh_file(mesh_path: str | os.PathLike, out: str | os.PathLike, options: XatlasOptions | None = None,
                 texture: str = "checker", size: int | str | None = None, square_size: float | None = None,
                 prepare_out=None) -> dict:
    """``mna uv``: xatlas on any mesh file -> ``OUT/mesh.obj/.mtl``, ``mesh_texture.png``, ``mesh.glb``, ``metrics.json``.

    ``prepare_out()``: called once the input and options are valid, before anything is
    written (the command's run-folder rule: refuse or empty ``OUT``)."""
    opts = (options or XatlasOptions()).validate()
    size = check_size(size if size is not None else (opts.resolution or 2048))
    if texture not in TEXTURES:
        raise InputError(f"unknown texture {texture!r}; choose from {', '.join(TEXTURES)}")
    _, mesh = load_uv_mesh(mesh_path, require_uv=False)
    check_mesh(mesh.vertices, mesh.faces, Path(mesh_path).name)
    if texture == "bake":
        source_colors(mesh)
    if prepare_out is not None:
        prepare_out()
    result = unwrap(mesh.vertices, mesh.faces, opts, check=False)
    norm = unit_ball_normalization(np.asarray(mesh.vertices)[np.unique(mesh.faces)])
    result_norm = result.mesh.transformed(norm)
    source = None
    if texture == "bake":
        source = mesh.copy()
        source.vertices = norm.apply(mesh.vertices)
    image = make_texture(texture, result_norm, size, opts.padding, source, square_size)
    paths = export_textured(out, result.mesh, image)
    metrics = measure(result.mesh, reference=mesh, normalization=norm)
    out_json = {"method": "xatlas", "input": str(mesh_path), "options": result.options, **result.record(),
                "uv_metrics": metrics.summary, "files": paths}
    write_json(Path(out) / "metrics.json", out_json)
    return out_json
