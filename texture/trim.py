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
3. **Cleanup.** An island smaller than ``min_island_fraction`` of the total area that
   another chart covers is handed over to that chart (its vertices are banned from its
   own chart and the ownership recomputed), so no hole opens where the other chart had
   given way. Small islands nobody else covers are dropped, smallest first, while their
   total stays under ``max_dropped_fraction`` (0.25 %) of the area. Zero-area slivers are
   dropped.

Everything works in the unit-ball frame (``cover_tol = 0.02`` = 1 % of the diameter,
the F-score threshold).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cached_property
from typing import NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from mnacore.charts import ChartGrids
from mnacore.grid import grid_faces
from mnacore.tolerances import SURFACE_TOL
from mnacore.triangles import triangle_areas

from .clip import UV_COLUMNS, clip_mesh
from .geometry import MeshProjector, sample_surface
from .islands import edge_keys, edge_use_counts, half_edges, uv_islands


@dataclass
class TrimConfig:
    """Options of the overlap trimming (unit-ball frame)."""

    cover_tol: float = SURFACE_TOL
    """Another chart covers a point if its surface is within this distance (not beyond its border)."""
    min_island_fraction: float = 1e-3
    """Islands smaller than this fraction of the total area go to a covering chart."""
    max_dropped_fraction: float = 2.5e-3
    """Small islands no other chart covers are dropped (smallest first) up to this fraction of the area."""
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
        return triangle_areas(self.xyz, self.faces)

    def uv_area(self) -> np.ndarray:
        return triangle_areas(self.uv, self.faces)


def _clip_piece(piece: Piece, field: np.ndarray) -> tuple[Piece, np.ndarray]:
    """Clipped piece and, per output vertex, the input vertex it is (-1 for cut points)."""
    c = clip_mesh(np.column_stack([piece.xyz, piece.uv]), piece.faces, field, plane=UV_COLUMNS)
    return Piece(piece.chart, c.attrs[:, :3], c.attrs[:, 3:5], c.faces), c.source_vertex


def domain_pieces(charts: ChartGrids) -> list[Piece]:
    """Each chart clipped at ``occ = tau``, positions in the unit-ball frame."""
    tri = grid_faces(charts.grid)
    out = []
    for k in range(charts.n_charts):
        xyz = charts.normalization.apply(charts.xyz[k].reshape(-1, 3))
        full = Piece(k, xyz, charts.uv[k].reshape(-1, 2), tri)
        out.append(_clip_piece(full, charts.occ[k].reshape(-1) - charts.tau)[0])
    return out


def border_points(piece: Piece) -> np.ndarray:
    """(B, 3) vertices on the piece's open border (edges used by one face)."""
    if len(piece.faces) == 0:
        return np.zeros((0, 3))
    he = half_edges(piece.faces)
    open_ = edge_use_counts(edge_keys(np.arange(len(piece.xyz)), piece.faces)) == 1
    return piece.xyz[np.unique(he[open_])]


def covered_by(points: np.ndarray, projector: MeshProjector, tol: float,
               banned: np.ndarray | None = None, proj=None) -> np.ndarray:
    """(N,) bool: the mesh lies within ``tol`` of each point, not beyond its border.

    Faces touching a ``banned`` vertex (V,) of the mesh do not cover. ``proj``: the
    points' projection onto the mesh (``max_distance=tol``), if already at hand.
    """
    proj = proj if proj is not None else projector.project(points, max_distance=tol)
    cov = (proj.distance < tol) & ~proj.on_boundary
    if banned is not None and banned.any() and cov.any():
        cov[cov] = ~banned[projector.faces[proj.face[cov]]].any(1)
    return cov


class Surface:
    """A piece and its :class:`MeshProjector` (None if it has no faces), built on first use and
    then shared by the trim's passes and checks; and the projections of its vertices onto
    other surfaces, computed once (the passes change only the bans, not the projections)."""

    def __init__(self, piece: Piece):
        self.piece = piece
        self._onto: dict[tuple[int, float], object] = {}

    @cached_property
    def projector(self) -> MeshProjector | None:
        p = self.piece
        return MeshProjector(p.xyz, p.faces) if len(p.faces) else None

    def projected_onto(self, j: int, other: Surface, tol: float):
        """This surface's vertices projected onto ``other`` (surface ``j`` of the same trim)."""
        if (j, tol) not in self._onto:
            self._onto[(j, tol)] = other.projector.project(self.piece.xyz, max_distance=tol)
        return self._onto[(j, tol)]


