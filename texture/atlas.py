"""Charts -> one packed UV atlas: trim overlaps, cut clean borders, split islands, pack.

``build_atlas(charts)`` chains :mod:`texture.trim` (one layer of surface, iso-line
borders) and :mod:`texture.pack` (xatlas packer, one texel density for all charts: every
island keeps its chart-local UV up to a rigid motion and one shared scale, because the
distortion loss shares one scale across charts). The result is a :class:`UVMesh` in the
input frame with UVs in [0,1]^2, plus the measurements the issue asks for.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .charts import ChartGrids
from mna.pointmetrics import POINTS, chamfer_fscore
from .geometry import sample_surface
from .islands import uv_islands
from .orient import Reference, orient_pieces
from .pack import Packing, pack_islands
from .trim import Piece, TrimConfig, trim_charts
from .uvmesh import Normalization, UVMesh, make_uv_mesh


@dataclass
class AtlasConfig:
    """Options of :func:`build_atlas`."""

    resolution: int = 2048
    """Texture size (texels) the islands are packed for."""
    padding: int = 8
    """Gutter around each island, in texels at ``resolution``."""
    trim: TrimConfig = field(default_factory=TrimConfig)
    orient: bool = True
    """With a reference surface, reorient inside-out parts of charts (:mod:`texture.orient`)."""
    seed: int = 0
    """Seed of the surface samples used for the coverage check."""


@dataclass
class Atlas:
    """A packed atlas.

    Attributes:
        mesh: UV mesh in the input frame, UVs in [0,1]^2 (v up).
        chart: (F,) chart id of each face.
        island: (F,) island id of each face (islands are numbered chart by chart).
        normalization: input frame -> unit ball (from charts.npz).
        packing: packer result (scale, utilisation, ...).
        stats: JSON-friendly measurements (coverage, doubly covered area, islands, timings).
    """

    mesh: UVMesh
    chart: np.ndarray
    island: np.ndarray
    normalization: Normalization
    packing: Packing
    stats: dict

    @property
    def mesh_unit(self) -> UVMesh:
        return self.mesh.transformed(self.normalization)


def _merge(pieces: list[Piece]):
    """Concatenate pieces -> (xyz, chart-local uv, faces, chart per face, island per face)."""
    xyz, uv, faces, chart, island = [], [], [], [], []
    v_off = i_off = 0
    for p in pieces:
        if len(p.faces) == 0:
            continue
        isl = uv_islands(p.faces, p.uv)
        xyz.append(p.xyz)
        uv.append(p.uv)
        faces.append(p.faces + v_off)
        chart.append(np.full(len(p.faces), p.chart))
        island.append(isl + i_off)
        v_off += len(p.xyz)
        i_off += int(isl.max()) + 1
    if not faces:
        raise ValueError("no chart has any in-domain surface left: nothing to texture")
    return tuple(np.concatenate(a) for a in (xyz, uv, faces, chart, island))


def coverage_stats(charts: ChartGrids, pieces: list[Piece], reference: np.ndarray | None, seed: int) -> dict:
    """F-score of the run's kept mesh and of the trimmed atlas against ``reference`` (unit frame)."""
    xyz, _, faces, _, _ = _merge(pieces)
    trimmed_pts, _ = sample_surface(xyz, faces, POINTS, seed)
    kept_pts = ref = None
    if charts.kept_vertices is not None and len(charts.kept_faces):
        kept = charts.normalization.apply(charts.kept_vertices)
        kept_pts, _ = sample_surface(kept, charts.kept_faces, POINTS, seed + 1)
        if reference is None:  # an independent sample, so "before" is not compared with itself
            ref, _ = sample_surface(kept, charts.kept_faces, POINTS, seed + 2)
    if reference is not None:
        ref = reference
    out = {"coverage_reference": "input" if reference is not None else "kept_mesh"}
    if ref is None:
        return out
    after = chamfer_fscore(trimmed_pts, ref)
    out.update(fscore_trimmed=after.fscore, chamfer_trimmed=after.chamfer)
    if kept_pts is not None:
        before = chamfer_fscore(kept_pts, ref)
        out.update(fscore_kept=before.fscore, chamfer_kept=before.chamfer, fscore_drop=before.fscore - after.fscore)
    return out


def build_atlas(charts: ChartGrids, config: AtlasConfig | None = None, reference_points: np.ndarray | None = None,
                reference: Reference | None = None) -> Atlas:
    """Trim, orient, cut, split and pack ``charts``.

    ``reference_points`` (unit frame) for the coverage check; ``reference`` (the input mesh
    with normals, unit frame) to orient every island outward.
    """
    cfg = config or AtlasConfig()
    t0 = time.perf_counter()
    trimmed = trim_charts(charts, cfg.trim)
    pieces, orient_stats = trimmed.pieces, {}
    if reference is not None and cfg.orient:
        total = sum(float(p.area().sum()) for p in pieces)
        pieces, orient_stats = orient_pieces(pieces, reference, cfg.trim.min_island_fraction * total)
    t1 = time.perf_counter()
    xyz, uv_local, faces, chart, island = _merge(pieces)
    packing = pack_islands(uv_local, faces, island, resolution=cfg.resolution, padding=cfg.padding)
    t2 = time.perf_counter()
    mesh = make_uv_mesh(charts.normalization.invert(xyz), faces, packing.uv, name="atlas")
    stats = {
        "charts": int(charts.n_charts),
        "charts_used": int(len(np.unique(chart))),
        "islands": int(island.max()) + 1,
        "faces": int(len(faces)),
        **trimmed.stats,
        **orient_stats,
        **coverage_stats(charts, pieces, reference_points, cfg.seed),
        "utilization": packing.utilization,
        "packer": packing.packer,
        "uv_scale": packing.scale,
        "texels_per_chart_unit": packing.texels_per_unit,
        "resolution": packing.resolution,
        "padding": packing.padding,
        "timings": {"trim": t1 - t0, "pack": t2 - t1},
    }
    return Atlas(mesh, chart, island, charts.normalization, packing, stats)
