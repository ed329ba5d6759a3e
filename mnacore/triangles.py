"""Per-triangle geometry: areas, signed UV areas, unit normals. One formula each, vectorised.

Shapes: ``points (V, 2)`` or ``(V, 3)``, ``faces (F, 3)`` int; results per face ``(F,)`` or
``(F, 3)``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def triangle_areas(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Per-face area (F,) of triangles ``points[faces]``; points (V, 2) or (V, 3).

    Example: the unit right triangle ``(0,0) (1,0) (0,1)`` has area 0.5.
    """
    p = np.asarray(points, np.float64)
    a, b, c = p[faces[:, 0]], p[faces[:, 1]], p[faces[:, 2]]
    if p.shape[1] == 2:
        return np.abs(signed_areas(p, faces))
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


def signed_areas(uv: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F,) signed area of 2D triangles: positive when counter-clockwise (u right, v up).

    Example: ``(0,0) (1,0) (0,1)`` gives +0.5, ``(0,0) (0,1) (1,0)`` gives -0.5.
    """
    t = np.asarray(uv, np.float64)[faces]
    e1, e2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    return 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])


def face_normals(points: np.ndarray, faces: np.ndarray, unit: bool = True) -> np.ndarray:
    """(F, 3) normals of 3D triangles by the right-hand rule: unit (zero for degenerate faces),
    or with ``unit=False`` of length twice the area (for area-weighted vertex normals)."""
    t = np.asarray(points, np.float64)[faces]
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    if not unit:
        return n
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0)


def isometric_triangle(p: np.ndarray) -> np.ndarray:
    """(3, 2) a triangle with the 3D corners ``p (3, 3)``'s edge lengths, counter-clockwise:
    ``(0, 0)``, ``(|p1 - p0|, 0)`` and the third corner by projection onto edge 01."""
    e1, e2 = p[1] - p[0], p[2] - p[0]
    length = float(np.linalg.norm(e1))
    x = float(e1 @ e2) / max(length, 1e-300)
    y = float(np.sqrt(max(float(e2 @ e2) - x * x, 0.0)))
    return np.array([[0.0, 0.0], [length, 0.0], [x, y]])


def half_edges(faces: np.ndarray) -> np.ndarray:
    """(3F, 2) directed edges ``(f0,f1), (f1,f2), (f2,f0)`` of each face, face-major."""
    faces = np.asarray(faces, np.int64)
    return np.stack([faces, np.roll(faces, -1, axis=1)], -1).reshape(-1, 2)


@dataclass(frozen=True)
class EdgePairs:
    """How the faces of a mesh meet along their edges (vertex indices, not positions)."""

    half_edges: np.ndarray
    """(3F, 2) :func:`half_edges`; half-edge ``h`` is corner ``h % 3`` of face ``h // 3``"""
    a: np.ndarray
    """(P,) one half-edge of each edge used by exactly two faces (and of each pair matched
    on an edge of more faces, where :func:`edge_pairs` had normals)"""
    b: np.ndarray
    """(P,) the other"""
    nonmanifold: int
    """edges used by more than two faces"""
    boundary: int
    """edges used by one face"""
    matched: int = 0
    """pairs of faces matched on edges of more than two faces (:func:`edge_pairs`)"""

    def disagreeing_faces(self) -> np.ndarray:
        """Faces on an edge of two faces that both run it the same way (wound against each other)."""
        same = self.half_edges[self.a, 0] == self.half_edges[self.b, 0]
        return np.unique(np.r_[self.a[same], self.b[same]] // 3)


def _matched(he: np.ndarray, order: np.ndarray, starts: np.ndarray, counts: np.ndarray,
             normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(a, b): on each edge of more than two faces (the half-edges ``order[s:s + c]`` for
    each start ``s`` and count ``c > 2``, as :func:`edge_pairs` sorted them), the faces
    running it one way matched to those running it the other way so that matched faces'
    ``normals`` agree most (sum of dot products; a face left over stays unmatched).

    A double-sided surface (each face beside a copy wound the other way, on the same
    vertices) has four faces on every edge: its front faces match each other (dot about 1)
    and its back faces each other, where a front face and its own back copy (dot -1) would
    fold the surface onto itself. A fin on a sheet keeps the sheet joined and the fin apart."""
    from scipy.optimize import linear_sum_assignment

    a, b = [], []
    rest = [order[s:s + c] for s, c in zip(starts[counts > 4], counts[counts > 4])]
    rest += list(order[starts[counts == 3][:, None] + np.arange(3)])
    four = starts[counts == 4]
    if len(four):  # the usual case (double-sided): two faces each way, two matchings, vectorised
        h = order[four[:, None] + np.arange(4)]
        fwd = he[h, 0] < he[h, 1]
        balanced = fwd.sum(1) == 2
        rest += list(h[~balanced])
        h, fwd = h[balanced], fwd[balanced]
        o = np.argsort(~fwd, axis=1, kind="stable")  # the two forward half-edges first
        p1, p2, m1, m2 = (np.take_along_axis(h, o[:, k:k + 1], 1)[:, 0] for k in range(4))
        n = normals
        straight = (n[p1 // 3] * n[m1 // 3]).sum(1) + (n[p2 // 3] * n[m2 // 3]).sum(1)
        crossed = (n[p1 // 3] * n[m2 // 3]).sum(1) + (n[p2 // 3] * n[m1 // 3]).sum(1)
        swap = crossed > straight
        a += [p1, p2]
        b += [np.where(swap, m2, m1), np.where(swap, m1, m2)]
    for g in rest:
        fwd = he[g, 0] < he[g, 1]
        p, m = g[fwd], g[~fwd]
        if len(p) and len(m):
            i, j = linear_sum_assignment(-(normals[p // 3] @ normals[m // 3].T))
            a.append(p[i])
            b.append(m[j])
    empty = np.zeros(0, np.int64)
    return (np.concatenate(a) if a else empty), (np.concatenate(b) if b else empty)


def edge_pairs(faces: np.ndarray, normals: np.ndarray | None = None) -> EdgePairs:
    """:class:`EdgePairs` of ``faces`` (one sort of the half-edges by their undirected edge).
    With the faces' unit ``normals (F, 3)``, the faces on an edge of more than two faces are
    matched in opposite-running pairs too (:func:`_matched`); without, such an edge pairs
    nothing."""
    he = half_edges(faces)
    n = int(he.max()) + 1 if len(he) else 1
    key = he.min(1) * n + he.max(1)
    order = np.argsort(key, kind="stable")
    ks = key[order]
    starts = np.r_[0, np.flatnonzero(ks[1:] != ks[:-1]) + 1] if len(ks) else np.zeros(0, np.int64)
    counts = np.diff(np.r_[starts, len(ks)])
    pair = starts[counts == 2]
    a, b = order[pair], order[pair + 1]
    many = np.flatnonzero(counts > 2)
    matched = 0
    if normals is not None and len(many):
        ma, mb = _matched(he, order, starts, counts, normals)
        a, b, matched = np.r_[a, ma], np.r_[b, mb], len(ma)
    return EdgePairs(he, a, b, int(len(many)), int((counts == 1).sum()), matched)


def consistent_winding(faces: np.ndarray, area: np.ndarray, pairs: EdgePairs | None = None) -> np.ndarray:
    """(F,) bool: the faces to turn (swap corners 1 and 2) so that each orientable patch
    (faces joined through edges of two faces: libigl's ``bfs_orient``) is wound one way,
    the way of most of its ``area``. A consistently wound mesh turns no face, and neither
    does a patch no winding makes consistent (a Mobius strip: turning faces would only move
    the edges where it disagrees), nor a face with a repeated index (degenerate). ``faces``
    index welded vertices; ``pairs``: their :func:`edge_pairs`, where the caller has them."""
    import igl

    faces = np.ascontiguousarray(faces, np.int64)
    turned = np.zeros(len(faces), bool)
    pairs = edge_pairs(faces) if pairs is None else pairs
    if len(faces) == 0 or len(pairs.disagreeing_faces()) == 0:  # wound consistently already (the usual case)
        return turned
    ok = np.flatnonzero((faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2]))
    f = faces[ok]
    oriented, patch = igl.bfs_orient(f)
    # bfs_orient reverses a face it turns: a face kept is a rotation of the input
    kept = np.zeros(len(f), bool)
    for k in range(3):
        kept |= (oriented == np.roll(f, k, axis=1)).all(1)
    against = np.bincount(patch, weights=np.where(kept, 0.0, area[ok]), minlength=int(patch.max()) + 1)
    total = np.bincount(patch, weights=area[ok], minlength=int(patch.max()) + 1)
    turn = ~kept ^ (against > 0.5 * total)[patch]
    wound = f.copy()
    wound[turn] = wound[turn][:, [0, 2, 1]]
    turned[ok] = turn & ~np.isin(patch, patch[edge_pairs(wound).disagreeing_faces()])
    return turned
