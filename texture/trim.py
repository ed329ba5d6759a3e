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

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from .charts import ChartGrids
from .clip import UV_COLUMNS, clip_mesh, grid_faces
from .geometry import MeshProjector, sample_surface, triangle_areas
from .islands import edge_keys, edge_use_counts, half_edges, uv_islands


@dataclass
class TrimConfig:
    """Options of the overlap trimming (unit-ball frame)."""

    cover_tol: float = 0.02
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


def projector(p: Piece, cache: dict | None = None) -> MeshProjector | None:
    """:class:`MeshProjector` of ``p`` (None if it has no faces); ``cache`` (keyed by the piece
    object) keeps one per piece across the trim's passes and checks."""
    if cache is not None and id(p) in cache:
        return cache[id(p)][1]
    proj = MeshProjector(p.xyz, p.faces) if len(p.faces) else None
    if cache is not None:
        cache[id(p)] = (p, proj)  # holding p keeps its id from being reused
    return proj


def ownership_fields(pieces: list[Piece], cover_tol: float, banned: list[np.ndarray] | None = None,
                     cache: dict | None = None) -> list[np.ndarray]:
    """Per piece, ``o_k`` at its vertices (see module docstring); finite.

    ``banned[k]`` (V_k,) marks vertices of piece ``k`` that must lose: ``o_k < 0`` there and
    piece ``k`` does not count as covering them for the other pieces.
    """
    banned = banned or [np.zeros(len(p.xyz), bool) for p in pieces]
    trees = []
    for p in pieces:
        b = border_points(p)
        trees.append(cKDTree(b) if len(b) else None)
    projectors = [projector(p, cache) for p in pieces]
    fields = []
    far = 10.0  # > unit-ball diameter: "no border"
    for k, p in enumerate(pieces):
        s_k = trees[k].query(p.xyz)[0] if trees[k] is not None else np.full(len(p.xyz), far)
        best_other = np.zeros(len(p.xyz))
        for j, q in enumerate(pieces):
            if j == k or projectors[j] is None:
                continue
            # the projection does not change between the passes (only the bans do): kept in the cache
            key = ("projection", id(p), id(q), cover_tol)
            proj = cache.get(key) if cache is not None else None
            if proj is None:
                proj = projectors[j].project(p.xyz, max_distance=cover_tol)
                if cache is not None:
                    cache[key] = proj
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


class TrimResult(NamedTuple):
    pieces: list[Piece]  # one per chart (possibly empty), trimmed, unit-ball frame
    domain: list[Piece]  # the charts cut at the domain iso-line only
    stats: dict


def doubly_covered_percent(pieces: list[Piece], tol: float, samples: int, seed: int,
                           cache: dict | None = None) -> float:
    """Percent of the total area that another chart also covers (sampled, seeded)."""
    areas = [float(p.area().sum()) for p in pieces]
    total = sum(areas)
    if total <= 0 or len(pieces) < 2:
        return 0.0
    projectors = [projector(p, cache) for p in pieces]
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


def _ban_small_islands(domain, trimmed, sources, banned, min_area, tol, cache: dict | None = None) -> int:
    """Ban (in ``banned``) the source vertices of small islands that another chart covers."""
    others = [(projector(p, cache), banned[j]) if len(p.faces) else None for j, p in enumerate(domain)]
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
    banned = [np.zeros(len(p.xyz), bool) for p in domain]
    cache: dict = {}  # one MeshProjector per piece for all passes and checks
    handed = 0
    for it in range(passes):
        fields = ownership_fields(domain, cfg.cover_tol, banned, cache)
        clipped = [_clip_piece(p, f) if len(p.faces) else (p, np.arange(len(p.xyz))) for p, f in zip(domain, fields)]
        trimmed = [c[0] for c in clipped]
        if it == passes - 1:
            break
        n = _ban_small_islands(domain, trimmed, [c[1] for c in clipped], banned, min_area, cfg.cover_tol, cache)
        handed += n
        if n == 0:
            break
    # small islands left: covered elsewhere -> slivers, drop; alone -> tiny holes, drop the
    # smallest while their total stays under max_dropped_fraction of the area
    finals = [_without_slivers(p) for p in trimmed]
    projs = [(projector(p, cache), None) if len(p.faces) else None for p in finals]
    keep = [np.ones(len(q.faces), bool) for q in finals]
    alone = []  # (area, chart, faces)
    dropped, dropped_area = 0, 0.0
    for k, q in enumerate(finals):
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
    final = [_drop_faces(q, m) if not m.all() else q for q, m in zip(finals, keep)]
    stats = {
        "domain_area": total,
        "trimmed_area": sum(float(p.area().sum()) for p in final),
        "doubly_covered_percent_before": doubly_covered_percent(domain, cfg.cover_tol, cfg.check_samples, cfg.seed,
                                                                cache),
        "doubly_covered_percent": doubly_covered_percent(final, cfg.cover_tol, cfg.check_samples, cfg.seed, cache),
        "handed_over_islands": handed,
        "dropped_islands": dropped,
        "dropped_uncovered_percent": 100.0 * dropped_area / total,
    }
    return TrimResult(final, domain, stats)
