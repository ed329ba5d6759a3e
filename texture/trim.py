"""From overlapping neural charts to one layer of surface with clean borders.

1. **Domain cut.** Each chart's grid is clipped at the ``occ = tau`` iso-line
   (:func:`texture.clip.clip_mesh`), so its border follows the domain boundary.
2. **Ownership.** Where charts overlap, a point belongs to the covering chart in whose
   domain it lies deepest: chart ``k`` keeps ``x`` iff
   ``o_k(x) = s_k(x) - max_{j covers x} s_j(x) > 0`` with ``s_j(x)`` the 3D distance
   from ``x`` to chart ``j``'s domain border. Chart ``j`` *covers* ``x`` when the
   closest point of its domain mesh is within ``cover_tol`` and not on its border.
   The distance is used instead of the occupancy because ``occ`` saturates near 1
   inside every chart (ties would fragment the border); it puts the border in the
   middle of each overlap, which is where both charts are farthest from their
   less accurate domain edges. The cut is again an iso-line (``o_k = 0``).
3. **Cleanup.** Zero-area slivers and islands smaller than ``min_island_fraction`` of
   the total area are dropped.

Everything works in the unit-ball frame (``cover_tol = 0.02`` = 1 % of the diameter,
the F-score threshold).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from .charts import ChartGrids
from .clip import clip_mesh, grid_faces
from .geometry import MeshProjector, sample_surface
from .islands import edge_keys, edge_use_counts, half_edges, uv_islands


@dataclass
class TrimConfig:
    """Options of the overlap trimming (unit-ball frame)."""

    cover_tol: float = 0.02
    """Another chart covers a point if its surface is within this distance (not beyond its border)."""
    min_island_fraction: float = 2e-4
    """Islands smaller than this fraction of the total area are dropped (slivers)."""
    check_samples: int = 20000
    """Surface samples for the doubly-covered-area measurement."""
    seed: int = 0


class Piece(NamedTuple):
    """Part of one chart: positions in the unit-ball frame, chart-local UV, faces."""

    chart: int
    xyz: np.ndarray  # (V, 3)
    uv: np.ndarray  # (V, 2)
    faces: np.ndarray  # (F, 3)

    def area(self) -> np.ndarray:
        t = self.xyz[self.faces]
        return 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)


def _clip_piece(piece: Piece, field: np.ndarray) -> Piece:
    c = clip_mesh(np.column_stack([piece.xyz, piece.uv]), piece.faces, field)
    return Piece(piece.chart, c.attrs[:, :3], c.attrs[:, 3:5], c.faces)


def domain_pieces(charts: ChartGrids) -> list[Piece]:
    """Each chart clipped at ``occ = tau``, positions in the unit-ball frame."""
    tri = grid_faces(charts.grid)
    out = []
    for k in range(charts.n_charts):
        xyz = charts.normalization.apply(charts.xyz[k].reshape(-1, 3))
        full = Piece(k, xyz, charts.uv[k].reshape(-1, 2), tri)
        out.append(_clip_piece(full, charts.occ[k].reshape(-1) - charts.tau))
    return out


def border_points(piece: Piece) -> np.ndarray:
    """(B, 3) vertices on the piece's open border (edges used by one face)."""
    if len(piece.faces) == 0:
        return np.zeros((0, 3))
    he = half_edges(piece.faces)
    open_ = edge_use_counts(edge_keys(np.arange(len(piece.xyz)), piece.faces)) == 1
    return piece.xyz[np.unique(he[open_])]


def covered_by(points: np.ndarray, projector: MeshProjector, tol: float) -> np.ndarray:
    """(N,) bool: the mesh lies within ``tol`` of each point, not beyond its border."""
    proj = projector.project(points, max_distance=tol)
    return (proj.distance < tol) & ~proj.on_boundary


