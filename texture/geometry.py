"""Point-to-mesh projection, surface sampling and boundary edges (numpy + scipy only).

``MeshProjector`` finds, for query points, the closest point on a triangle mesh: a
KD-tree over triangle centroids proposes ``k`` candidate triangles, and the exact
point-triangle closest point (Ericson, *Real-Time Collision Detection*, 5.1.5) picks
the best. With ``k`` large enough for the mesh's triangle sizes it is exact; the
default is generous for the near-uniform meshes used here.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from .islands import edge_keys, edge_use_counts, half_edges


def triangle_areas(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Per-face area (F,) of triangles ``points[faces]``; points (V, 2) or (V, 3)."""
    p = np.asarray(points, np.float64)
    a, b, c = p[faces[:, 0]], p[faces[:, 1]], p[faces[:, 2]]
    if p.shape[1] == 2:
        e1, e2 = b - a, c - a
        return 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


def closest_point_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray):
    """Closest point of each triangle ``(a, b, c)`` to ``p``, all (N, 3); returns (point, bary (N, 3))."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(1), (ac * ap).sum(1)
    bp = p - b
    d3, d4 = (ab * bp).sum(1), (ac * bp).sum(1)
    cp = p - c
    d5, d6 = (ab * cp).sum(1), (ac * cp).sum(1)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    n = len(p)
    bary = np.zeros((n, 3))
    done = np.zeros(n, bool)

    def put(mask, w0, w1, w2):
        m = mask & ~done
        bary[m, 0], bary[m, 1], bary[m, 2] = w0[m], w1[m], w2[m]
        done[m] = True

    one, zero = np.ones(n), np.zeros(n)
    with np.errstate(divide="ignore", invalid="ignore"):
        put((d1 <= 0) & (d2 <= 0), one, zero, zero)  # vertex a
        put((d3 >= 0) & (d4 <= d3), zero, one, zero)  # vertex b
        put((d6 >= 0) & (d5 <= d6), zero, zero, one)  # vertex c
        v = d1 / (d1 - d3)
        put((vc <= 0) & (d1 >= 0) & (d3 <= 0), 1 - v, v, zero)  # edge ab
        w = d2 / (d2 - d6)
        put((vb <= 0) & (d2 >= 0) & (d6 <= 0), 1 - w, zero, w)  # edge ac
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        put((va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0), zero, 1 - w, w)  # edge bc
        denom = va + vb + vc
        v, w = vb / denom, vc / denom
        put(np.ones(n, bool), 1 - v - w, v, w)  # interior
    bary = np.nan_to_num(bary, nan=1.0 / 3.0)
    point = bary[:, :1] * a + bary[:, 1:2] * b + bary[:, 2:] * c
    return point, bary


class Projection(NamedTuple):
    point: np.ndarray  # (N, 3) closest point on the mesh
    distance: np.ndarray  # (N,)
    face: np.ndarray  # (N,) face holding the closest point
    bary: np.ndarray  # (N, 3) its barycentric coordinates in that face
    on_boundary: np.ndarray  # (N,) bool: closest point lies on an open-boundary edge


class MeshProjector:
    """Closest points on a fixed triangle mesh ``(vertices (V,3), faces (F,3))``."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, k: int = 16):
        self.vertices = np.asarray(vertices, np.float64)
        self.faces = np.asarray(faces, np.int64)
        self.k = int(min(k, len(self.faces)))
        tri = self.vertices[self.faces]
        centroid = tri.mean(1)
        self.tree = cKDTree(centroid)
        #: largest centroid-to-corner distance: a point within d of a face is within d + this of its centroid
        self.radius = float(np.linalg.norm(tri - centroid[:, None], axis=2).max()) if len(tri) else 0.0
        keys = edge_keys(np.arange(len(self.vertices)), self.faces)
        # boundary[f, i]: the edge opposite corner i of face f is used by one face only
        open_edge = (edge_use_counts(keys) == 1).reshape(-1, 3)  # edge j joins corners j, j+1
        self.boundary = open_edge[:, [1, 2, 0]]

    def project(self, points: np.ndarray, max_distance: float | None = None, chunk: int = 200_000) -> Projection:
        """Closest points; with ``max_distance`` points farther than it get ``distance = inf``, face -1.

        The bound makes far queries cheap (a KD-tree k-NN search far from the data is slow).
        """
        points = np.asarray(points, np.float64)
        parts = [self._project(points[i:i + chunk], max_distance) for i in range(0, max(len(points), 1), chunk)]
        return Projection(*(np.concatenate([p[j] for p in parts]) for j in range(5)))

    def _project(self, p: np.ndarray, max_distance: float | None):
        n, k = len(p), self.k
        empty = (np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0, bool))
        if n == 0:
            return empty
        if max_distance is not None:
            _, cand = self.tree.query(p, k=k, distance_upper_bound=max_distance + self.radius)
            cand = cand.reshape(n, k)
            near = cand[:, 0] < len(self.faces)
            out = (np.zeros((n, 3)), np.full(n, np.inf), np.full(n, -1), np.zeros((n, 3)), np.zeros(n, bool))
            if near.any():
                sub = self._exact(p[near], np.where(cand[near] < len(self.faces), cand[near], cand[near][:, :1]))
                for o, v in zip(out, sub):
                    o[near] = v
                out[1][near & (out[1] > max_distance)] = np.inf
            return out
        _, cand = self.tree.query(p, k=k)
        return self._exact(p, cand.reshape(n, k))

    def _exact(self, p: np.ndarray, cand: np.ndarray):
        n, k = cand.shape
        tri = self.vertices[self.faces[cand.ravel()]]
        q, bary = closest_point_on_triangles(np.repeat(p, k, 0), tri[:, 0], tri[:, 1], tri[:, 2])
        d = np.linalg.norm(q - np.repeat(p, k, 0), axis=1).reshape(n, k)
        best = d.argmin(1)
        sel = np.arange(n) * k + best
        face = cand[np.arange(n), best]
        bary = bary[sel]
        on_edge = bary < 1e-9
        on_boundary = (on_edge & self.boundary[face]).any(1)
        return q[sel], d[np.arange(n), best], face, bary, on_boundary


