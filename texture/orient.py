"""Orient every island outward: no folded faces in the atlas.

A neural chart has no notion of "outside": the handedness of its UV square decides which
way its faces point, and in places a chart turns inside out (its surface passes through a
thin part, or folds, and carries on with the opposite orientation). Those faces are where
the input surface is, but they face inward, so a renderer that culls back faces drops
them and the UV metrics count them as folded.

With a reference surface (the input mesh, its vertex normals) each trimmed piece is cut at
the zero iso-line of the orientation field ``g(v) = <n_piece(v), n_ref(v)>`` (both unit
vertex normals; ``n_ref`` interpolated at the closest point of the reference), with the
same marching-triangles clip as every other border (:func:`texture.clip.clip_mesh`). The
part where ``g < 0`` is reoriented: its faces' winding is reversed (so their normals agree
with the reference) and its UVs are mirrored ``u -> -u`` (so its UV orientation stays
consistent and a texture reads the right way round from outside). Mirroring is an isometry:
the distortion and the texel density do not change. The reoriented part becomes its own
island (a new seam along the fold line).

Noise: a fragment of either sign smaller than ``min_area`` (a part of an island the cut
would split off) never becomes an island of its own, so the cut never sprays tiny islands
along a fold line. Fragments are dropped, smallest first, while their total stays under a
budget (a speck of hole is no worse than a speck turned inside out, which a renderer that
culls back faces does not draw either); the rest are kept with their surroundings (the
field is overridden there and the cut redone). A whole small island of one sign is
reoriented as a whole. What is left folded, and what was dropped, is reported.

Undecided orientation: where a reference facet within ``FOLD_TOL`` beyond the closest
point faces against the closest normal (the two sides of a thin part, touching parts),
the harness calls a face's orientation undecided, not folded. Here such places still
follow the closest normal (the nearer side is the better guess), but a fragment lying
mostly there is kept with its surroundings and spends none of the drop budget, and the
folded areas in the stats leave them out.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .clip import UV_COLUMNS, clip_mesh
from .geometry import MeshProjector
from .harness import FOLD_TOL, facet_normals
from .islands import uv_islands
from . import parallel
from .parallel import parallel_map
from .trim import Piece


class Reference:
    """A reference surface with unit vertex normals, in the unit-ball frame."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray):
        self.projector = MeshProjector(np.asarray(vertices, np.float64), np.asarray(faces, np.int64))
        n = np.asarray(normals, np.float64)
        self.normals = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
        self._facets = None  # unit facet normals, on first use

    @classmethod
    def from_trimesh(cls, mesh, normalization) -> "Reference":
        """From a ``trimesh.Trimesh`` in the input frame and the input -> unit-ball ``normalization``."""
        import trimesh

        # merged copy: a mesh loaded with its UV seams split has one-sided normals along them
        merged = trimesh.Trimesh(np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces), process=True)
        return cls(normalization.apply(merged.vertices), merged.faces, merged.vertex_normals)

    def normal_at(self, points: np.ndarray, with_distance: bool = False):
        """(N, 3) unit reference normal at the closest reference point of each of ``points``
        (and the (N,) distances to it with ``with_distance``)."""
        proj = self.projector.project(points)
        n = (proj.bary[:, :, None] * self.normals[self.projector.faces[proj.face]]).sum(1)
        n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
        return (n, proj.distance) if with_distance else n

    def undecided(self, points: np.ndarray, normal: np.ndarray, distance: np.ndarray) -> np.ndarray:
        """(N,) bool: a reference facet within ``distance + FOLD_TOL`` of the point faces
        against its closest reference ``normal``: the harness's undecided orientation (the
        two sides of a thin part, touching parts)."""
        out = np.zeros(len(points), bool)
        if self._facets is None:
            self._facets = facet_normals(self.projector.vertices, self.projector.faces, self.normals)
        i, _, _ = self.projector.faces_within(points, distance + FOLD_TOL,
                                             where=lambda i, f: (self._facets[f] * normal[i]).sum(1) < -UNDECIDED_COS)
        out[np.unique(i)] = True
        return out


def face_normals(xyz: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F, 3) area-weighted (unnormalised, length = 2 * area) face normals."""
    t = xyz[faces]
    return np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])


def vertex_normals(xyz: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(V, 3) unit area-weighted vertex normals (zero for unused vertices)."""
    acc = np.zeros((len(xyz), 3))
    fn = face_normals(xyz, faces)
    for i in range(3):
        np.add.at(acc, faces[:, i], fn)
    return acc / np.maximum(np.linalg.norm(acc, axis=1, keepdims=True), 1e-300)