def ownership_fields(surfaces: list[Surface], cover_tol: float,
                     banned: list[np.ndarray] | None = None) -> list[np.ndarray]:
    """Per piece, ``o_k`` at its vertices (see module docstring); finite.

    ``banned[k]`` (V_k,) marks vertices of piece ``k`` that must lose: ``o_k < 0`` there and
    piece ``k`` does not count as covering them for the other pieces.
    """
    pieces = [s.piece for s in surfaces]
    banned = banned or [np.zeros(len(p.xyz), bool) for p in pieces]
    trees = []
    for p in pieces:
        b = border_points(p)
        trees.append(cKDTree(b) if len(b) else None)
    projectors = [s.projector for s in surfaces]
    fields = []
    far = 10.0  # > unit-ball diameter: "no border"
    for k, p in enumerate(pieces):
        s_k = trees[k].query(p.xyz)[0] if trees[k] is not None else np.full(len(p.xyz), far)
        best_other = np.zeros(len(p.xyz))
        for j in range(len(pieces)):
            if j == k or projectors[j] is None:
                continue
            proj = surfaces[k].projected_onto(j, surfaces[j], cover_tol)
            cov = covered_by(p.xyz, projectors[j], cover_tol, banned[j], proj)
            if not cov.any():
                continue
            s_j = trees[j].query(p.xyz[cov])[0] if trees[j] is not None else np.full(int(cov.sum()), far)
            best_other[cov] = np.maximum(best_other[cov], s_j)
        o = s_k - best_other
        o[banned[k]] = -far
        fields.append(o)
    return fields


def _small_islands(piece: Piece, min_area: float) -> tuple[np.ndarray, np.ndarray]:
    """(island id per face, bool per island: smaller than ``min_area``)."""
    if len(piece.faces) == 0:
        return np.zeros(0, np.int64), np.zeros(0, bool)
    island = uv_islands(piece.faces, piece.uv)
    return island, np.bincount(island, weights=piece.area()) < min_area


def _covered_fraction(piece: Piece, faces: np.ndarray, others: list, tol: float) -> float:
    """Area fraction of ``piece``'s ``faces`` whose centroids another piece covers."""
    centroid = piece.xyz[piece.faces[faces]].mean(1)
    hit = np.zeros(len(faces), bool)
    for proj, ban in others:
        hit |= covered_by(centroid, proj, tol, ban)
    area = piece.area()[faces]
    return float((area * hit).sum() / max(area.sum(), 1e-300))
def _drop_faces(piece: Piece, keep: np.ndarray) -> Piece:
    faces = piece.faces[keep]
    used = np.unique(faces)
    remap = np.full(len(piece.xyz), -1)
    remap[used] = np.arange(len(used))
    return Piece(piece.chart, piece.xyz[used], piece.uv[used], remap[faces])


def _without_slivers(piece: Piece) -> Piece:
    """Remove faces with (numerically) zero UV or 3D area."""
    if len(piece.faces) == 0:
        return piece
    uv_area, area = piece.uv_area(), piece.area()
    return _drop_faces(piece, (uv_area > 1e-12 * max(float(np.median(uv_area)), 1e-300)) & (area > 0))


@dataclass(frozen=True)
class TrimStats:
    """What the trim did: areas (unit-ball frame), doubly covered area before and after (percent
    of the area), islands handed over to a covering chart or dropped, area dropped uncovered
    (percent)."""

    domain_area: float
    trimmed_area: float
    doubly_covered_percent_before: float
    doubly_covered_percent: float
    handed_over_islands: int
    dropped_islands: int
    dropped_uncovered_percent: float

    def to_json(self) -> dict:
        return dataclasses.asdict(self)


class TrimResult(NamedTuple):
    pieces: list[Piece]  # one per chart (possibly empty), trimmed, unit-ball frame
    domain: list[Piece]  # the charts cut at the domain iso-line only
    stats: TrimStats


def doubly_covered_percent(surfaces: list[Surface], tol: float, samples: int, seed: int) -> float:
    """Percent of the total area that another chart also covers (sampled, seeded)."""
    pieces = [s.piece for s in surfaces]
    areas = [float(p.area().sum()) for p in pieces]
    total = sum(areas)
    if total <= 0 or len(pieces) < 2:
        return 0.0
    projectors = [s.projector for s in surfaces]
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


