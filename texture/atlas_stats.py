"""The atlas stages' measurements as typed results, and their ``atlas.json`` form.

``atlas.json``'s ``atlas`` section is :meth:`AtlasStats.to_json`: one flat mapping whose
keys (and their order) are a contract of ``mna export``; a key a stage did not reach is
left out, not written as null.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from mnacore.charts import ChartGrids
from mnacore.pointmetrics import POINTS, chamfer_fscore

from .geometry import sample_surface
from .trim import TrimStats


def _present(pairs) -> dict:
    return {k: v for k, v in pairs if v is not None}


@dataclass(frozen=True)
class OrientStats:
    """The orientation stage (:func:`texture.orient.orient_pieces`'s measurements, percent of the
    area), and whether fragment islands were kept (None: no fragment islands allowed)."""

    folded_percent_before_orient: float
    reoriented_percent: float
    folded_percent: float
    orient_dropped_percent: float
    orient_fragment_island_count: int
    orient_fragment_islands: bool | None = None

    def to_json(self) -> dict:
        out = dataclasses.asdict(self)
        if self.orient_fragment_islands is None:
            del out["orient_fragment_islands"]
        return out


@dataclass
class RelaxStats:
    """The relaxation stage: SLIM iterations, islands stopped by a border crossing, and the
    3D-area weighted mean of ``tr g + tr g^-1 - 4`` at the isometric scale before and after
    (None: not relaxed)."""

    iterations_max: int = 0
    stopped_by_crossing: int = 0
    energy_before: float | None = None
    energy_after: float | None = None

    @classmethod
    def from_json(cls, atlas: dict) -> RelaxStats:
        """The relaxation's stats back from ``atlas.json``'s ``atlas`` section."""
        return cls(atlas.get("relax_iterations_max", 0), atlas.get("relax_stopped_by_crossing", 0),
                   atlas.get("relax_energy_before"), atlas.get("relax_energy_after"))

    def to_json(self) -> dict:
        out = {"relax_iterations_max": self.iterations_max, "relax_stopped_by_crossing": self.stopped_by_crossing}
        out.update(_present([("relax_energy_before", self.energy_before), ("relax_energy_after", self.energy_after)]))
        return out


@dataclass(frozen=True)
class LayoutStats:
    """What the packing search did (:func:`texture.unwrap_layout.choose_layout`): the islands
    handed to it, the utilisation they packed at as they came (turned as packs best), its
    halvings in order (island rank, axis, position, 3D cut length, utilisation after), and
    whether xatlas's exhaustive placement was kept."""

    islands_before: int
    utilization_uncut: float | None
    halvings: tuple[dict, ...]
    brute_force: bool

    @classmethod
    def of(cls, stats: dict, islands_before: int) -> LayoutStats:
        """From :class:`texture.unwrap_layout.LayoutChoice`'s ``stats``."""
        return cls(islands_before, stats.get("utilization_uncut"), tuple(stats.get("halvings", ())),
                   bool(stats.get("brute_force", False)))

    def to_json(self) -> dict:
        out = {"islands_before_layout": self.islands_before, "split_islands": len(self.halvings)}
        out.update(_present([("utilization_uncut", self.utilization_uncut)]))
        out.update(halvings=[dict(h) for h in self.halvings], brute_force=self.brute_force)
        return out


@dataclass
class CoverageStats:
    """F-score and Chamfer distance of the run's kept mesh and of the trimmed atlas against
    the reference (the input, else an independent sample of the kept mesh); None where there
    is nothing to compare."""

    reference: str
    fscore_trimmed: float | None = None
    chamfer_trimmed: float | None = None
    fscore_kept: float | None = None
    chamfer_kept: float | None = None
    fscore_drop: float | None = None

    def to_json(self) -> dict:
        return {"coverage_reference": self.reference,
                **_present([("fscore_trimmed", self.fscore_trimmed), ("chamfer_trimmed", self.chamfer_trimmed),
                            ("fscore_kept", self.fscore_kept), ("chamfer_kept", self.chamfer_kept),
                            ("fscore_drop", self.fscore_drop)])}


def coverage_stats(charts: ChartGrids, xyz: np.ndarray, faces: np.ndarray, reference: np.ndarray | None,
                   seed: int) -> CoverageStats:
    """F-score of the run's kept mesh and of the trimmed atlas ``(xyz, faces)`` against ``reference`` (unit frame)."""
    trimmed_pts, _ = sample_surface(xyz, faces, POINTS, seed)
    kept_pts = ref = None
    if charts.kept_vertices is not None and len(charts.kept_faces):
        kept = charts.normalization.apply(charts.kept_vertices)
        kept_pts, _ = sample_surface(kept, charts.kept_faces, POINTS, seed + 1)
        if reference is None:  # an independent sample, so "before" is not compared with itself
            ref, _ = sample_surface(kept, charts.kept_faces, POINTS, seed + 2)
    if reference is not None:
        ref = reference
    out = CoverageStats("input" if reference is not None else "kept_mesh")
    if ref is None:
        return out
    after = chamfer_fscore(trimmed_pts, ref)
    out.fscore_trimmed, out.chamfer_trimmed = after.fscore, after.chamfer
    if kept_pts is not None:
        before = chamfer_fscore(kept_pts, ref)
        out.fscore_kept, out.chamfer_kept = before.fscore, before.chamfer
        out.fscore_drop = before.fscore - after.fscore
    return out


@dataclass
class AtlasStats:
    """Everything :func:`texture.atlas.build_atlas` measured, stage by stage.

    ``orient`` is None when the pieces were not oriented (no reference surface).
    """

    charts: int
    charts_used: int
    islands: int
    faces: int
    trim: TrimStats
    orient: OrientStats | None
    relax: RelaxStats
    layout: LayoutStats
    coverage: CoverageStats
    utilization: float
    packer: str
    uv_scale: float
    texels_per_chart_unit: float
    resolution: int
    padding: int
    timings: dict = field(default_factory=dict)
    """Seconds per stage: trim, orient, relax, pack."""

    @property
    def doubly_covered_percent(self) -> float:
        return self.trim.doubly_covered_percent

    @property
    def fscore_drop(self) -> float:
        """F-score points lost by trimming (NaN when there was no reference to measure it)."""
        drop = self.coverage.fscore_drop
        return float("nan") if drop is None else drop

    def to_json(self, timings: bool = True) -> dict:
        """The ``atlas`` section of ``atlas.json`` (with ``timings`` unless told otherwise)."""
        out = {"charts": self.charts, "charts_used": self.charts_used, "islands": self.islands, "faces": self.faces,
               **self.trim.to_json(), **(self.orient.to_json() if self.orient else {}), **self.relax.to_json(), **self.layout.to_json(),
               **self.coverage.to_json(), "utilization": self.utilization, "packer": self.packer,
               "uv_scale": self.uv_scale, "texels_per_chart_unit": self.texels_per_chart_unit,
               "resolution": self.resolution, "padding": self.padding}
        if timings:
            out["timings"] = dict(self.timings)
        return out
