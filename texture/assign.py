"""Face -> chart labels: which fitted chart each face of the user's mesh belongs to.

Every working face gets ``SAMPLES_BARY`` sample points (its centroid and three points
toward its corners), in the unit-ball frame. For each sample and each chart ``k`` we take
the exact closest point on the chart's *trimmed surface* (the grid triangles of chart
``k`` whose three vertices are in its domain ``occ > tau``) and there the chart's
*depth*: the distance, in grid cells, from that grid point to the nearest grid point out
of the domain (a Euclidean distance transform of the domain mask, interpolated).

A sample votes for, among the charts within ``NEAR_TOL`` of its nearest chart, the one
in whose domain it lies deepest: where two charts overlap (their domains are fitted
independently), the one that reaches the point from well inside its domain gives the
cleaner label than whichever happens to be a hair closer. A face takes the label with
most votes (ties: the smaller chart id). A face whose samples all lie farther than
``FAR_TOL`` from every chart is *far*: it keeps the nearest chart's label, and is counted.

``clean_labels`` then merges small regions; see :mod:`texture.regions`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import distance_transform_edt
from scipy.spatial import cKDTree

from mnacore.charts import ChartGrids
from mnacore.tolerances import NEAR_TOL

from .geometry import MeshProjector

#: barycentric coordinates of the samples of each face: centroid + three toward the corners.
SAMPLES_BARY = np.array([[1 / 3, 1 / 3, 1 / 3], [2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6],
                         [1 / 6, 1 / 6, 2 / 3]])
#: a sample farther than this from every chart (1 % of the diameter) is not reached by the fit.
FAR_TOL = 0.02
#: closest points are exact within this distance (nearest grid vertex beyond; > FAR_TOL + NEAR_TOL).
PROJECT_TOL = 0.05
#: above this many samples (4 per face), one sample per face (the centroid).
MAX_SAMPLES = 200_000
#: at most this many faces are labelled from their own samples. The labels carry no detail
#: finer than the chart surfaces (at most MAX_GRID^2 = 16,384 grid points per chart): above
#: this count an evenly spread subset (one face per cell of a 3D grid sized for this many
#: cells on the surface, plus one face per connected piece) is labelled by its centroid and every other face
#: takes the label of the labelled face nearest along the mesh (:func:`spread_labels`).
MAX_LABELLED = 50_000
#: chart surfaces for labelling use at most this many grid lines per side.
MAX_GRID = 128


@dataclass
class ChartSurface:
    """Chart ``k``'s trimmed surface: ``vertices (Vk, 3)`` unit frame, ``faces (Fk, 3)``,
    ``depth (Vk,)`` in (strided) grid cells (0 outside the domain)."""

    vertices: np.ndarray
    faces: np.ndarray
    depth: np.ndarray


def chart_surfaces(charts: ChartGrids, max_grid: int = MAX_GRID) -> list[ChartSurface]:
    """One :class:`ChartSurface` per chart (empty arrays for a chart with an empty domain),
    on every ``ceil(G / max_grid)``-th grid line (labels need no finer surface).

    Grid cell ``(i, j)`` is split into triangles ``(a, b, c)`` and ``(a, c, d)`` with
    ``a = (i, j)``, ``b = (i, j+1)``, ``c = (i+1, j+1)``, ``d = (i+1, j)`` (counter-clockwise
    in UV, since u grows with j and v with i).
    """
    step = max(1, -(-charts.grid // max_grid))
    G = len(range(0, charts.grid, step))
    i, j = np.meshgrid(np.arange(G - 1), np.arange(G - 1), indexing="ij")
    a = (i * G + j).ravel()
    b, c, d = a + 1, a + G + 1, a + G
    grid_faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    out = []
    for k in range(charts.n_charts):
        inside = charts.occ[k] > charts.tau
        # the square's edge is the domain's border too: pad with out-of-domain cells
        depth = distance_transform_edt(np.pad(inside, 1))[1:-1, 1:-1][::step, ::step].ravel() / step
        inside = inside[::step, ::step]
        xyz = charts.normalization.apply(charts.xyz[k, ::step, ::step].reshape(-1, 3))
        keep = inside.ravel()[grid_faces].all(1)
        f = grid_faces[keep]
        used, inv = np.unique(f, return_inverse=True)
        out.append(ChartSurface(xyz[used], inv.reshape(-1, 3), depth[used]))
    return out


@dataclass
class Assignment:
    """Face labels and how they were decided.

    Attributes:
        label: (F,) chart per face.
        far: (F,) bool: every sample farther than ``FAR_TOL`` from every chart.
        distance: (F,) mean distance of the face's samples to their nearest chart.
        stats: JSON-friendly counts.
        reach: (F, K) bool: chart ``k`` competes (lies within ``NEAR_TOL`` of the nearest
            chart) at half the face's samples or more; every chart for a far face. The
            charts that could label the face as well as its own: where region borders may
            move (:mod:`texture.borders`).
    """

    label: np.ndarray
    far: np.ndarray
    distance: np.ndarray
    stats: dict
    reach: np.ndarray


def face_samples(vertices: np.ndarray, faces: np.ndarray, bary: np.ndarray = SAMPLES_BARY) -> np.ndarray:
    """(F, S, 3) sample points of each face (barycentric rows ``bary (S, 3)``)."""
    return np.einsum("sc,fcd->fsd", bary, vertices[faces])


def labelled_subset(vertices: np.ndarray, faces: np.ndarray, adj, budget: int) -> np.ndarray:
    """Sorted face ids: one face per occupied cell of a cubic grid whose cell size ``h`` is
    chosen so that the surface holds about ``budget`` cells (``h = sqrt(area / budget)``),
    plus the first face of every edge-connected piece (so every face has a labelled face
    in its own piece)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from mnacore.triangles import triangle_areas

    F = len(faces)
    c = vertices[faces].mean(1)
    h = np.sqrt(max(float(triangle_areas(vertices, faces).sum()), 1e-300) / budget)
    for _ in range(2):  # a surface crosses more cells than its area in cells: one correction
        cell = np.floor((c - c.min(0)) / h).astype(np.int64)
        _, first = np.unique(cell, axis=0, return_index=True)
        h *= np.sqrt(max(len(first) / budget, 1.0))
    graph = coo_matrix((np.ones(len(adj.a)), (adj.a, adj.b)), shape=(F, F))
    _, piece = connected_components(graph, directed=False)
    _, first_of_piece = np.unique(piece, return_index=True)
    return np.union1d(first, first_of_piece)