def sample_surface(vertices: np.ndarray, faces: np.ndarray, count: int, seed: int = 0):
    """``count`` points uniform on the surface (area-weighted), seeded; returns (points, face)."""
    vertices = np.asarray(vertices, np.float64)
    tri = vertices[np.asarray(faces, np.int64)]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    rng = np.random.default_rng(seed)
    face = rng.choice(len(tri), size=count, p=area / area.sum())
    r1, r2 = rng.random(count), rng.random(count)
    s = np.sqrt(r1)
    w = np.stack([1 - s, s * (1 - r2), s * r2], 1)
    return (w[:, :, None] * tri[face]).sum(1), face


def boundary_segments(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(S, 2, 3) open-boundary edges (used by one face) of a mesh, after welding positions."""
    from .uvmesh import weld_ids

    vertices = np.asarray(vertices, np.float64)
    ids = weld_ids(vertices)
    keys = edge_keys(ids, faces)
    open_ = edge_use_counts(keys) == 1
    return vertices[half_edges(faces)[open_]]


def distance_to_segments(points: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """(N,) distance from each point to the nearest of ``segments (S, 2, 3)`` (inf if S = 0)."""
    points = np.asarray(points, np.float64)
    if len(segments) == 0:
        return np.full(len(points), np.inf)
    mid = segments.mean(1)
    k = min(8, len(segments))
    _, cand = cKDTree(mid).query(points, k=k)
    cand = cand.reshape(len(points), k)
    a, b = segments[cand, 0], segments[cand, 1]  # (N, k, 3)
    ab = b - a
    t = ((points[:, None] - a) * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-300)
    q = a + np.clip(t, 0, 1)[..., None] * ab
    return np.linalg.norm(points[:, None] - q, axis=-1).min(1)
