"""Smooth shading normals for export: one normal per smoothing group, split only at creases.

A *smoothing group* at a 3D point is a set of its face corners connected through shared
edges whose dihedral angle is below ``CREASE_DEGREES``; each group gets the angle-weighted
mean of its faces' normals. Groups are built on welded 3D points (``uvmesh.weld_ids``), so
the seam copies of a vertex (one per UV island) lie in one group and get the same normal:
a UV seam never shows in the shading. A vertex is duplicated only where a crease runs
through it (its corners fall in two groups).

Example: a cube (8 points, 90 degree edges) gets 24 vertices, 3 per corner, each with its
face's normal; a finely sampled sphere keeps its vertex count with normals ``= position``.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from .islands import half_edges

#: edges whose faces meet at more than this angle stay sharp. A curved surface sampled with
#: at least 8 triangles around a full turn bends under 45 degrees per edge, so only edges
#: made sharp on purpose (a box's, a blade's) exceed it.
CREASE_DEGREES = 45.0


class Shading(NamedTuple):
    """Output of :func:`shading_normals`."""

    source: np.ndarray  # (V',) input vertex each output vertex copies
    faces: np.ndarray  # (F, 3) faces on the output vertices (same order and winding)
    normals: np.ndarray  # (V', 3) unit normals


def face_normals_angles(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """((F, 3) unit face normals (zero for degenerate faces), (F, 3) corner angles in radians)."""
    t = np.asarray(vertices, np.float64)[faces]
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, length, out=np.zeros_like(n), where=length > 0)
    e1 = np.roll(t, -1, axis=1) - t  # corner c -> c+1
    e2 = np.roll(t, 1, axis=1) - t  # corner c -> c-1
    cos = (e1 * e2).sum(-1) / np.maximum(np.linalg.norm(e1, axis=-1) * np.linalg.norm(e2, axis=-1), 1e-300)
    return n, np.arccos(np.clip(cos, -1.0, 1.0))


def shading_normals(vertices: np.ndarray, faces: np.ndarray, weld: np.ndarray,
                    crease_degrees: float = CREASE_DEGREES) -> Shading:
    """Smoothing-group normals of ``(vertices (V, 3), faces (F, 3))``; ``weld (V,)`` 3D point ids.

    Returns the output vertices as indices into the input (``source``), the faces on them
    and unit normals. Output vertex order: by (input vertex, group), so a mesh without
    creases keeps its vertices in their order.
    """
    faces = np.asarray(faces, np.int64)
    F = len(faces)
    normal, angle = face_normals_angles(vertices, faces)
    corner_point = weld[faces].reshape(-1)  # (3F,) corner c of face f is 3 f + c
    # corners of two faces sharing a welded edge join when the faces bend less than the crease
    he = weld[half_edges(faces)]  # (3F, 2): edge (c, c+1) of each face
    lo, hi = he.min(1), he.max(1)
    key = lo * (int(weld.max()) + 1) + hi
    order = np.argsort(key, kind="stable")
    ks = key[order]
    pairs = np.flatnonzero(ks[1:] == ks[:-1])  # consecutive half-edges on one edge (fans too)
    h1, h2 = order[pairs], order[pairs + 1]
    f1, f2 = h1 // 3, h2 // 3
    smooth = (normal[f1] * normal[f2]).sum(1) >= np.cos(np.radians(crease_degrees))
    smooth &= f1 != f2
    h1, h2 = h1[smooth], h2[smooth]
    # half-edge h = (corner h, corner next(h)); join the corners that sit on the same point
    a1, b1 = h1, 3 * (h1 // 3) + (h1 + 1) % 3
    a2, b2 = h2, 3 * (h2 // 3) + (h2 + 1) % 3
    same = corner_point[a1] == corner_point[a2]
    rows = np.concatenate([a1, b1])
    cols = np.concatenate([np.where(same, a2, b2), np.where(same, b2, a2)])
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(3 * F, 3 * F))
    _, group = connected_components(graph, directed=False)
    acc = np.zeros((int(group.max()) + 1 if F else 0, 3))
    np.add.at(acc, group, np.repeat(normal, 3, axis=0) * angle.reshape(-1, 1))
    length = np.linalg.norm(acc, axis=1, keepdims=True)
    # a group of degenerate faces only: any unit vector is as good as another
    acc = np.where(length > 0, acc / np.maximum(length, 1e-300), np.array([0.0, 0.0, 1.0]))
    # output vertex = (input vertex, group); a vertex splits only where groups differ
    pair = np.stack([faces.reshape(-1), group], 1)
    uniq, inverse = np.unique(pair, axis=0, return_inverse=True)
    return Shading(uniq[:, 0], inverse.reshape(-1, 3), acc[uniq[:, 1]])


def open_surface(faces: np.ndarray, weld: np.ndarray) -> bool:
    """True when some welded edge is used by one face only (the surface has a border)."""
    from .islands import edge_keys, edge_use_counts

    return bool((edge_use_counts(edge_keys(weld, np.asarray(faces, np.int64))) == 1).any())
