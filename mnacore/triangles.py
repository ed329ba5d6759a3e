"""Per-triangle geometry: areas, signed UV areas, unit normals. One formula each, vectorised.

Shapes: ``points (V, 2)`` or ``(V, 3)``, ``faces (F, 3)`` int; results per face ``(F,)`` or
``(F, 3)``.
"""
from __future__ import annotations

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


def consistent_winding(faces: np.ndarray, area: np.ndarray) -> np.ndarray:
    """(F,) bool: the faces to turn (swap corners 1 and 2) so that each orientable patch
    (faces joined through edges of two faces: libigl's ``bfs_orient``) is wound one way,
    the way of most of its ``area``. A consistently wound mesh turns no face, and neither
    does a patch no winding makes consistent (a Mobius strip: turning faces would only move
    the edges where it disagrees). ``faces`` index welded vertices (a face with a repeated
    index is degenerate: leave it out)."""
    import igl

    faces = np.ascontiguousarray(faces, np.int64)
    if len(faces) == 0 or len(_disagreeing_faces(faces)) == 0:  # wound consistently already (the usual case)
        return np.zeros(len(faces), bool)
    oriented, patch = igl.bfs_orient(faces)
    # bfs_orient reverses a face it turns: a face kept is a rotation of the input
    kept = np.zeros(len(faces), bool)
    for k in range(3):
        kept |= (oriented == np.roll(faces, k, axis=1)).all(1)
    against = np.bincount(patch, weights=np.where(kept, 0.0, area), minlength=int(patch.max()) + 1)
    total = np.bincount(patch, weights=area, minlength=int(patch.max()) + 1)
    turned = ~kept ^ (against > 0.5 * total)[patch]
    wound = faces.copy()
    wound[turned] = wound[turned][:, [0, 2, 1]]
    return turned & ~np.isin(patch, patch[_disagreeing_faces(wound)])


def _disagreeing_faces(faces: np.ndarray) -> np.ndarray:
    """Faces on an edge that two faces run in the same direction (used by exactly two faces)."""
    he = np.stack([faces, np.roll(faces, -1, axis=1)], -1).reshape(-1, 2)
    n = int(faces.max()) + 1
    key = he.min(1) * n + he.max(1)
    order = np.argsort(key, kind="stable")
    ks = key[order]
    starts = np.r_[0, np.flatnonzero(ks[1:] != ks[:-1]) + 1]
    counts = np.diff(np.r_[starts, len(ks)])
    a, b = order[starts[counts == 2]], order[starts[counts == 2] + 1]
    same = he[a, 0] == he[b, 0]
    return np.unique(np.r_[a[same], b[same]] // 3)
