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
"""
from __future__ import annotations

import numpy as np

from .clip import clip_mesh
from .geometry import MeshProjector
from .islands import uv_islands
from .trim import Piece, _drop_faces


class Reference:
    """A reference surface with unit vertex normals, in the unit-ball frame."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray):
        self.projector = MeshProjector(np.asarray(vertices, np.float64), np.asarray(faces, np.int64))
        n = np.asarray(normals, np.float64)
        self.normals = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)

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
#: threshold) a chart is
#: not on the surface and the reference says nothing about its orientation
NEAR = 0.02


def orientation_field(piece: Piece, reference: Reference) -> np.ndarray:
    """(V,) cosine between the piece's vertex normal and the reference normal there.

    Vertices farther than ``NEAR`` from the reference take the sign of the piece's
    majority (near vertices, area-weighted), so a chart that is off the surface is never cut.
    """
    vn = vertex_normals(piece.xyz, piece.faces)
    rn, dist = reference.normal_at(piece.xyz, with_distance=True)
    g = (vn * rn).sum(1)
    far = dist > NEAR
    if far.any():
        weight = np.zeros(len(g))
        np.add.at(weight, piece.faces.ravel(), np.repeat(piece.area(), 3))
        majority = 1.0 if float((np.sign(g) * weight)[~far].sum()) >= 0 else -1.0
        g[far] = majority * 1e-3
    return g


def folded_area(piece: Piece, reference: Reference) -> float:
    """3D area of the piece's faces whose normal disagrees with the reference (at the centroid)."""
    if len(piece.faces) == 0:
        return 0.0
    fn = face_normals(piece.xyz, piece.faces)
    centroid = piece.xyz[piece.faces].mean(1)
    bad = (fn * reference.normal_at(centroid)).sum(1) < 0
    return 0.5 * float(np.linalg.norm(fn[bad], axis=1).sum())


def _clip(piece: Piece, field: np.ndarray) -> tuple[Piece, np.ndarray]:
    c = clip_mesh(np.column_stack([piece.xyz, piece.uv]), piece.faces, field)
    return Piece(piece.chart, c.attrs[:, :3], c.attrs[:, 3:5], c.faces), c.source_vertex


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


def split_orientation(piece: Piece, reference: Reference, min_area: float, drop_budget: float = 0.0,
                      passes: int = 3) -> tuple[Piece, Piece, float]:
    """(outward part, inward part reoriented outward, dropped 3D area) of ``piece``.

    Fragments (parts of an island the cut splits off) smaller than ``min_area`` are dropped,
    smallest first, while their total stays within ``drop_budget``; the others are kept
    with their surroundings. See the module docstring.
    """
    empty = Piece(piece.chart, np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 3), np.int64))
    if len(piece.faces) == 0:
        return piece, empty, 0.0
    g = orientation_field(piece, reference)
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
            return piece, empty, 0.0
        if (field < 0).all():
            return empty, _reversed(piece), 0.0
        parts = [_clip(piece, field), _clip(piece, -field)]
        fragments = []  # (area, part, faces, source vertices, sign to force)
        for i, ((part, src), s) in enumerate(zip(parts, (-1.0, 1.0))):
            for faces, area in _small_components(part, min_area):
                verts = src[np.unique(part.faces[faces])]
                verts = verts[verts >= 0]
                if len(verts) and vertex_island_area[verts].max() > area * (1 + 1e-6):
                    fragments.append((area, i, faces, verts, s))
        keep = [np.ones(len(p.faces), bool) for p, _ in parts]
        dropped, changed = 0.0, False
        for area, i, faces, verts, s in sorted(fragments, key=lambda f: (f[0], f[1], int(f[2][0]))):
            if dropped + area <= drop_budget:
                keep[i][faces] = False
                dropped += area
                continue
            flip = verts[force[verts] != s]
            if len(flip):
                force[flip] = s
                changed = True
        if not changed:
            break
    pos, neg = (_drop_faces(p, k) if not k.all() else p for (p, _), k in zip(parts, keep))
    pos, neg = _settle(pos, neg, reference)
    return pos, _reversed(neg), dropped


def _face_signs(piece: Piece, reference: Reference) -> np.ndarray:
    """(F,) +1 / -1: face normal with / against the reference; 0 off the surface or degenerate."""
    fn = face_normals(piece.xyz, piece.faces)
    rn, dist = reference.normal_at(piece.xyz[piece.faces].mean(1), with_distance=True)
    return np.where(dist <= NEAR, np.sign((fn * rn).sum(1)), 0.0)