def spread_labels(vertices: np.ndarray, faces: np.ndarray, adj, chosen: np.ndarray) -> np.ndarray:
    """(F,) for every face the labelled face (one of ``chosen``) nearest to it along the mesh:
    shortest paths over shared edges, each step weighted by the distance between the two
    faces' centroids."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import dijkstra

    F = len(faces)
    c = vertices[faces].mean(1)
    w = np.linalg.norm(c[adj.a] - c[adj.b], axis=1) + 1e-12
    g = sp.coo_matrix((np.r_[w, w], (np.r_[adj.a, adj.b], np.r_[adj.b, adj.a])), shape=(F, F)).tocsr()
    _, _, src = dijkstra(g, indices=chosen, min_only=True, return_predecessors=True)
    src = np.asarray(src, np.int64)
    lost = src < 0  # cannot happen (every piece holds a chosen face); nearest centroid then
    if lost.any():
        src[lost] = chosen[cKDTree(c[chosen]).query(c[lost])[1]]
    return src


def assign_faces(vertices: np.ndarray, faces: np.ndarray, surfaces: list[ChartSurface],
                 near_tol: float = NEAR_TOL, far_tol: float = FAR_TOL,
                 max_samples: int = MAX_SAMPLES, max_labelled: int = MAX_LABELLED) -> Assignment:
    """Label each face of ``(vertices (V,3) unit frame, faces (F,3))``; see the module docstring.

    Meshes with more than ``max_samples / 4`` faces get one sample per face (the centroid):
    their faces are small next to the charts' features, and neighbours vote alike. Meshes
    with more than ``max_labelled`` faces: only :func:`labelled_subset` is labelled so, and
    every other face copies label, far flag and distance from its :func:`spread_labels` face.
    """
    if len(faces) > max_labelled:
        from .regions import face_adjacency

        adj = face_adjacency(vertices, faces)
        chosen = labelled_subset(vertices, faces, adj, max_labelled)
        # one sample (the centroid) per labelled face: the subset is already spread evenly
        sub = assign_faces(vertices, faces[chosen], surfaces, near_tol, far_tol, len(chosen), len(chosen))
        at = np.zeros(len(faces), np.int64)
        at[chosen] = np.arange(len(chosen))
        src = at[spread_labels(vertices, faces, adj, chosen)]
        far = sub.far[src]
        stats = {**sub.stats, "labelled_faces": int(len(chosen)), "far_faces": int(far.sum()),
                 "faces_per_chart": np.bincount(sub.label[src], minlength=len(surfaces)).tolist()}
        return Assignment(sub.label[src], far, sub.distance[src], stats, sub.reach[src])
    bary = SAMPLES_BARY if len(faces) * len(SAMPLES_BARY) <= max_samples else SAMPLES_BARY[:1]
    F, S, K = len(faces), len(bary), len(surfaces)
    pts = face_samples(vertices, faces, bary).reshape(-1, 3)
    dist = np.full((len(pts), K), np.inf)
    depth = np.zeros((len(pts), K))
    for k, s in enumerate(surfaces):
        if len(s.faces) == 0:
            continue
        # exact closest points only where they can matter (a far query is slow for the
        # projector's k-NN search); beyond, the nearest grid vertex (its depth is irrelevant)
        proj = MeshProjector(s.vertices, s.faces).project(pts, max_distance=PROJECT_TOL)
        hit = np.isfinite(proj.distance)
        dist[hit, k] = proj.distance[hit]
        depth[hit, k] = (proj.bary[hit] * s.depth[s.faces[proj.face[hit]]]).sum(1)
        if not hit.all():
            dist[~hit, k] = cKDTree(s.vertices).query(pts[~hit])[0]
    if not np.isfinite(dist).any(axis=1).all():
        raise ValueError("assign_faces: no chart has a non-empty domain")
    nearest = dist.min(1)
    competing = dist <= nearest[:, None] + near_tol
    vote = np.argmax(np.where(competing, depth, -1.0), axis=1)  # argmax: smallest k on ties
    votes = np.zeros((F, K))
    np.add.at(votes, (np.repeat(np.arange(F), S), vote), 1.0)
    label = np.argmax(votes, axis=1)
    face_nearest = nearest.reshape(F, S)
    far = (face_nearest > far_tol).all(1)
    plain = np.argmin(dist, axis=1).reshape(F, S)
    # far faces: the chart nearest to the centroid (sample 0) instead of the depth vote
    label[far] = plain[far, 0]
    reach = 2 * competing.reshape(F, S, K).sum(1) >= S
    reach[far] = True
    reach[np.arange(F), label] = True
    stats = {"samples_per_face": S, "labelled_faces": F, "near_tol": near_tol, "far_tol": far_tol,
             "far_faces": int(far.sum()),
             "depth_vote_changed_samples": int((vote != plain.ravel()).sum()),
             "faces_per_chart": np.bincount(label, minlength=K).tolist()}
    return Assignment(label.astype(np.int64), far, face_nearest.mean(1), stats, reach)