def _ban_small_islands(domain: list[Surface], trimmed, sources, banned, min_area, tol) -> int:
    """Ban (in ``banned``) the source vertices of small islands that another chart covers."""
    others = [(s.projector, banned[j]) if len(s.piece.faces) else None for j, s in enumerate(domain)]
    count = 0
    for k, (q, src) in enumerate(zip(trimmed, sources)):
        island, small = _small_islands(q, min_area)
        for i in np.flatnonzero(small):
            faces = np.flatnonzero(island == i)
            rest = [o for j, o in enumerate(others) if j != k and o is not None]
            if rest and _covered_fraction(q, faces, rest, tol) > 0.5:
                verts = src[np.unique(q.faces[faces])]
                banned[k][verts[verts >= 0]] = True
                count += 1
    return count


def _owned(surfaces: list[Surface], cfg: TrimConfig, min_area: float, passes: int) -> tuple[list[Piece], int]:
    """(every domain piece cut at its ownership iso-line, islands handed over): small islands
    another chart covers are banned and the ownership recomputed, up to ``passes`` times."""
    domain = [s.piece for s in surfaces]
    banned = [np.zeros(len(p.xyz), bool) for p in domain]
    handed = 0
    for it in range(passes):
        fields = ownership_fields(surfaces, cover_tol=cfg.cover_tol, banned=banned)
        clipped = [_clip_piece(p, f) if len(p.faces) else (p, np.arange(len(p.xyz))) for p, f in zip(domain, fields)]
        trimmed = [c[0] for c in clipped]
        if it == passes - 1:
            break
        n = _ban_small_islands(surfaces, trimmed, [c[1] for c in clipped], banned, min_area, cfg.cover_tol)
        handed += n
        if n == 0:
            break
    return trimmed, handed


def _cleaned(finals: list[Surface], cfg: TrimConfig, min_area: float, total: float) -> tuple[list[Surface], int, float]:
    """(surfaces without their small islands, islands dropped, area dropped alone): small islands
    covered elsewhere are slivers, dropped; alone they are tiny holes: the smallest are dropped
    while their total stays under ``max_dropped_fraction`` of the area."""
    projs = [(s.projector, None) if len(s.piece.faces) else None for s in finals]
    keep = [np.ones(len(s.piece.faces), bool) for s in finals]
    alone = []  # (area, chart, faces)
    dropped, dropped_area = 0, 0.0
    for k, s in enumerate(finals):
        q = s.piece
        island, small = _small_islands(q, min_area)
        area = q.area()
        for i in np.flatnonzero(small):
            faces = np.flatnonzero(island == i)
            rest = [o for j, o in enumerate(projs) if j != k and o is not None]
            if rest and _covered_fraction(q, faces, rest, cfg.cover_tol) > 0.5:
                keep[k][faces] = False
                dropped += 1
            else:
                alone.append((float(area[faces].sum()), k, faces))
    for a, k, faces in sorted(alone, key=lambda t: (t[0], t[1], int(t[2][0]))):
        if dropped_area + a > cfg.max_dropped_fraction * total:
            break
        keep[k][faces] = False
        dropped += 1
        dropped_area += a
    out = [Surface(_drop_faces(s.piece, m)) if not m.all() else s for s, m in zip(finals, keep)]
    return out, dropped, dropped_area


def trim_charts(charts: ChartGrids, config: TrimConfig | None = None, passes: int = 3) -> TrimResult:
    """Domain cut, ownership cut and cleanup (module docstring); stats in percent of area.

    Small islands that another chart covers are handed to that chart (their vertices are
    banned from their own chart and the ownership is recomputed, up to ``passes`` times);
    dropping them instead would leave holes where the other chart had given way.
    """
    cfg = config or TrimConfig()
    domain = [_without_slivers(p) for p in domain_pieces(charts)]
    total = sum(float(p.area().sum()) for p in domain)
    min_area = cfg.min_island_fraction * total
    surfaces = [Surface(p) for p in domain]  # one MeshProjector per piece for all passes and checks
    trimmed, handed = _owned(surfaces, cfg, min_area, passes)
    finals, dropped, dropped_area = _cleaned([Surface(_without_slivers(p)) for p in trimmed], cfg, min_area, total)
    final = [s.piece for s in finals]
    stats = TrimStats(
        domain_area=total,
        trimmed_area=sum(float(p.area().sum()) for p in final),
        doubly_covered_percent_before=doubly_covered_percent(surfaces, cfg.cover_tol, cfg.check_samples, cfg.seed),
        doubly_covered_percent=doubly_covered_percent(finals, cfg.cover_tol, cfg.check_samples, cfg.seed),
        handed_over_islands=handed,
        dropped_islands=dropped,
        dropped_uncovered_percent=100.0 * dropped_area / total,
    )
    return TrimResult(final, domain, stats)
