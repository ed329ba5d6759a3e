"""Closest points on meshes and segments: exact against brute force on meshes of very
different triangle sizes (a large triangle among small ones: the case where the nearest
triangle centroids are not the nearest triangles)."""
from __future__ import annotations

import numpy as np
import pytest

from texture.geometry import MeshProjector, closest_point_on_triangles, distance_to_segments


def _mixed_mesh(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """One triangle of side ~4 in the plane z = 0, and 400 small ones (side 0.05) scattered
    just above and around it; the big triangle's centroid is far from most of its area."""
    rng = np.random.default_rng(seed)
    big = np.array([[-2.0, -2.0, 0.0], [2.0, -2.0, 0.0], [0.0, 2.0, 0.0]])
    c = rng.uniform([-2.5, -2.5, 0.02], [2.5, 2.5, 0.3], size=(400, 3))
    small = c[:, None] + rng.normal(scale=0.03, size=(400, 3, 3))
    V = np.concatenate([big, small.reshape(-1, 3)])
    F = np.arange(len(V)).reshape(-1, 3)
    return V, F


def _brute(points, V, F):
    t = V[F]
    n, m = len(points), len(F)
    q, _ = closest_point_on_triangles(np.repeat(points, m, 0), np.tile(t[:, 0], (n, 1)),
                                      np.tile(t[:, 1], (n, 1)), np.tile(t[:, 2], (n, 1)))
    d = np.linalg.norm(q - np.repeat(points, m, 0), axis=1).reshape(n, m)
    return d


def test_projector_is_exact_on_mixed_triangle_sizes():
    V, F = _mixed_mesh()
    rng = np.random.default_rng(1)
    # near the big triangle (between the small ones), and a few far away
    pts = np.concatenate([rng.uniform([-1.5, -1.5, -0.05], [1.5, 1.0, 0.05], size=(1500, 3)),
                          rng.normal(scale=5.0, size=(100, 3))])
    d = _brute(pts, V, F)
    proj = MeshProjector(V, F).project(pts)
    np.testing.assert_allclose(proj.distance, d.min(1), rtol=0, atol=1e-12)
    # the face it names holds a closest point, and point/bary agree with it
    np.testing.assert_allclose(d[np.arange(len(pts)), proj.face], d.min(1), rtol=0, atol=1e-12)
    np.testing.assert_allclose((proj.bary[:, :, None] * V[F[proj.face]]).sum(1), proj.point, atol=1e-12)
    # a projector that takes the k nearest centroids without the certificate gets many wrong
    from scipy.spatial import cKDTree

    _, cand = cKDTree(V[F].mean(1)).query(pts, k=8)
    wrong = d[np.arange(len(pts))[:, None], cand].min(1) > d.min(1) + 1e-9
    assert wrong.mean() > 0.2


def test_projector_max_distance_and_faces_within():
    V, F = _mixed_mesh(2)
    rng = np.random.default_rng(3)
    pts = rng.uniform([-2, -2, -0.3], [2, 2, 0.5], size=(800, 3))
    d = _brute(pts, V, F)
    P = MeshProjector(V, F)
    proj = P.project(pts, max_distance=0.05)
    near = d.min(1) <= 0.05
    assert near.any() and (~near).any()
    np.testing.assert_allclose(proj.distance[near], d.min(1)[near], atol=1e-12)
    assert np.isinf(proj.distance[~near]).all() and (proj.face[~near] == -1).all()
    # every (point, face) within a per-point radius, no more, no fewer
    radius = rng.uniform(0.0, 0.3, len(pts))
    i, f, dist = P.faces_within(pts, radius)
    assert set(zip(i.tolist(), f.tolist())) == set(zip(*np.nonzero(d <= radius[:, None])))
    np.testing.assert_allclose(dist, d[i, f], atol=1e-12)


def test_projector_keeps_proxy_count_bounded():
    # one huge triangle among tiny ones: the proxy spacing grows rather than the memory
    V, F = _mixed_mesh()
    V = V.copy()
    V[:3] *= 1000.0
    P = MeshProjector(V, F, max_proxies=20_000)
    assert P.tree.n <= 20_000
    pts = np.random.default_rng(4).uniform(-10, 10, size=(300, 3))
    np.testing.assert_allclose(P.project(pts).distance, _brute(pts, V, F).min(1), atol=1e-9)


@pytest.mark.parametrize("seed", [0, 1])
def test_distance_to_segments_exact_with_long_and_short_segments(seed):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(300, 3))
    long_ = rng.random((300, 1)) < 0.1
    b = a + rng.normal(size=(300, 3)) * np.where(long_, 3.0, 0.05)
    pts = rng.normal(size=(3000, 3)) * 2
    ab = b - a
    u = np.clip(((pts[:, None] - a) * ab).sum(-1) / (ab * ab).sum(-1), 0, 1)
    ref = np.linalg.norm(pts[:, None] - (a + u[..., None] * ab), axis=-1).min(1)
    np.testing.assert_allclose(distance_to_segments(pts, np.stack([a, b], 1)), ref, rtol=0, atol=1e-12)
    assert np.isinf(distance_to_segments(pts[:3], np.zeros((0, 2, 3)))).all()
