"""A short cut graph: the edges that cut a region with handles or several boundary loops to a disk.

libigl's ``cut_to_disk`` finds a cut graph from the faces alone (it peels faces off in
breadth-first order): the cut is topologically right, but its length is whatever the peeling
order gives, and every cut edge becomes seam. This module builds the cut from the surface's
edge lengths, as the greedy system of loops of Erickson and Whittlesey ("Greedy optimal
homotopy and homology generators", SODA 2005) does, with every boundary loop taken as the root:

1. a shortest-path tree ``T`` from the root (all boundary vertices at distance 0: one
   multi-source Dijkstra; a closed region is rooted at one vertex);
2. every edge ``e = (a, b)`` outside ``T`` closes a loop through the root of length
   ``d(a) + |e| + d(b)``; a maximum spanning tree ``C`` of the dual graph (faces, joined
   across edges outside ``T``, weighted by that length) keeps the long loops uncut;
3. the edges in neither ``T`` nor ``C`` (``2g + b - 1`` of them on a region of genus ``g``
   with ``b`` boundary loops) each close one loop; the region cut along every edge not
   crossed by ``C`` is one tree of faces, a disk, and the branches of ``T`` that end at an
   interior vertex are glued back (they only slit the disk), leaving those loops.

On a closed surface the greedy loops are the shortest system of loops through the root
(Erickson and Whittlesey); with the boundary as root the arcs between boundary loops are
shortest paths too. The root of a closed region is chosen among a few far-apart vertices,
the shortest result kept. A closed genus-0 region has no such loop (its cut is chosen by
:func:`texture.flatten.cut_to_disk`).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra, minimum_spanning_tree

#: roots tried on a closed region (farthest-point samples, the first at vertex 0's farthest)
CLOSED_ROOTS = 4


def _edges(vertices: np.ndarray, faces: np.ndarray):
    """(edge endpoints (E, 2) sorted, edge of each face corner (F, 3), edge lengths (E,),
    faces of each edge (E, 2; -1 where only one face uses it))."""
    a = faces.reshape(-1)
    b = np.roll(faces, -1, axis=1).reshape(-1)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = lo * (int(faces.max()) + 1) + hi
    uniq, first, inv = np.unique(key, return_index=True, return_inverse=True)
    ends = np.column_stack([lo[first], hi[first]])
    length = np.linalg.norm(vertices[ends[:, 0]] - vertices[ends[:, 1]], axis=1)
    owner = np.full((len(uniq), 2), -1, np.int64)
    face_of = np.repeat(np.arange(len(faces)), 3)
    order = np.argsort(inv, kind="stable")
    inv_sorted = inv[order]
    start = np.r_[0, np.flatnonzero(np.diff(inv_sorted)) + 1]
    owner[inv_sorted[start], 0] = face_of[order[start]]
    second = start + 1
    ok = (second < len(order)) & (inv_sorted[np.minimum(second, len(order) - 1)] == inv_sorted[start])
    owner[inv_sorted[start[ok]], 1] = face_of[order[second[ok]]]
    return ends, inv.reshape(-1, 3), length, owner


def _greedy(n: int, ends: np.ndarray, length: np.ndarray, owner: np.ndarray, nfaces: int,
            roots: np.ndarray) -> tuple[np.ndarray, float]:
    """(cut flags per edge (E,), cut length) of the greedy cut rooted at ``roots``."""
    interior = owner[:, 1] >= 0
    w = np.maximum(length, 1e-12)  # a zero-length edge must still be an edge of the graph
    g = sp.coo_matrix((w[interior], (ends[interior, 0], ends[interior, 1])), shape=(n, n)).tocsr()
    dist, pred, _ = dijkstra(g, directed=False, indices=roots, min_only=True, return_predecessors=True)
    a, b = ends[:, 0], ends[:, 1]
    tree = interior & ((pred[a] == b) | (pred[b] == a))
    # dual graph over the edges outside the tree: a maximum spanning tree keeps the long loops
    dual = interior & ~tree
    loop = dist[a] + length + dist[b]
    f1, f2, lw = owner[dual, 0], owner[dual, 1], loop[dual]
    idx = np.flatnonzero(dual)
    # two faces may share two edges (a degenerate fold): the dual keeps one, the other is cut
    pair = np.minimum(f1, f2) * nfaces + np.maximum(f1, f2)
    order = np.lexsort((-lw, pair))
    keep = np.r_[True, pair[order][1:] != pair[order][:-1]]
    sel = order[keep]
    top = float(lw.max()) if len(lw) else 0.0
    cost = (top + 1.0) - lw[sel]  # positive, smallest for the longest loop
    mst = minimum_spanning_tree(sp.coo_matrix((cost, (f1[sel], f2[sel])), shape=(nfaces, nfaces)).tocsr())
    m = mst.tocoo()
    crossed = set((np.minimum(m.row, m.col).astype(np.int64) * nfaces + np.maximum(m.row, m.col)).tolist())
    in_c = np.zeros(len(ends), bool)
    hit = np.fromiter((p in crossed for p in pair[sel].tolist()), bool, len(sel))
    in_c[idx[sel[hit]]] = True
    cut = interior & ~in_c
    cut = _pruned(n, ends, cut, owner[:, 1] < 0)
    return cut, float(length[cut].sum())


def _pruned(n: int, ends: np.ndarray, cut: np.ndarray, boundary: np.ndarray) -> np.ndarray:
    """``cut`` without its dangling branches: edges reaching a vertex that no other cut edge
    and no boundary edge touches are glued back, until none is left."""
    cut = cut.copy()
    on_boundary = np.zeros(n, bool)
    on_boundary[ends[boundary].ravel()] = True
    ids = np.flatnonzero(cut)
    deg = np.bincount(ends[ids].ravel(), minlength=n)
    inc = sp.csr_matrix((np.ones(2 * len(ids)), (ends[ids].T.ravel(), np.r_[ids, ids])), shape=(n, len(ends)))
    stack = [v for v in np.flatnonzero((deg == 1) & ~on_boundary).tolist()]
    while stack:
        v = stack.pop()
        if deg[v] != 1:
            continue
        row = inc.indices[inc.indptr[v]:inc.indptr[v + 1]]
        e = next(int(e) for e in row if cut[e])
        cut[e] = False
        deg[v] -= 1
        u = int(ends[e, 0] if ends[e, 1] == v else ends[e, 1])
        deg[u] -= 1
        if deg[u] == 1 and not on_boundary[u]:
            stack.append(u)
    return cut


def short_cut_flags(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F, 3) bool: the corners' edges ``(faces[f, j], faces[f, (j + 1) % 3])`` on the greedy cut
    graph of the connected manifold region ``(vertices, faces)`` (module docstring). Cutting
    there leaves one disk wherever the region has a handle or two boundary loops; no flag is
    set where it is a disk already or a closed genus-0 surface."""
    faces = np.asarray(faces, np.int64)
    vertices = np.asarray(vertices, np.float64)
    n = max(len(vertices), int(faces.max()) + 1)
    ends, corner_edge, length, owner = _edges(vertices, faces)
    boundary = owner[:, 1] < 0
    if boundary.any():
        roots = np.unique(ends[boundary])
        cut, _ = _greedy(n, ends, length, owner, len(faces), roots)
    else:
        cut = None
        best = np.inf
        for root in _far_vertices(n, ends, length, CLOSED_ROOTS):
            c, total = _greedy(n, ends, length, owner, len(faces), np.array([root]))
            if total < best:
                cut, best = c, total
    return cut[corner_edge]


def _far_vertices(n: int, ends: np.ndarray, length: np.ndarray, k: int) -> list[int]:
    """``k`` far-apart vertices (farthest-point sampling by edge-path distance)."""
    g = sp.coo_matrix((np.maximum(length, 1e-12), (ends[:, 0], ends[:, 1])), shape=(n, n)).tocsr()
    used = np.unique(ends)
    d = dijkstra(g, directed=False, indices=int(used[0]))
    picks = []
    for _ in range(k):
        d = np.where(np.isfinite(d), d, -1.0)
        v = int(used[np.argmax(d[used])])
        if v in picks:
            break
        picks.append(v)
        d = np.minimum(d, dijkstra(g, directed=False, indices=v))
    return picks
