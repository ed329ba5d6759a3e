"""Shortest region borders: move chart borders, within the charts' overlap, to where they are shortest.

The assignment (:mod:`texture.assign`) labels every face with the chart that reaches it from
deepest inside its domain. Where two charts overlap, the border between their regions then
follows the depth contest face by face: it wanders and zigzags along mesh edges, and every
unit of it becomes a seam (both sides of a region border are island borders). Yet inside
the overlap either chart serves the face (it lies within ``NEAR_TOL`` of both), so the
border may run anywhere there.

:func:`shortest_borders` moves it to the shortest place: for every pair of charts
``(a, b)``, the faces labelled ``a`` or ``b`` that both charts reach (``Assignment.reach``)
are relabelled by a minimum cut (scipy's ``maximum_flow``) of the face graph, whose edge
capacities are the 3D lengths of the shared mesh edges, with every face one chart alone
reaches held to its label. The cut is the shortest ``a``/``b`` border the overlap allows,
given the other labels (an alpha-beta swap of graph-cut labelling, Potts energy = border
length, no data term inside the overlap). Swaps repeat until the total border length stops
falling. No face ever takes a chart that does not reach it; a region may vanish when the
overlap covers it (the other chart reaches all of it).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order, maximum_flow

from .regions import FaceAdjacency

#: the capacities of one cut sum to at most this (scipy's maximum_flow counts in int32)
CAPACITY_TOTAL = 2**30
#: rounds of swaps over every chart pair at most (each round only shortens the borders)
MAX_ROUNDS = 4


def border_length(label: np.ndarray, adj: FaceAdjacency) -> float:
    """Total 3D length of the edges between faces of different labels."""
    return float(adj.length[label[adj.a] != label[adj.b]].sum())


def min_cut_labels(label: np.ndarray, free: np.ndarray, adj: FaceAdjacency, a: int, b: int,
                   weight: np.ndarray | None = None) -> np.ndarray:
    """``label`` with the ``free`` faces relabelled ``a`` or ``b`` by a minimum cut of the face
    graph (capacities: the shared edges' 3D lengths, times ``weight`` per face pair where
    given), every other face held to its label: the shortest ``a``/``b`` border that runs
    through the free faces only. A free face next to a held face of another label than ``a``
    or ``b`` is not tied to either side."""
    length_of = adj.length if weight is None else adj.length * weight
    idx = np.flatnonzero(free)
    if len(idx) == 0:
        return label
    n = len(idx)
    loc = np.full(len(label), -1)
    loc[idx] = np.arange(n)
    src, snk = n, n + 1
    la, lb = loc[adj.a], loc[adj.b]
    both = (la >= 0) & (lb >= 0)
    rows, cols, caps = [la[both], lb[both]], [lb[both], la[both]], [length_of[both], length_of[both]]
    # a free face next to a held face: cutting that edge costs its length, on the side it holds
    for inner, outer in ((la, adj.b), (lb, adj.a)):
        edge = (inner >= 0) & (loc[outer] < 0)
        for side, lab in ((src, a), (snk, b)):
            m = edge & (label[outer] == lab)
            rows.append(np.full(int(m.sum()), src) if side == src else inner[m])
            cols.append(inner[m] if side == src else np.full(int(m.sum()), snk))
            caps.append(length_of[m])
    length = np.concatenate(caps)
    scale = CAPACITY_TOTAL / max(float(length.sum()), 1e-300)
    cap = np.maximum(np.floor(length * scale), 1).astype(np.int32)
    graph = sp.csr_matrix((cap, (np.concatenate(rows), np.concatenate(cols))), shape=(n + 2, n + 2))
    graph.sum_duplicates()
    residual = (graph - maximum_flow(graph, src, snk).flow).tocsr()
    residual.data[residual.data < 0] = 0
    residual.eliminate_zeros()
    side = np.zeros(n + 2, bool)
    side[breadth_first_order(residual, src, directed=True, return_predecessors=False)] = True
    out = label.copy()
    out[idx] = np.where(side[:n], a, b)
    return out


def _swap(label: np.ndarray, reach: np.ndarray, adj: FaceAdjacency, a: int, b: int) -> np.ndarray:
    """``label`` with the faces of charts ``a``/``b`` that both reach relabelled by a minimum cut."""
    return min_cut_labels(label, ((label == a) | (label == b)) & reach[:, a] & reach[:, b], adj, a, b)


def shortest_borders(label: np.ndarray, reach: np.ndarray, adj: FaceAdjacency) -> tuple[np.ndarray, dict]:
    """(labels, stats): see the module docstring. ``label (F,)`` holds charts ``0..K-1`` (and
    any other value for faces no chart labels: they stay), ``reach (F, K)`` which charts may
    label each face (a face's own chart always may)."""
    label = np.asarray(label, np.int64).copy()
    K = reach.shape[1]
    reach = reach.copy()
    own = label < K
    reach[np.flatnonzero(own), label[own]] = True
    before = length = border_length(label, adj)
    rounds = 0
    for rounds in range(1, MAX_ROUNDS + 1):
        for a in range(K):
            for b in range(a + 1, K):
                label = _swap(label, reach, adj, a, b)
        new = border_length(label, adj)
        if new >= length * (1 - 1e-9):
            length = new
            break
        length = new
    return label, {"border_length_before": before, "border_length": length, "rounds": rounds}
