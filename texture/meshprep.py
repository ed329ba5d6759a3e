"""Pre-clean a user's mesh for unwrapping, without changing its faces or their order.

``prepare_mesh(vertices, faces)`` returns a :class:`PreparedMesh`: a *working* mesh on
which every non-degenerate input face is a face of an edge-manifold, consistently
oriented mesh, plus the maps back to the input. Nothing is deleted or re-ordered:

- duplicated vertices (same position within ``mnacore.uvmesh.WELD_TOL`` of the bounding-box
  diagonal)
  are welded, so a mesh saved with split vertices unwraps as one surface;
- faces wound against their neighbours are turned, in the working mesh only, to the
  winding of most of their patch's area (:func:`mnacore.triangles.consistent_winding`): a surface whose
  winding was scrambled (an STL or CAD export, a merge of flipped pieces) unwraps as the
  surface it is, not as the pieces its flips leave (a sphere with half its faces flipped
  at random: 1,353 islands, seam 81, utilisation 0.21, as xatlas gives too);
- on a non-manifold edge (used by more than two faces) the faces running it one way are
  matched to those running it the other way whose normals agree most
  (:func:`mnacore.triangles.edge_pairs`): a double-sided surface (each face beside a copy
  wound the other way, on the same vertices after welding) stays a front and a back
  surface; the faces left over, and edges whose two faces still disagree on orientation (a
  non-orientable surface: a Mobius strip), are *cut* (their faces are not connected
  across them), and
  non-manifold vertices (several fans meeting at one point) are split into one working
  vertex per fan: a working vertex is a group of face corners on one welded point that
  are connected through the remaining (manifold, consistently oriented) edges;
- on the rim of a double-sided open surface, where a face meets its own reversed copy, the
  two sides stay joined, except at one end of a chord (an inner edge between two rim
  vertices), where the rim is cut so that the chord's front and back copies do not join the
  same two working vertices (:func:`fold_cuts`);
- a face that repeats an earlier face (the same welded points, wound the same way: an
  export that wrote some faces twice) is left out of the working mesh and takes its
  original's UVs: the same surface gets the same texels (on a copy of its own it would be
  an island of one face: 200 faces repeated in a 7k-face scan made 194 islands of 3);
- degenerate faces (a repeated vertex after welding, or zero 3D area) are left out of
  the working mesh (``work_face == -1``); :mod:`texture.unwrap` gives them the UVs of
  their corners in a neighbouring island, so they still get valid UVs.

Example: two triangles ``(0,1,2), (3,2,1)`` where vertex 3 duplicates vertex 0's
position weld into a closed two-face "pillow" with three working vertices and
edges of use 2.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from mnacore.errors import InputError
from mnacore.triangles import EdgePairs, consistent_winding, edge_pairs, face_normals, triangle_areas
from mnacore.uvmesh import WELD_TOL, validate_mesh, weld_ids

#: a face with 3D area below this times the squared diagonal is degenerate.
DEGENERATE_AREA = 1e-14


@dataclass
class PreparedMesh:
    """A working mesh for unwrapping and its maps to the input.

    Attributes:
        vertices: (V, 3) input positions (as given).
        faces: (F, 3) input faces (as given).
        work_vertices: (W, 3) positions of the working vertices.
        work_faces: (Fw, 3) working faces: manifold, consistently oriented (a turned face,
            ``turned``, has its input face's corners 1 and 2 swapped).
        work_face: (F,) working face of each input face, -1 for a degenerate face or a copy.
        input_face: (Fw,) input face of each working face.
        corner_vertex: (F, 3) working vertex of each input face corner (-1 on degenerate faces).
        component: (Fw,) connected component of each working face (ids 0..C-1).
        turned: (Fw,) bool, working faces wound against their input face.
        stats: counts of what was welded, turned, cut and split.
        copy_of: (F,) for a face that repeats an earlier one (:func:`copied_faces`) that
            face, else -1.
    """

    vertices: np.ndarray
    faces: np.ndarray
    work_vertices: np.ndarray
    work_faces: np.ndarray
    work_face: np.ndarray
    input_face: np.ndarray
    corner_vertex: np.ndarray
    component: np.ndarray
    turned: np.ndarray
    stats: dict
    copy_of: np.ndarray

    @property
    def n_components(self) -> int:
        return int(self.component.max()) + 1 if len(self.component) else 0


def degenerate_faces(vertices: np.ndarray, faces: np.ndarray, weld: np.ndarray) -> np.ndarray:
    """(F,) bool: a repeated (welded) vertex or 3D area <= ``DEGENERATE_AREA * diag^2``."""
    f = weld[faces]
    repeated = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])
    used = vertices[np.unique(faces)]
    diag = float(np.linalg.norm(used.max(0) - used.min(0))) or 1.0
    return repeated | (triangle_areas(vertices, faces) <= DEGENERATE_AREA * diag * diag)


def copied_faces(wf: np.ndarray) -> np.ndarray:
    """(F,) for each face of ``wf`` (welded ids) the first earlier face on the same three
    points wound the same way (its corners in the same cyclic order), -1 for the rest. A face
    on the same points wound the other way is not a copy: it is the back of a double-sided
    surface."""
    if not len(wf):
        return np.zeros(0, np.int64)
    rot = np.argmin(wf, axis=1)  # each face's corners from its lowest point on: cyclic order kept
    canon = np.take_along_axis(wf, (rot[:, None] + np.arange(3)) % 3, 1)
    _, first, inv = np.unique(canon, axis=0, return_index=True, return_inverse=True)
    orig = first[inv.reshape(-1)]
    return np.where(orig == np.arange(len(wf)), -1, orig)


def corner_groups(wf: np.ndarray, pairs: EdgePairs | None = None,
                  cut: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
    """(Fw, 3) working vertex per corner of faces ``wf`` (welded ids), cutting bad edges.

    Corners ``(f, c)`` and ``(g, d)`` on the same welded point are joined when faces
    ``f`` and ``g`` share an edge through that point that is used by exactly these two
    faces in opposite directions (manifold and consistently oriented). ``pairs``:
    :func:`mnacore.triangles.edge_pairs` of ``wf``, where the caller has them; ``cut``:
    (P,) bool over ``pairs.a``, pairs left unjoined (:func:`fold_cuts`).
    """
    Fw = len(wf)
    pairs = edge_pairs(wf) if pairs is None else pairs
    he, a, b = pairs.half_edges, pairs.a, pairs.b  # half-edge ids
    opposite = (he[a, 0] == he[b, 1]) & (he[a, 1] == he[b, 0])
    stats = {"nonmanifold_edges": pairs.nonmanifold, "nonmanifold_matched": pairs.matched,
             "inconsistent_edges": int((~opposite).sum()),
             "boundary_edges": pairs.boundary}
    if cut is not None:
        opposite &= ~cut
    a, b = a[opposite], b[opposite]
    # half-edge h = 3 f + c runs corner c -> c+1; its twin runs d+1 -> d: join (f,c)~(g,d+1), (f,c+1)~(g,d)
    fa, ca = np.divmod(a, 3)
    fb, cb = np.divmod(b, 3)
    c1 = np.r_[3 * fa + ca, 3 * fa + (ca + 1) % 3]
    c2 = np.r_[3 * fb + (cb + 1) % 3, 3 * fb + cb]
    graph = coo_matrix((np.ones(len(c1)), (c1, c2)), shape=(3 * Fw, 3 * Fw))
    _, group = connected_components(graph, directed=False)
    _, corner_vertex = np.unique(group, return_inverse=True)
    return corner_vertex.reshape(Fw, 3), stats


def doubled_edges(corner_vertex: np.ndarray) -> np.ndarray:
    """(D, 2) working-vertex pairs joined by more than one working edge: used by more than two
    faces of ``corner_vertex`` (the working faces)."""
    he = np.stack([corner_vertex, np.roll(corner_vertex, -1, 1)], -1).reshape(-1, 2)
    n = int(corner_vertex.max()) + 1
    keys, counts = np.unique(he.min(1) * n + he.max(1), return_counts=True)
    d = keys[counts > 2]
    return np.stack([d // n, d % n], 1)


def fold_cuts(wf: np.ndarray, corner_vertex: np.ndarray, pairs: EdgePairs, vertices: np.ndarray) -> np.ndarray:
    """(P,) bool over ``pairs.a``: the *folds* to cut so that no two working edges join the
    same two working vertices (:func:`doubled_edges`).

    A fold is an edge of a face and its own copy wound the other way (the same welded
    vertices): the rim of a double-sided open surface, where its front and back meet. The two
    sides stay joined there (a leaf card unfolds like a book, one island), but a chord of the
    sheet (an inner edge between two rim vertices: a quad card's diagonal, a grid's corner
    triangle) then exists twice, front and back, between the same two working vertices. The
    working mesh is no longer a simplicial mesh, and everything that reads edges from vertex
    ids (pinch splits, disk cuts, SLIM) sees three or four faces on it: a region holding both
    copies fell apart there (a double-sided grid: four one-face islands at its corners, and
    merge trials that could not join them, 19.5 s of its 25.8 s unwrap). Cutting the folds at
    one end of the chord gives that vertex a front and a back copy, and the chord's two copies
    distinct ends; the end whose folds are shorter is cut (less seam)."""
    cut = np.zeros(len(pairs.a), bool)
    doubled = doubled_edges(corner_vertex)
    if not len(doubled):
        return cut
    he = pairs.half_edges
    fa, fb = pairs.a // 3, pairs.b // 3
    twin = (np.sort(wf[fa], 1) == np.sort(wf[fb], 1)).all(1)
    ca = pairs.a % 3
    ends = np.stack([corner_vertex[fa, ca], corner_vertex[fa, (ca + 1) % 3]], 1)  # working ids of each pair's edge
    length = np.linalg.norm(vertices[he[pairs.a, 0]] - vertices[he[pairs.a, 1]], axis=1)
    fold_at = np.zeros(int(corner_vertex.max()) + 1)
    for k in range(2):
        np.add.at(fold_at, ends[twin, k], length[twin])
    for u, v in doubled:
        w = u if (fold_at[u], u) <= (fold_at[v], v) else v
        if fold_at[w] == 0:
            w = v if w == u else u
        cut |= twin & (ends == w).any(1)
    return cut


def face_components(faces: np.ndarray) -> np.ndarray:
    """(F,) connected component of each face (sharing a vertex index), ids by first face."""
    F = len(faces)
    V = int(faces.max()) + 1
    rows = np.repeat(np.arange(F), 3)
    graph = coo_matrix((np.ones(3 * F), (rows, F + faces.ravel())), shape=(F + V, F + V))
    _, labels = connected_components(graph, directed=False)
    labels = labels[:F]
    _, first, inv = np.unique(labels, return_index=True, return_inverse=True)
    rank = np.empty(len(first), np.int64)
    rank[np.argsort(first)] = np.arange(len(first))
    return rank[inv.reshape(-1)]


def prepare_mesh(vertices, faces, name: str = "mesh") -> PreparedMesh:
    """Weld, turn faces wound against their patch, cut non-manifold and inconsistently oriented
    edges, split non-manifold vertices,
    set degenerate faces aside; see the module docstring. Raises ``InputError`` on bad input
    (no faces, NaN, out-of-range indices, only degenerate faces)."""
    vertices, faces = validate_mesh(vertices, faces, name)
    weld = weld_ids(vertices, WELD_TOL)
    degenerate = degenerate_faces(vertices, faces, weld)
    copy_of = np.full(len(faces), -1, np.int64)
    live = np.flatnonzero(~degenerate)
    orig = copied_faces(weld[faces[live]])
    copy_of[live[orig >= 0]] = live[orig[orig >= 0]]
    keep = np.flatnonzero(~degenerate & (copy_of < 0))
    if len(keep) == 0:
        raise InputError(f"{name}: every face is degenerate (zero area or a repeated vertex)")
    wf = weld[faces[keep]]
    pairs = edge_pairs(wf)
    turned = consistent_winding(wf, triangle_areas(vertices, faces[keep]), pairs)
    fk = faces[keep]
    if turned.any():
        wf[turned] = wf[turned][:, [0, 2, 1]]
        fk[turned] = fk[turned][:, [0, 2, 1]]  # the corners in the working faces' order
    if turned.any() or pairs.nonmanifold:
        # faces on an edge of more than two are matched by their normals (a double-sided
        # surface stays two surfaces, not one island per face)
        pairs = edge_pairs(wf, face_normals(vertices, fk))
    corner_vertex_w, stats = corner_groups(wf, pairs)
    wpos = np.zeros((int(wf.max()) + 1, 3))
    wpos[wf.ravel()] = vertices[fk.ravel()]
    cut = np.zeros(len(pairs.a), bool)
    for _ in range(3):  # a cut that leaves a chord doubled (both ends shared) is followed by another
        more = fold_cuts(wf, corner_vertex_w, pairs, wpos) & ~cut
        if not more.any():
            break
        cut |= more
        corner_vertex_w, stats = corner_groups(wf, pairs, cut)
    stats["folds_cut"] = int(cut.sum())
    # position of a working vertex: the input position of (any) one of its corners
    pos = np.zeros((int(corner_vertex_w.max()) + 1, 3))
    pos[corner_vertex_w.ravel()] = vertices[fk.ravel()]
    corner_vertex = np.full(faces.shape, -1, np.int64)
    corner_vertex[keep] = corner_vertex_w
    corner_vertex[keep[turned]] = corner_vertex_w[turned][:, [0, 2, 1]]  # back to the input's corners
    work_face = np.full(len(faces), -1, np.int64)
    work_face[keep] = np.arange(len(keep))
    n_points = len(np.unique(weld[faces[keep]]))
    stats.update({"input_vertices": int(len(vertices)), "input_faces": int(len(faces)),
                  "welded_vertices": int(len(np.unique(faces)) - len(np.unique(weld[faces]))),
                  "degenerate_faces": int(degenerate.sum()), "copied_faces": int((copy_of >= 0).sum()),
                  "split_vertices": int(len(pos) - n_points), "turned_faces": int(turned.sum())})
    comp = face_components(corner_vertex_w)
    stats["components"] = int(comp.max()) + 1
    return PreparedMesh(vertices, faces, pos, corner_vertex_w, work_face, keep, corner_vertex, comp, turned, stats,
                        copy_of)
