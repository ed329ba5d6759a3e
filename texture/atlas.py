"""Charts -> one packed UV atlas: a straight chain of stages.

``build_atlas(charts)`` runs, each stage on the previous one's typed result:

1. trim (:mod:`texture.trim`): one layer of surface, iso-line borders;
2. orient (:func:`texture.atlas_stages.orient_stage`): inside-out parts reoriented;
3. relax (:func:`texture.atlas_stages.relax_stage`): islands re-flattened toward an isometry;
4. unmirror: every island reads the right way round from its front;
5. layout and pack (:func:`texture.unwrap_layout.choose_layout`, the unwrap's packing
   search): the islands turned, and halved along short cuts on the surface while that packs
   tighter, then packed (:func:`texture.pack.pack_islands`) at one texel density for all
   islands, every island keeping its relaxed UVs up to a rigid motion (the distortion loss
   shares one scale across charts).

The result is a :class:`UVMesh` in the input frame with UVs in [0,1]^2, plus the
measurements (:class:`texture.atlas_stats.AtlasStats`).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from mnacore.charts import ChartGrids
from mnacore.frame import Normalization
from mnacore.uvmesh import UVMesh, make_uv_mesh

from .atlas_config import AtlasConfig
from .atlas_stages import joined, layout_goal, layout_islands, orient_stage, relax_stage, unmirrored_layout
from .atlas_stats import AtlasStats, LayoutStats, coverage_stats
from .layouts import merge, prepare
from .orient import Reference
from .pack import Packing
from .trim import trim_charts
from .unwrap_layout import choose_layout

__all__ = ["Atlas", "AtlasConfig", "build_atlas"]


@dataclass
class Atlas:
    """A packed atlas.

    Attributes:
        mesh: UV mesh in the input frame, UVs in [0,1]^2 (v up).
        chart: (F,) chart id of each face.
        island: (F,) island id of each face (in the packing search's order).
        normalization: input frame -> unit ball (from charts.npz).
        packing: packer result (scale, utilisation, ...).
        report: the stages' measurements (coverage, doubly covered area, islands, timings).
    """

    mesh: UVMesh
    chart: np.ndarray
    island: np.ndarray
    normalization: Normalization
    packing: Packing
    report: AtlasStats

    @property
    def mesh_unit(self) -> UVMesh:
        return self.mesh.transformed(self.normalization)

    @property
    def stats(self) -> dict:
        """:attr:`report` as ``atlas.json`` writes it (its ``atlas`` section)."""
        return self.report.to_json()


def build_atlas(charts: ChartGrids, config: AtlasConfig | None = None, reference_points: np.ndarray | None = None,
                reference: Reference | None = None) -> Atlas:
    """Trim, orient, relax, lay out and pack ``charts`` (module docstring).

    ``reference_points`` (unit frame) for the coverage check; ``reference`` (the input mesh
    with normals, unit frame) to orient every island outward.
    """
    cfg = config or AtlasConfig()
    t0 = time.perf_counter()
    trimmed = trim_charts(charts, cfg.trim)
    t_trim = time.perf_counter()
    oriented = orient_stage(trimmed.pieces, reference, cfg)
    t1 = time.perf_counter()
    relaxed = relax_stage(oriented.layout, cfg.relax)
    if relaxed.pieces is None:
        flat = unmirrored_layout(oriented.layout)
    else:
        flat = unmirrored_layout([prepare(p) for p in relaxed.pieces])
    t_relax = time.perf_counter()
    surface = merge(flat)  # (raises where no chart has any surface left)
    islands = layout_islands(flat)
    choice = choose_layout(islands, np.zeros(len(surface.faces), np.int64), layout_goal(cfg))
    m, packing = joined(choice.islands), choice.packing
    t2 = time.perf_counter()
    mesh = make_uv_mesh(charts.normalization.invert(m.xyz), m.faces, packing.uv, name="atlas")
    report = AtlasStats(
        charts=int(charts.n_charts), charts_used=int(len(np.unique(m.chart))), islands=len(choice.islands),
        faces=int(len(m.faces)), trim=trimmed.stats, orient=oriented.stats, relax=relaxed.stats,
        layout=LayoutStats.of(choice.stats, len(islands)),
        # measured before the layout: its halvings keep the surface and only reorder the faces
        coverage=coverage_stats(charts, surface.xyz, surface.faces, reference_points, cfg.seed),
        utilization=packing.utilization, packer=packing.packer, uv_scale=packing.scale,
        texels_per_chart_unit=packing.texels_per_unit, resolution=packing.resolution, padding=packing.padding,
        timings={"trim": t_trim - t0, "orient": t1 - t_trim, "relax": t_relax - t1, "pack": t2 - t_relax})
    return Atlas(mesh, m.chart, m.island, charts.normalization, packing, report)
