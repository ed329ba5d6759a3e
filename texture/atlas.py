"""Charts -> one packed UV atlas: a straight chain of stages.

``build_atlas(charts)`` runs, each stage on the previous one's typed result:

1. trim (:mod:`texture.trim`): one layer of surface, iso-line borders;
2. orient (:func:`texture.atlas_stages.orient_stage`): inside-out parts reoriented;
3. relax (:func:`texture.atlas_stages.relax_stage`): islands re-flattened toward an isometry;
4. unmirror: every island reads the right way round from its front;
5. layout (:func:`texture.atlas_stages.choose_layout`): the islands as they are or with one
   cut, relaxed or not, as :mod:`texture.policy` decides from coarse packings;
6. pack (:func:`texture.pack.pack_islands`): one texel density for all islands, every island
   keeping its chart-local UV up to a rigid motion (the distortion loss shares one scale
   across charts).

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
from .atlas_stages import choose_layout, orient_stage, relax_stage, unmirrored_layout
from .atlas_stats import AtlasStats, coverage_stats
from .layouts import prepare
from .orient import Reference
from .pack import Packing, pack_islands
from .policy import DEFAULT_POLICY, SearchPolicy
from .trim import trim_charts

__all__ = ["Atlas", "AtlasConfig", "build_atlas"]


@dataclass
class Atlas:
    """A packed atlas.

    Attributes:
        mesh: UV mesh in the input frame, UVs in [0,1]^2 (v up).
        chart: (F,) chart id of each face.
        island: (F,) island id of each face (islands are numbered chart by chart).
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
                reference: Reference | None = None, policy: SearchPolicy = DEFAULT_POLICY) -> Atlas:
    """Trim, orient, relax, cut and pack ``charts`` (module docstring).

    ``reference_points`` (unit frame) for the coverage check; ``reference`` (the input mesh
    with normals, unit frame) to orient every island outward; ``policy`` for the packing search.
    """
    cfg = config or AtlasConfig()
    t0 = time.perf_counter()
    trimmed = trim_charts(charts, cfg.trim)
    t_trim = time.perf_counter()
    oriented = orient_stage(trimmed.pieces, reference, cfg)
    t1 = time.perf_counter()
    relaxed = relax_stage(oriented.layout, cfg.relax)
    raw = unmirrored_layout(oriented.layout)
    if relaxed.pieces is None:
        flat, raw = raw, None
    else:
        flat = unmirrored_layout([prepare(p) for p in relaxed.pieces])
    t_relax = time.perf_counter()
    choice = choose_layout(flat, raw, cfg, relaxed.stats, policy)
    m = choice.merged
    packing = pack_islands(*m.islands, resolution=cfg.resolution, padding=cfg.padding, plan=choice.plan,
                           policy=policy)
    t2 = time.perf_counter()
    mesh = make_uv_mesh(charts.normalization.invert(m.xyz), m.faces, packing.uv, name="atlas")
    report = AtlasStats(
        charts=int(charts.n_charts), charts_used=int(len(np.unique(m.chart))), islands=int(m.island.max()) + 1,
        faces=int(len(m.faces)), trim=trimmed.stats, orient=oriented.stats, relax=relaxed.stats,
        layout=choice.stats, coverage=coverage_stats(charts, m.xyz, m.faces, reference_points, cfg.seed),
        utilization=packing.utilization, packer=packing.packer, uv_scale=packing.scale,
        texels_per_chart_unit=packing.texels_per_unit, resolution=packing.resolution, padding=packing.padding,
        timings={"trim": t_trim - t0, "orient": t1 - t_trim, "relax": t_relax - t1, "pack": t2 - t_relax})
    return Atlas(mesh, m.chart, m.island, charts.normalization, packing, report)