def _settle(pos: Piece, neg: Piece, reference: Reference) -> tuple[Piece, Piece]:
    """Move the sub-triangles on the cut whose own normal disagrees with their side.

    The iso-line of the vertex-normal field crosses a fold's straddling triangles, but each
    sub-triangle keeps its triangle's normal: half of such a triangle lands on the wrong
    side. Sub-triangles touching the cut go to the side their normal agrees with; their cut
    vertices are snapped onto the other side's (the two clips compute them independently,
    equal only up to rounding), so they join that side's island.
    """
    if len(pos.faces) == 0 or len(neg.faces) == 0:
        return pos, neg
    from scipy.spatial import cKDTree

    def on_cut(p: Piece, other: Piece) -> np.ndarray:
        tree = cKDTree(other.uv)
        d, _ = tree.query(p.uv, distance_upper_bound=1e-9)
        return np.isfinite(d)[p.faces].sum(1) >= 2  # an edge on the cut: it joins the other side there

    move_pos = on_cut(pos, neg) & (_face_signs(pos, reference) < 0)
    move_neg = on_cut(neg, pos) & (_face_signs(neg, reference) > 0)
    if not move_pos.any() and not move_neg.any():
        return pos, neg

    def join(dst: Piece, keep: np.ndarray, src: Piece, take: np.ndarray) -> Piece:
        xyz, uv = src.xyz.copy(), src.uv.copy()
        d, j = cKDTree(dst.uv).query(uv, distance_upper_bound=1e-9)
        hit = np.isfinite(d)
        xyz[hit], uv[hit] = dst.xyz[j[hit]], dst.uv[j[hit]]
        both = Piece(dst.chart, np.concatenate([dst.xyz, xyz]), np.concatenate([dst.uv, uv]),
                     np.concatenate([dst.faces[keep], src.faces[take] + len(dst.xyz)]))
        # a moved sub-triangle that joins no island of its new side (rare: its neighbour across
        # the cut moved too) would be an island of its own: it is a sliver, drop it
        moved = np.arange(len(both.faces)) >= int(keep.sum())
        island = uv_islands(both.faces, both.uv)
        alone = np.bincount(island, weights=~moved, minlength=int(island.max()) + 1) == 0
        return _drop_faces(both, ~alone[island])

    sliver = 1e-5 * (float(pos.area().sum()) + float(neg.area().sum()))
    return tuple(_without_specks(p, sliver) for p in (join(pos, ~move_pos, neg, move_neg),
                                                      join(neg, ~move_neg, pos, move_pos)))


def _without_specks(piece: Piece, min_area: float) -> Piece:
    """Drop islands under ``min_area`` (slivers a move split off at the cut)."""
    if len(piece.faces) == 0:
        return piece
    island = uv_islands(piece.faces, piece.uv)
    small = np.bincount(island, weights=piece.area()) < min_area
    return _drop_faces(piece, ~small[island]) if small.any() else piece


def orient_pieces(pieces: list[Piece], reference: Reference, min_area: float,
                  max_dropped_fraction: float = 2.5e-3) -> tuple[list[Piece], dict]:
    """Every piece split by :func:`split_orientation`; stats in percent of the total area.

    Fragments may be dropped up to ``max_dropped_fraction`` of each piece's area.

    The result lists the outward parts first (chart order), then the reoriented ones, and
    drops empty parts; a chart may now own two pieces.
    """
    total = max(sum(float(p.area().sum()) for p in pieces), 1e-300)
    before = sum(folded_area(p, reference) for p in pieces)
    outward, inward, dropped = [], [], 0.0
    for p in pieces:
        a, b, d = split_orientation(p, reference, min_area, max_dropped_fraction * float(p.area().sum()))
        outward.append(a)
        inward.append(b)
        dropped += d
    out = [p for p in outward + inward if len(p.faces)]
    stats = {
        "folded_percent_before_orient": 100.0 * before / total,
        "reoriented_percent": 100.0 * sum(float(p.area().sum()) for p in inward) / total,
        "folded_percent": 100.0 * sum(folded_area(p, reference) for p in out) / total,
        "orient_dropped_percent": 100.0 * dropped / total,
    }
    return out, stats