#: farther than this from the reference (unit-ball frame, 1 % of the diameter: the F-score
#: threshold) a chart is not on the surface and the reference says nothing about its orientation
NEAR = 0.02
#: a reference facet this much against the closest normal (cosine) makes the orientation undecided
UNDECIDED_COS = 0.1


def folded_area(piece: Piece, reference: Reference) -> float:
    """3D area of the piece's faces whose normal disagrees with the reference (at the centroid)."""
    if len(piece.faces) == 0:
        return 0.0
    fn = face_normals(piece.xyz, piece.faces)
    centroid = piece.xyz[piece.faces].mean(1)
    bad = (fn * reference.normal_at(centroid)).sum(1) < 0
    return 0.5 * float(np.linalg.norm(fn[bad], axis=1).sum())


class _Part(NamedTuple):
    """A piece with, per vertex, the reference normal (3) and distance (1) at its closest
    point, and 1 where the reference's orientation is undecided there (0 elsewhere).

    Clipping interpolates them like any attribute, so the reference is projected once per
    piece, not again for every sub-triangle the cuts make.
    """

    piece: Piece
    ref: np.ndarray  # (V, 5)

    @classmethod
    def of(cls, piece: Piece, reference: Reference) -> "_Part":
        n, d = reference.normal_at(piece.xyz, with_distance=True)
        return cls(piece, np.column_stack([n, d, reference.undecided(piece.xyz, n, d)]))

    def face_signs(self) -> np.ndarray:
        """(F,) +1 / -1: face normal with / against the reference; 0 off the surface,
        undecided or degenerate."""
        p = self.piece
        r = self.ref[p.faces].mean(1)
        decided = (r[:, 3] <= NEAR) & (r[:, 4] < 0.5)
        return np.where(decided, np.sign((face_normals(p.xyz, p.faces) * r[:, :3]).sum(1)), 0.0)

    def folded(self) -> float:
        """Area facing against the reference."""
        return float(self.piece.area()[self.face_signs() < 0].sum()) if len(self.piece.faces) else 0.0

    def unfolded(self) -> float:
        """Area facing with the reference: what is folded once the part is reversed."""
        return float(self.piece.area()[self.face_signs() > 0].sum()) if len(self.piece.faces) else 0.0

    def clip(self, field: np.ndarray) -> tuple["_Part", np.ndarray]:
        p = self.piece
        c = clip_mesh(np.column_stack([p.xyz, p.uv, self.ref]), p.faces, field, plane=UV_COLUMNS)
        return _Part(Piece(p.chart, c.attrs[:, :3], c.attrs[:, 3:5], c.faces), c.attrs[:, 5:]), c.source_vertex

    def keep(self, faces: np.ndarray) -> "_Part":
        """Only the faces where ``faces`` (F,) bool is set; unused vertices removed."""
        p = self.piece
        used = np.unique(p.faces[faces])
        remap = np.full(len(p.xyz), -1)
        remap[used] = np.arange(len(used))
        return _Part(Piece(p.chart, p.xyz[used], p.uv[used], remap[p.faces[faces]]), self.ref[used])


def _field(part: _Part) -> np.ndarray:
    p = part.piece
    g = (vertex_normals(p.xyz, p.faces) * part.ref[:, :3]).sum(1)
    far = part.ref[:, 3] > NEAR
    if far.any():
        weight = np.zeros(len(g))
        np.add.at(weight, p.faces.ravel(), np.repeat(p.area(), 3))
        majority = 1.0 if float((np.sign(g) * weight)[~far].sum()) >= 0 else -1.0
        g[far] = majority * 1e-3
    return g


def _small_components(piece: Piece, min_area: float) -> list[tuple[np.ndarray, float]]:
    """(face indices, 3D area) of the piece's UV islands smaller than ``min_area``."""
    if len(piece.faces) == 0:
        return []
    island = uv_islands(piece.faces, piece.uv)
    area = np.bincount(island, weights=piece.area())
    return [(np.flatnonzero(island == i), float(area[i])) for i in np.flatnonzero(area < min_area)]


def _reversed(piece: Piece) -> Piece:
    """Winding reversed (normals flip) and UVs mirrored (UV orientation flips with them)."""
    return Piece(piece.chart, piece.xyz, piece.uv * np.array([-1.0, 1.0]), piece.faces[:, [0, 2, 1]])


def _empty(chart: int) -> Piece:
    return Piece(chart, np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 3), np.int64))