def ownership_fields(pieces: list[Piece], cover_tol: float) -> list[np.ndarray]:
    """Per piece, ``o_k`` at its vertices (see module docstring); ``+inf``-free, finite."""
    trees = []
    for p in pieces:
        b = border_points(p)
        trees.append(cKDTree(b) if len(b) else None)
    projectors = [MeshProjector(p.xyz, p.faces) if len(p.faces) else None for p in pieces]
    fields = []
    for k, p in enumerate(pieces):
        far = 10.0  # > unit-ball diameter: "no border"
        s_k = trees[k].query(p.xyz)[0] if trees[k] is not None else np.full(len(p.xyz), far)
        best_other = np.zeros(len(p.xyz))
        for j, q in enumerate(pieces):
            if j == k or projectors[j] is None:
                continue
            cov = covered_by(p.xyz, projectors[j], cover_tol)
            if not cov.any():
                continue
            s_j = trees[j].query(p.xyz[cov])[0] if trees[j] is not None else np.full(int(cov.sum()), far)
            best_other[cov] = np.maximum(best_other[cov], s_j)
        fields.append(s_k - best_other)
    return fields


def _drop_small(piece: Piece, min_area: float) -> tuple[Piece, int]:
    """Remove zero-area faces and islands below ``min_area``; returns (piece, islands dropped)."""
    if len(piece.faces) == 0:
        return piece, 0
    t = piece.uv[piece.faces]
    uv_area = 0.5 * np.abs((t[:, 1, 0] - t[:, 0, 0]) * (t[:, 2, 1] - t[:, 0, 1])
                           - (t[:, 1, 1] - t[:, 0, 1]) * (t[:, 2, 0] - t[:, 0, 0]))
    area = piece.area()
    ok = (uv_area > 1e-12 * max(float(np.median(uv_area)), 1e-300)) & (area > 0)
    faces = piece.faces[ok]
    island = uv_islands(faces, piece.uv)
    isl_area = np.bincount(island, weights=area[ok])
    keep = isl_area[island] >= min_area
    dropped = int((isl_area < min_area).sum())
    faces = faces[keep]
    used = np.unique(faces)
    remap = np.full(len(piece.xyz), -1)
    remap[used] = np.arange(len(used))
    return Piece(piece.chart, piece.xyz[used], piece.uv[used], remap[faces]), dropped


class TrimResult(NamedTuple):
    pieces: list[Piece]  # one per chart (possibly empty), trimmed, unit-ball frame
    domain: list[Piece]  # the charts cut at the domain iso-line only
    stats: dict


def doubly_covered_percent(pieces: list[Piece], tol: float, samples: int, seed: int) -> float:
    """Percent of the total area that another chart also covers (sampled, seeded)."""
    areas = [float(p.area().sum()) for p in pieces]
    total = sum(areas)
    if total <= 0 or len(pieces) < 2:
        return 0.0
    projectors = [MeshProjector(p.xyz, p.faces) if len(p.faces) else None for p in pieces]
    covered_area = 0.0
    for k, p in enumerate(pieces):
        n = int(round(samples * areas[k] / total))
        if n == 0:
            continue
        pts, _ = sample_surface(p.xyz, p.faces, n, seed + k)
        hit = np.zeros(n, bool)
        for j, proj in enumerate(projectors):
            if j != k and proj is not None:
                hit |= covered_by(pts, proj, tol)
        covered_area += areas[k] * float(hit.mean())
    return 100.0 * covered_area / total


def trim_charts(charts: ChartGrids, config: TrimConfig | None = None) -> TrimResult:
    """Domain cut, ownership cut and cleanup (module docstring); stats in percent of area."""
    cfg = config or TrimConfig()
    domain = domain_pieces(charts)
    fields = ownership_fields(domain, cfg.cover_tol)
    total = sum(float(p.area().sum()) for p in domain)
    trimmed, dropped = [], 0
    for p, f in zip(domain, fields):
        q = _clip_piece(p, f) if len(p.faces) else p
        q, d = _drop_small(q, cfg.min_island_fraction * total)
        trimmed.append(q)
        dropped += d
    stats = {
        "domain_area": total,
        "trimmed_area": sum(float(p.area().sum()) for p in trimmed),
        "doubly_covered_percent_before": doubly_covered_percent(domain, cfg.cover_tol, cfg.check_samples, cfg.seed),
        "doubly_covered_percent": doubly_covered_percent(trimmed, cfg.cover_tol, cfg.check_samples, cfg.seed),
        "dropped_islands": dropped,
    }
    return TrimResult(trimmed, domain, stats)
