"""Topology of a triangle mesh: parts, genus and boundary loops, from the Euler characteristic.

Per connected part (vertices welded by position first, so a mesh split along UV seams
or saved as a triangle soup counts as the surface it is):
``chi = V - E + F`` and ``genus = (2 - chi - b) / 2`` with ``b`` boundary loops. The formula
holds for an orientable 2-manifold; on a part with non-manifold edges it is only an
estimate, so each part says whether it is manifold and the genus is never negative.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

#: vertices closer than this fraction of the bounding-box diagonal are one vertex
WELD = 1e-9


@dataclass(frozen=True)
class Topology:
    parts: int
    genus: tuple[int, ...]
    """genus of each part (largest part by face count first)."""
    boundaries: tuple[int, ...]
    """boundary loops of each part, same order."""
    manifold: bool
    """every edge has at most two faces (else the genus is an estimate)."""

    @property
    def total_genus(self) -> int:
        return int(sum(self.genus))


def _components(n: int, a: np.ndarray, b: np.ndarray) -> tuple[int, np.ndarray]:
    graph = coo_matrix((np.ones(len(a)), (a, b)), shape=(n, n))
    return connected_components(graph, directed=False)


def mesh_topology(vertices: np.ndarray, faces: np.ndarray) -> Topology:
    """Parts, per-part genus and boundary loops of ``(vertices (V, 3), faces (F, 3))``."""
    vertices, faces = np.asarray(vertices, dtype=np.float64), np.asarray(faces, dtype=np.int64)
    diag = float(np.linalg.norm(np.ptp(vertices, axis=0))) or 1.0
    keys = np.round(vertices / (WELD * diag)).astype(np.int64)
    _, weld = np.unique(keys, axis=0, return_inverse=True)
    f = weld.reshape(-1)[faces]
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]  # drop collapsed faces
    nv = int(weld.max()) + 1
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    uniq, edge_of, uses = np.unique(edges, axis=0, return_inverse=True, return_counts=True)
    edge_of = edge_of.reshape(-1)
    _, part_of_vertex = _components(nv, uniq[:, 0], uniq[:, 1])
    used = np.unique(f)
    part_ids, part_of_vertex_used = np.unique(part_of_vertex[used], return_inverse=True)
    part_index = np.full(nv, -1)
    part_index[used] = part_of_vertex_used
    n_parts = len(part_ids)
    face_part = part_index[f[:, 0]]
    V = np.bincount(part_of_vertex_used, minlength=n_parts)
    E = np.bincount(part_index[uniq[:, 0]], minlength=n_parts)
    F = np.bincount(face_part, minlength=n_parts)
    # boundary loops: connected pieces of the graph of edges with one face
    border = uniq[uses == 1]
    loops = np.zeros(n_parts, dtype=np.int64)
    if len(border):
        _, piece = _components(nv, border[:, 0], border[:, 1])
        on_border = np.unique(border)
        # one vertex per loop (the first of each piece), counted in its part
        _, first = np.unique(piece[on_border], return_index=True)
        loops = np.bincount(part_index[on_border[first]], minlength=n_parts)
    chi = V - E + F
    genus = np.maximum(0, (2 - chi - loops) // 2)
    order = np.argsort(-F, kind="stable")
    return Topology(parts=n_parts, genus=tuple(int(g) for g in genus[order]),
                    boundaries=tuple(int(b) for b in loops[order]), manifold=bool((uses <= 2).all()))