def split_orientation(piece: Piece, reference: Reference, min_area: float, drop_budget: float = 0.0,
                      passes: int = 3, min_island: float | None = None) -> tuple[Piece, Piece, float]:
    """(outward part, inward part reoriented outward, dropped 3D area) of ``piece``.

    Fragments (parts of an island the cut splits off) smaller than ``min_area`` are dropped,
    smallest first, while their total stays within ``drop_budget``; the others are kept
    with their surroundings, or, if at least ``min_island``, reoriented as islands of their
    own. See the module docstring.
    """
    out, back, dropped, *_ = _split(_Part.of(piece, reference), min_area, drop_budget, passes, min_island)
    return out, back, dropped


def _split(whole: _Part, min_area: float, drop_budget: float, passes: int = 3, min_island: float | None = None):
    """(outward piece, reoriented piece, dropped area, folded area before, after, fragments made
    islands of their own) of one part.

    A fragment that the drop budget cannot take stays on its own side as a separate island
    if it is at least ``min_island`` (default: never, it goes with its surroundings)."""
    piece = whole.piece
    if len(piece.faces) == 0:
        return piece, _empty(piece.chart), 0.0, 0.0, 0.0, 0
    before = whole.folded()
    g = _field(whole)
    magnitude = np.maximum(np.abs(g), 1e-6)
    # area of the island of the uncut piece each vertex lies in: a small component that is a
    # whole island (all one sign) is not a fragment of the cut and is reoriented as a whole
    island = uv_islands(piece.faces, piece.uv)
    island_area = np.bincount(island, weights=piece.area())
    vertex_island_area = np.zeros(len(piece.xyz))
    vertex_island_area[piece.faces.ravel()] = np.repeat(island_area[island], 3)
    force = np.zeros(len(g))  # +1 / -1: this vertex keeps that sign whatever g says
    for _ in range(passes):
        sign = np.where(force != 0, force, np.sign(g))
        field = sign * magnitude
        if (field > 0).all():
            return piece, _empty(piece.chart), 0.0, before, before, 0
        if (field < 0).all():
            return _empty(piece.chart), _reversed(piece), 0.0, before, whole.unfolded(), 0
        parts = [whole.clip(field), whole.clip(-field)]
        fragments = []  # (area, part, faces, source vertices, sign to force)
        for i, ((part, src), s) in enumerate(zip(parts, (-1.0, 1.0))):
            decided = part.face_signs() != 0
            for faces, area in _small_components(part.piece, min_area):
                verts = src[np.unique(part.piece.faces[faces])]
                verts = verts[verts >= 0]
                if len(verts) and vertex_island_area[verts].max() > area * (1 + 1e-6):
                    # a fragment mostly where the orientation is undecided is folded by no
                    # measure: kept with its surroundings, it spends none of the drop budget
                    mute = float(part.piece.area()[faces][decided[faces]].sum()) < 0.5 * area
                    fragments.append((area, i, faces, verts, s, mute))
        keep = [np.ones(len(p.piece.faces), bool) for p, _ in parts]
        dropped, changed, own_islands = 0.0, False, 0
        for area, i, faces, verts, s, mute in sorted(fragments, key=lambda f: (f[0], f[1], int(f[2][0]))):
            if not mute and dropped + area <= drop_budget:
                keep[i][faces] = False
                dropped += area
                continue
            if not mute and min_island is not None and area >= min_island:
                own_islands += 1
                continue  # reoriented with its side: an island of its own
            flip = verts[force[verts] != s]
            if len(flip):
                force[flip] = s
                changed = True
        if not changed:
            break
    pos, neg = (p.keep(k) for (p, _), k in zip(parts, keep))
    pos, neg = _settle(pos, neg)
    return pos.piece, _reversed(neg.piece), dropped, before, pos.folded() + neg.unfolded(), own_islands


