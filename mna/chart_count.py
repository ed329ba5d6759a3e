"""How many charts a fit gets when the user does not say: from the input's topology (issue 18).

A chart's domain is a planar region, so on a closed surface every handle has to be either
cut by a chart's border or carried as a hole in a learned domain. Three charts (the
paper's choice) fit genus 0-2 inputs to within a point or two of their oracle, but on a
genus-4 plate they stalled 12 F points short however long they ran, and five charts closed
most of that gap (benchmarks/RESULTS.md, fit_quality_hard). So: three charts, plus one per
handle beyond two, up to a cap (a step costs linearly in charts). The genus comes from the
Euler characteristic of the input mesh (:func:`mnacore.topology.mesh_topology`); a point
cloud has no faces to count, so it gets the base count.
"""
from __future__ import annotations

from mna.config import FitConfig
from mna.data import Surface
from mnacore.topology import Topology, mesh_topology

#: charts for a surface of genus <= FREE_HANDLES (the paper's K)
BASE_CHARTS = 3
#: handles the base charts carry without help (measured: genus 2 and the genus-2 "eight")
FREE_HANDLES = 2
#: no more than this many charts by the rule: each costs one more MLP per step
AUTO_MAX_CHARTS = 6


def charts_for(topology: Topology) -> int:
    """Charts for an input of this topology: base, plus one per handle beyond the free ones, capped."""
    return min(AUTO_MAX_CHARTS, BASE_CHARTS + max(0, topology.total_genus - FREE_HANDLES))


def resolve_charts(cfg: FitConfig, surface: Surface) -> str | None:
    """Set ``cfg.model.charts`` by ``cfg.charts_rule``; a line saying how K was chosen (None: fixed K)."""
    if cfg.charts_rule != "topology":
        return None
    if not surface.is_mesh:
        cfg.model.charts = BASE_CHARTS
        return f"{BASE_CHARTS} charts (point cloud: no topology to count)"
    topo = mesh_topology(surface.mesh.vertices, surface.mesh.faces)
    cfg.model.charts = charts_for(topo)
    estimate = "" if topo.manifold else ", an estimate: the mesh has non-manifold edges"
    return (f"{cfg.model.charts} charts for genus {topo.total_genus} over {topo.parts} part(s){estimate} "
            f"(3 + one per handle beyond {FREE_HANDLES}, at most {AUTO_MAX_CHARTS}; --charts N fixes K)")
