"""UV islands (charts) and UV/3D edge topology of a per-vertex UV mesh.

Two faces are in the same island when they share an edge *in UV*: both endpoints at
identical UV coordinates (and, when positions are given, on identical 3D points).
Vertex indices are not trusted, so duplicated-but-coincident vertices still connect and
two islands that merely overlap in UV stay apart.
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from mnacore.triangles import half_edges


def unique_rows(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(first, ids) of the distinct rows of ``values`` (N, K): the index of each distinct row's
    first occurrence, in lexicographic row order, and (N,) the id of each row's distinct row.

    The same as ``np.unique(values, axis=0, return_index=True, return_inverse=True)[1:]``,
    column by column (a 1-D sort per column) instead of one row-wise sort, which is several
    times slower on float rows.
    """
    values = np.asarray(values)
    values = values[:, None] if values.ndim == 1 else values
    if values.shape[1] == 0 or len(values) == 0:
        return np.zeros(min(len(values), 1), np.int64), np.zeros(len(values), np.int64)
    ids = np.zeros(len(values), np.int64)
    for col in values.T:
        _, col_ids = np.unique(col, return_inverse=True)
        key = ids * (int(col_ids.max()) + 1) + col_ids.reshape(-1)  # < N^2: fits in int64
        _, ids = np.unique(key, return_inverse=True)
        ids = ids.reshape(-1)
    return np.unique(ids, return_index=True)[1], ids


def _point_ids(values: np.ndarray) -> np.ndarray:
    """(V,) id per row of ``values``, equal iff the rows are exactly equal."""
    return unique_rows(values)[1]


def vertex_adjacency(faces: np.ndarray, n: int):
    """(n, n) symmetric 0/1 CSR matrix: vertices joined by a face edge."""
    he = half_edges(faces)
    a = coo_matrix((np.ones(len(he)), (he[:, 0], he[:, 1])), shape=(n, n)).tocsr()
    return ((a + a.T) > 0).astype(np.float64).tocsr()


def neighbour_mean(adj, uv: np.ndarray, free: np.ndarray) -> np.ndarray:
    """``uv`` with every ``free`` vertex at the mean of its neighbours in ``adj``
    (:func:`vertex_adjacency`), the others where they are: Tutte's condition, one sparse
    solve (``deg(i) x_i - sum_{j ~ i} x_j = 0`` on the free vertices)."""
    from scipy.sparse import diags
    from scipy.sparse.linalg import splu

    uv = np.array(uv, np.float64)
    idx = np.flatnonzero(free)
    if len(idx):
        deg = np.asarray(adj[idx].sum(1)).ravel()
        lap = diags(deg) - adj[idx][:, idx]
        uv[idx] = splu(lap.tocsc()).solve(adj[idx] @ np.where(free[:, None], 0.0, uv))
    return uv


def edge_keys(ids: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(3F,) integer key of each undirected half-edge, from per-vertex point ``ids``."""
    e = ids[half_edges(faces)]
    lo, hi = e.min(1), e.max(1)
    return lo * (int(ids.max()) + 1) + hi


def uv_point_ids(uv: np.ndarray, weld: np.ndarray | None = None) -> np.ndarray:
    """(V,) id of each vertex's UV point (combined with its 3D point id ``weld`` if given)."""
    uv = np.asarray(uv, np.float64)
    if weld is None:
        return _point_ids(uv)
    return _point_ids(np.column_stack([uv, np.asarray(weld, np.float64)]))


def uv_islands(faces: np.ndarray, uv: np.ndarray, weld: np.ndarray | None = None) -> np.ndarray:
    """(F,) island id per face, ids ``0..n-1`` numbered by first face.

    Args:
        faces: (F, 3) int vertex indices.
        uv: (V, 2) per-vertex UVs.
        weld: optional (V,) 3D point id per vertex (see ``uvmesh.weld_ids``).

    Example: two triangles sharing a UV edge form one island; move one of them in UV
    (same vertex indices impossible then, so duplicate its vertices) and they form two.
    """
    faces = np.asarray(faces, np.int64)
    F = len(faces)
    if F == 0:
        return np.zeros(0, np.int64)
    keys = edge_keys(uv_point_ids(uv, weld), faces)
    face_of = np.repeat(np.arange(F), 3)
    order = np.argsort(keys, kind="stable")
    ks, fs = keys[order], face_of[order]
    same = ks[1:] == ks[:-1]
    a, b = fs[:-1][same], fs[1:][same]
    graph = coo_matrix((np.ones(len(a)), (a, b)), shape=(F, F))
    _, labels = connected_components(graph, directed=False)
    # renumber by first occurrence so ids are deterministic and start at face 0
    _, first = np.unique(labels, return_index=True)
    rank = np.empty(len(first), np.int64)
    rank[np.argsort(first)] = np.arange(len(first))
    return rank[labels]


def edge_use_counts(keys: np.ndarray) -> np.ndarray:
    """(len(keys),) how many half-edges share each half-edge's key."""
    _, inverse, counts = np.unique(keys, return_inverse=True, return_counts=True)
    return counts[inverse.reshape(-1)]
