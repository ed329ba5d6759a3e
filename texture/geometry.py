"""Point-to-mesh projection, surface sampling and boundary edges.

``MeshProjector`` finds, for query points, the exact closest point on a triangle mesh of
any triangle sizes (libigl's AABB tree), and every triangle within a radius of a point (a
KD-tree over proxy points: triangle centroids, large triangles subdivided, and an exact
point-triangle test).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from mnacore.triangles import triangle_areas

from .islands import edge_keys, edge_use_counts, half_edges


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


def _proxies(tri: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Points standing in for the triangles ``tri (F, 3, 3)`` in a KD-tree: (points (P, 3), face (P,)).

    A triangle whose centroid-to-corner distance ``r`` is at most ``radius`` is its centroid;
    a larger one is split into ``m^2`` similar sub-triangles (``m = ceil(r / radius)``, the
    regular ``m``-subdivision) and stands in as their centroids. Every point of a triangle
    then lies within ``radius`` of one of its proxies.
    """
    centroid = tri.mean(1)
    r = np.linalg.norm(tri - centroid[:, None], axis=2).max(1)
    m = np.maximum(np.ceil(r / radius - 1e-9), 1).astype(np.int64)
    points, face = [centroid[m == 1]], [np.flatnonzero(m == 1)]
    for mm in np.unique(m[m > 1]):
        f = np.flatnonzero(m == mm)
        i, j = np.meshgrid(np.arange(mm), np.arange(mm), indexing="ij")
        up = (i + j <= mm - 1).ravel()
        down = (i + j <= mm - 2).ravel()
        # barycentric (w1, w2) of the sub-triangle centroids: "up" ones and inverted ones
        w = np.concatenate([np.stack([i.ravel()[up] + 1 / 3, j.ravel()[up] + 1 / 3], 1),
                            np.stack([i.ravel()[down] + 2 / 3, j.ravel()[down] + 2 / 3], 1)]) / mm
        t = tri[f]  # (n, 3, 3)
        e1, e2 = t[:, None, 1] - t[:, None, 0], t[:, None, 2] - t[:, None, 0]
        pts = t[:, None, 0] + w[None, :, :1] * e1 + w[None, :, 1:] * e2
        points.append(pts.reshape(-1, 3))
        face.append(np.repeat(f, len(w)))
    return np.concatenate(points), np.concatenate(face)