def _settle(pos: _Part, neg: _Part) -> tuple[_Part, _Part]:
    """Move the sub-triangles on the cut whose own normal disagrees with their side.

    The iso-line of the vertex-normal field crosses a fold's straddling triangles, but each
    sub-triangle keeps its triangle's normal: half of such a triangle lands on the wrong
    side. Sub-triangles with an edge on the cut go to the side their normal agrees with;
    their cut vertices become the other side's (the two clips compute them independently,
    equal only up to rounding), so they join that side's island.
    """
    if len(pos.piece.faces) == 0 or len(neg.piece.faces) == 0:
        return pos, neg
    from scipy.spatial import cKDTree

    def on_cut(p: Piece, other: Piece) -> np.ndarray:
        d, _ = cKDTree(other.uv).query(p.uv, distance_upper_bound=1e-9)
        return np.isfinite(d)[p.faces].sum(1) >= 2  # an edge on the cut: it joins the other side there

    move_pos = on_cut(pos.piece, neg.piece) & (pos.face_signs() < 0)
    move_neg = on_cut(neg.piece, pos.piece) & (neg.face_signs() > 0)
    if not move_pos.any() and not move_neg.any():
        return pos, neg

    def join(dst: _Part, keep: np.ndarray, src: _Part, take: np.ndarray) -> _Part:
        d, s = dst.piece, src.piece
        # the moved faces' cut vertices become the other side's (same index, so every consumer,
        # xatlas included, sees one connected island); their other vertices are appended
        dist, j = cKDTree(d.uv).query(s.uv, distance_upper_bound=1e-9)
        hit = np.isfinite(dist)
        index = np.where(hit, j, len(d.xyz) + np.cumsum(~hit) - 1)
        n_keep = int(keep.sum())
        faces = np.concatenate([d.faces[keep], index[s.faces[take]]])
        both = _Part(Piece(d.chart, np.concatenate([d.xyz, s.xyz[~hit]]), np.concatenate([d.uv, s.uv[~hit]]), faces),
                     np.concatenate([dst.ref, src.ref[~hit]]))
        # a moved sub-triangle must share an edge with a face that stayed (otherwise it would
        # hang on by a corner, or be an island of its own): if not, it is a sliver, drop it
        moved = np.arange(len(faces)) >= n_keep
        edges = np.sort(faces[:, [[0, 1], [1, 2], [2, 0]]], axis=2).reshape(-1, 2)
        key = edges[:, 0] * (len(both.piece.xyz) + 1) + edges[:, 1]
        stayed = np.isin(key, key[: 3 * n_keep]).reshape(-1, 3).any(1)
        return both.keep(~moved | stayed)

    sliver = 1e-5 * (float(pos.piece.area().sum()) + float(neg.piece.area().sum()))
    return tuple(_without_specks(p, sliver) for p in (join(pos, ~move_pos, neg, move_neg),
                                                      join(neg, ~move_neg, pos, move_pos)))


def _without_specks(part: _Part, min_area: float) -> _Part:
    """Drop islands under ``min_area`` (slivers a move split off at the cut)."""
    p = part.piece
    if len(p.faces) == 0:
        return part
    island = uv_islands(p.faces, p.uv)
    small = np.bincount(island, weights=p.area()) < min_area
    return part.keep(~small[island]) if small.any() else part


def _split_job(k: int, shared):
    pieces, reference, min_area, max_dropped_fraction, min_fragment_island = shared
    p = pieces[k]
    return _split(_Part.of(p, reference), min_area, max_dropped_fraction * float(p.area().sum()),
                  min_island=min_fragment_island)


def orient_pieces(pieces: list[Piece], reference: Reference, min_area: float,
                  max_dropped_fraction: float = 2.5e-3,
                  min_fragment_island: float | None = None) -> tuple[list[Piece], dict]:
    """Every piece split by :func:`split_orientation`; stats in percent of the total area.

    Fragments may be dropped up to ``max_dropped_fraction`` of each piece's area. The
    folded areas in the stats use the reference normal interpolated from the vertices
    (the harness measures the final mesh exactly).

    The result lists the outward parts first (chart order), then the reoriented ones, and
    drops empty parts; a chart may now own two pieces.
    """
    total = max(sum(float(p.area().sum()) for p in pieces), 1e-300)
    outward, inward, dropped, before, after, own = [], [], 0.0, 0.0, 0.0, 0
    # pieces are independent: split in parallel processes, the reference shared by the fork
    shared = (pieces, reference, min_area, max_dropped_fraction, min_fragment_island)
    splits = parallel_map(_split_job, list(range(len(pieces))), shared=shared,
                          parallel=sum(len(p.faces) for p in pieces) >= parallel.MIN_FACES)
    for a, b, d, f, g, k in splits:
        outward.append(a)
        inward.append(b)
        dropped += d
        before += f
        after += g
        own += k
    out = [p for p in outward + inward if len(p.faces)]
    stats = {
        "folded_percent_before_orient": 100.0 * before / total,
        "reoriented_percent": 100.0 * sum(float(p.area().sum()) for p in inward) / total,
        "folded_percent": 100.0 * after / total,
        "orient_dropped_percent": 100.0 * dropped / total,
        "orient_fragment_island_count": own,
    }
    return out, stats
