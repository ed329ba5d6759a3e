"""Face labels -> clean regions: connected pieces of one label, small ones merged away.

A *region* is a maximal set of faces with one label, connected through shared edges.
Raw chart labels leave specks (a few faces where two charts overlap); a majority filter
over face neighbours oscillates and need not converge. Instead, :func:`clean_labels`
merges every region smaller than ``min_fraction`` of its connected component's area into
the neighbouring region with which it shares the longest border, and repeats until
nothing changes. Property on return: every region is at least ``min_fraction`` of its
component's area, or it is the only region of its component, or it has no neighbour
(each merge strictly lowers the region count, so this terminates).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

#: a region below this fraction of its component's area is merged into a neighbour.
MIN_FRACTION = 0.01


@dataclass
class FaceAdjacency:
    """Faces ``a[i]`` and ``b[i]`` share an edge of 3D length ``length[i]``."""

    a: np.ndarray
    b: np.ndarray
    length: np.ndarray


def face_adjacency(vertices: np.ndarray, faces: np.ndarray) -> FaceAdjacency:
    """Pairs of faces sharing an edge used by exactly two faces (a manifold working mesh)."""
    he = np.stack([faces, np.roll(faces, -1, axis=1)], -1).reshape(-1, 2)
    n = int(faces.max()) + 1
    key = he.min(1) * n + he.max(1)
    order = np.argsort(key, kind="stable")
    ks = key[order]
    same = np.flatnonzero(ks[1:] == ks[:-1])
    # an edge used three times would pair twice; the working mesh has none
    h1, h2 = order[same], order[same + 1]
    length = np.linalg.norm(vertices[he[h1, 0]] - vertices[he[h1, 1]], axis=1)
    return FaceAdjacency(h1 // 3, h2 // 3, length)


def regions(label: np.ndarray, adj: FaceAdjacency) -> np.ndarray:
    """(F,) region id per face: connected (through ``adj``) faces of one label; ids by first face."""
    F = len(label)
    same = label[adj.a] == label[adj.b]
    graph = coo_matrix((np.ones(int(same.sum())), (adj.a[same], adj.b[same])), shape=(F, F))
    _, comp = connected_components(graph, directed=False)
    _, first, inv = np.unique(comp, return_index=True, return_inverse=True)
    rank = np.empty(len(first), np.int64)
    rank[np.argsort(first)] = np.arange(len(first))
    return rank[inv.reshape(-1)]


def clean_labels(label: np.ndarray, area: np.ndarray, component: np.ndarray, adj: FaceAdjacency,
                 min_fraction: float = MIN_FRACTION, max_rounds: int = 200) -> tuple[np.ndarray, dict]:
    """(new labels (F,), stats); see the module docstring.

    Per round, every small region whose longest-border neighbour is larger than itself (or
    equal and of larger id) takes that neighbour's label, so two small neighbours never swap.
    """
    label = np.asarray(label, np.int64).copy()
    comp_area = np.bincount(component, weights=area)
    raw = int(regions(label, adj).max()) + 1
    rounds = 0
    for rounds in range(1, max_rounds + 1):
        reg = regions(label, adj)
        R = int(reg.max()) + 1
        r_area = np.bincount(reg, weights=area, minlength=R)
        r_comp = np.zeros(R, np.int64)
        r_comp[reg] = component
        r_label = np.zeros(R, np.int64)
        r_label[reg] = label
        small = r_area < min_fraction * comp_area[r_comp]
        ra, rb = reg[adj.a], reg[adj.b]
        cross = ra != rb
        if not small.any() or not cross.any():
            break
        # border length between region pairs (both directions)
        src = np.r_[ra[cross], rb[cross]]
        dst = np.r_[rb[cross], ra[cross]]
        w = np.r_[adj.length[cross], adj.length[cross]] + 1e-12  # zero-length edges still connect
        border = coo_matrix((w, (src, dst)), shape=(R, R)).tocsr()
        border.sum_duplicates()
        target = np.full(R, -1)
        for r in np.flatnonzero(small):
            row = border.getrow(r)
            if row.nnz == 0:
                continue
            s = row.indices[np.argmax(row.data)]
            if (r_area[s], s) > (r_area[r], r):
                target[r] = s
        move = np.flatnonzero(target >= 0)
        if len(move) == 0:
            break
        new_label = r_label.copy()
        new_label[move] = r_label[target[move]]
        label = new_label[reg]
    final = regions(label, adj)
    return label, {"raw_regions": raw, "regions": int(final.max()) + 1, "merge_rounds": rounds,
                   "min_fraction": min_fraction}


def smooth_borders(label: np.ndarray, adj: FaceAdjacency, passes: int = 20) -> tuple[np.ndarray, int]:
    """(labels, faces changed): a face with at least two edge neighbours of one other label
    takes that label, one face at a time (Gauss-Seidel), until no face changes or after
    ``passes`` sweeps over the border faces.

    Each change turns >= 2 border edges of the face into <= 1, so the number of border
    edges strictly drops and the sweeps terminate; this removes the one-face teeth of a
    border that follows mesh edges (a simultaneous majority filter oscillates instead).
    """
    import scipy.sparse as sp

    label = np.asarray(label, np.int64).copy()
    F = len(label)
    nb = sp.coo_matrix((np.ones(2 * len(adj.a)), (np.r_[adj.a, adj.b], np.r_[adj.b, adj.a])), shape=(F, F)).tocsr()
    indptr, indices = nb.indptr, nb.indices
    changed = 0
    for _ in range(passes):
        border = np.flatnonzero(np.bincount(adj.a[label[adj.a] != label[adj.b]], minlength=F)
                                + np.bincount(adj.b[label[adj.a] != label[adj.b]], minlength=F) >= 2)
        moved = 0
        for f in border.tolist():
            labs = label[indices[indptr[f]:indptr[f + 1]]]
            labs = labs[labs != label[f]]
            if len(labs) < 2:
                continue
            vals, counts = np.unique(labs, return_counts=True)
            if counts.max() >= 2:
                label[f] = vals[np.argmax(counts)]
                moved += 1
        changed += moved
        if moved == 0:
            break
    return label, changed