class MeshProjector:
    """Exact closest points on a fixed triangle mesh ``(vertices (V,3), faces (F,3))``.

    :meth:`project` asks libigl's AABB tree (``igl.AABB.squared_distance``: exact, any
    triangle sizes) for the nearest face of each point, and takes the point and its
    barycentric coordinates on that face from the exact point-triangle closest point
    (Ericson, *Real-Time Collision Detection*, 5.1.5), whose regions give exact zeros on
    edges and corners (the open-border test needs them). A KD-tree of proxy points
    (:func:`_proxies`) serves :meth:`faces_within`, the ball queries the tree has no call
    for; it is built on first use.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, max_proxies: int | None = None):
        self.vertices = np.asarray(vertices, np.float64)
        self.faces = np.asarray(faces, np.int64)
        self._max_proxies = max_proxies
        self._tree = self._aabb = None  # built on first use (and again after unpickling)
        keys = edge_keys(np.arange(len(self.vertices)), self.faces)
        # boundary[f, i]: the edge opposite corner i of face f is used by one face only
        open_edge = (edge_use_counts(keys) == 1).reshape(-1, 3)  # edge j joins corners j, j+1
        self.boundary = open_edge[:, [1, 2, 0]]

    def __getstate__(self) -> dict:
        # libigl's tree does not pickle (projectors are shared with worker processes)
        return {**self.__dict__, "_aabb": None, "_tree": None}

    @property
    def aabb(self):
        """libigl's AABB tree of the faces (None for a mesh without faces)."""
        if self._aabb is None and len(self.faces):
            import igl

            self._aabb = igl.AABB()
            self._aabb.init(self.vertices, self.faces)
        return self._aabb

    @property
    def tree(self) -> cKDTree:
        """KD-tree over proxy points: every point of a triangle lies within ``self.radius``
        of one of its proxies (half the median triangle's radius, coarser if a few huge
        triangles would need more than ``max_proxies``, default 4 per triangle, at least 10^6)."""
        if self._tree is None:
            tri = self.vertices[self.faces]
            r = np.linalg.norm(tri - tri.mean(1)[:, None], axis=2).max(1) if len(tri) else np.zeros(0)
            self.radius = float(max(0.5 * np.median(r), 1e-12 * max(r.max(), 1e-300))) if len(r) else 0.0
            budget = self._max_proxies or max(4 * len(r), 1_000_000)
            while len(r) and (np.maximum(np.ceil(r / self.radius), 1) ** 2).sum() > budget:
                self.radius *= 1.5
            proxy, self._proxy_face = (_proxies(tri, self.radius) if len(tri)
                                       else (np.zeros((0, 3)), np.zeros(0, np.int64)))
            self._tree = cKDTree(proxy, balanced_tree=False, compact_nodes=False)
        return self._tree

    def project(self, points: np.ndarray, max_distance: float | None = None, chunk: int = 1_000_000) -> Projection:
        """Closest points; with ``max_distance`` points farther than it get ``distance = inf``, face -1."""
        points = np.asarray(points, np.float64).reshape(-1, 3)
        parts = [self._project(points[i:i + chunk], max_distance) for i in range(0, max(len(points), 1), chunk)]
        return Projection(*(np.concatenate([p[j] for p in parts]) for j in range(5)))

    def _project(self, p: np.ndarray, max_distance: float | None):
        n = len(p)
        out = (np.zeros((n, 3)), np.full(n, np.inf), np.full(n, -1), np.zeros((n, 3)), np.zeros(n, bool))
        if n == 0 or self.aabb is None:
            return out
        _, face, _ = self.aabb.squared_distance(self.vertices, self.faces, np.ascontiguousarray(p))
        sub = self._exact(p, np.asarray(face, np.int64)[:, None])
        for o, v in zip(out, sub):
            o[:] = v
        if max_distance is not None:
            far = out[1] > max_distance
            out[1][far], out[2][far] = np.inf, -1
        return out

    def _ball_pairs(self, points: np.ndarray, radius: np.ndarray, budget: int = 4_000_000):
        """Batches of ``(i, face)``: each triangle with a proxy within ``radius[i] + self.radius``
        of ``points[i]`` (so every triangle within ``radius[i]``), once per point; a batch
        holds at most about ``budget`` proxies."""
        tree = self.tree  # built (and self.radius set) on first use
        r = radius + self.radius
        size = tree.query_ball_point(points, r, return_length=True, workers=-1)
        batch = np.cumsum(size) // budget
        for b in np.unique(batch):
            sel = np.flatnonzero(batch == b)
            balls = tree.query_ball_point(points[sel], r[sel], workers=-1)
            face = self._proxy_face[np.concatenate(balls).astype(np.int64)]
            pair = np.unique(np.repeat(sel, size[sel]) * len(self.faces) + face)  # grouped by point
            yield pair // len(self.faces), pair % len(self.faces)

    def faces_within(self, points: np.ndarray, radius, where=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every (point index, triangle, exact distance) with the triangle within ``radius``
        (scalar or per point) of the point; with ``where(i, face) -> bool mask``, only the
        pairs it keeps (tested before the distances, which cost the most)."""
        points = np.asarray(points, np.float64)
        radius = np.broadcast_to(np.asarray(radius, np.float64), (len(points),))
        out = [(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))]
        if len(points) and len(self.faces):
            for i, face in self._ball_pairs(points, radius):
                if where is not None:
                    keep = where(i, face)
                    i, face = i[keep], face[keep]
                d = self._exact(points[i], face[:, None])[1]
                keep = d <= radius[i]
                out.append((i[keep], face[keep], d[keep]))
        return tuple(np.concatenate(x) for x in zip(*out))

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
    area = triangle_areas(vertices, np.asarray(faces, np.int64))
    rng = np.random.default_rng(seed)
    face = rng.choice(len(tri), size=count, p=area / area.sum())
    r1, r2 = rng.random(count), rng.random(count)
    s = np.sqrt(r1)
    w = np.stack([1 - s, s * (1 - r2), s * r2], 1)
    return (w[:, :, None] * tri[face]).sum(1), face


def boundary_segments(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(S, 2, 3) open-boundary edges (used by one face) of a mesh, after welding positions."""
    from mnacore.uvmesh import weld_ids

    vertices = np.asarray(vertices, np.float64)
    ids = weld_ids(vertices)
    keys = edge_keys(ids, faces)
    open_ = edge_use_counts(keys) == 1
    return vertices[half_edges(faces)[open_]]


def distance_to_segments(points: np.ndarray, segments: np.ndarray, k: int = 8) -> np.ndarray:
    """(N,) exact distance from each point to the nearest of ``segments (S, 2, 3)`` (inf if S = 0).

    As in :class:`MeshProjector`: a KD-tree over proxies (midpoints of the segments, long
    ones cut into pieces no longer than the median segment), ``k`` candidates, and an
    exhaustive ball search for the points whose distance certificate fails.
    """
    points = np.asarray(points, np.float64)
    segments = np.asarray(segments, np.float64)
    if len(segments) == 0:
        return np.full(len(points), np.inf)
    a, b = segments[:, 0], segments[:, 1]
    length = np.linalg.norm(b - a, axis=1)
    step = max(float(np.median(length)), 1e-12 * max(float(length.max()), 1e-300))
    while (np.ceil(length / step)).sum() > max(4 * len(length), 1_000_000):
        step *= 1.5
    pieces = np.maximum(np.ceil(length / step - 1e-9), 1).astype(np.int64)
    seg = np.repeat(np.arange(len(segments)), pieces)
    t = (np.arange(len(seg)) - np.repeat(np.cumsum(pieces) - pieces, pieces) + 0.5) / pieces[seg]
    tree = cKDTree(a[seg] + t[:, None] * (b - a)[seg])
    radius = 0.5 * float((length / pieces).max())  # every point of a segment is this close to a proxy

    def dist(p, s):
        ab = b[s] - a[s]
        u = np.clip(((p - a[s]) * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-300), 0, 1)
        return np.linalg.norm(p - (a[s] + u[..., None] * ab), axis=-1)

    k = min(k, len(seg))
    pd, cand = tree.query(points, k=k)
    pd, cand = pd.reshape(len(points), k), cand.reshape(len(points), k)
    out = dist(points[:, None], seg[cand]).min(1)
    for i in np.flatnonzero(pd[:, -1] - radius < out):  # not certified: every segment in the ball
        near = np.unique(seg[tree.query_ball_point(points[i], out[i] + radius)])
        out[i] = dist(points[i][None], near).min()
    return out
