"""Clip a triangle mesh to ``{field > 0}`` of a piecewise-linear scalar field (marching triangles).

Each face keeps the part where the linearly interpolated field is positive: a face with
all three vertices inside is kept, with none inside dropped, with one inside becomes
one triangle, with two inside a quad split in two triangles. The cut points lie on
the mesh edges at ``t = f_a / (f_a - f_b)`` (``a`` inside, ``b`` outside), and every
per-vertex attribute (3D position, UV, other fields) is interpolated with the same
``t``. A cut point is made once per edge, so neighbouring faces stay connected and the
border is the field's iso-line, not a staircase of whole faces.

Example: on a flat grid over [0,1]^2 with ``field = 0.3 - x`` the kept region is exactly
``x < 0.3`` (area 0.3), whatever the grid resolution.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

#: field values with |f| below this fraction of max|f| count as outside, so a cut never
#: lands on an inside vertex (which would make zero-area slivers).
SNAP_REL = 1e-7


class Clipped(NamedTuple):
    attrs: np.ndarray  # (V', D) interpolated attributes of the kept mesh
    faces: np.ndarray  # (F', 3) int64, same orientation as the input faces
    field: np.ndarray  # (V',) field value (0 on cut vertices)
    source_face: np.ndarray  # (F',) input face each output face came from
    source_vertex: np.ndarray  # (V',) input vertex each output vertex is (-1 for cut points)


def clip_mesh(attrs: np.ndarray, faces: np.ndarray, field: np.ndarray) -> Clipped:
    """Keep ``{field > 0}`` of the mesh ``(attrs (V, D), faces (F, 3))``; see module docstring.

    Unused vertices are removed; output vertex order is the kept input vertices (in input
    order) followed by the cut points (sorted by edge).
    """
    attrs = np.asarray(attrs, np.float64)
    faces = np.asarray(faces, np.int64)
    field = np.asarray(field, np.float64).copy()
    scale = float(np.abs(field).max()) if len(field) else 0.0
    field[np.abs(field) <= SNAP_REL * scale] = -SNAP_REL * scale
    inside = field > 0
    fin = inside[faces]
    n_in = fin.sum(1)
    # rotate each partial face so that, for 1 inside, corner 0 is inside; for 2 inside,
    # corner 2 is outside (rotation keeps the orientation)
    shift = np.zeros(len(faces), np.int64)
    one, two = n_in == 1, n_in == 2
    shift[one] = np.argmax(fin[one], axis=1)
    shift[two] = (np.argmin(fin[two], axis=1) + 1) % 3
    idx = (np.arange(3)[None, :] + shift[:, None]) % 3
    rot = np.take_along_axis(faces, idx, axis=1)

    V = len(attrs)
    # cut edges: (inside vertex, outside vertex)
    e1 = np.concatenate([rot[one][:, [0, 1]], rot[one][:, [0, 2]],
                         rot[two][:, [1, 2]], rot[two][:, [0, 2]]])
    key = np.minimum(e1[:, 0], e1[:, 1]) * V + np.maximum(e1[:, 0], e1[:, 1])
    ukey, first, inv = np.unique(key, return_index=True, return_inverse=True)
    a, b = e1[first, 0], e1[first, 1]
    t = field[a] / (field[a] - field[b])
    cut_attrs = (1 - t)[:, None] * attrs[a] + t[:, None] * attrs[b]
    cut_id = V + inv.reshape(-1)
    n1, n2 = int(one.sum()), int(two.sum())
    c_ab, c_ac = cut_id[:n1], cut_id[n1:2 * n1]
    c_bc, c_ac2 = cut_id[2 * n1:2 * n1 + n2], cut_id[2 * n1 + n2:]
    r1, r2 = rot[one], rot[two]
    full = n_in == 3
    new_faces = np.concatenate([
        faces[full],
        np.stack([r1[:, 0], c_ab, c_ac], 1),
        np.stack([r2[:, 0], r2[:, 1], c_bc], 1),
        np.stack([r2[:, 0], c_bc, c_ac2], 1),
    ])
    src = np.concatenate([np.flatnonzero(full), np.flatnonzero(one), np.flatnonzero(two), np.flatnonzero(two)])
    all_attrs = np.concatenate([attrs, cut_attrs])
    all_field = np.concatenate([field, np.zeros(len(cut_attrs))])
    used = np.zeros(len(all_attrs), bool)
    used[new_faces.ravel()] = True
    remap = np.cumsum(used) - 1
    order = np.argsort(src, kind="stable")
    source = np.concatenate([np.arange(V), np.full(len(cut_attrs), -1)])
    return Clipped(all_attrs[used], remap[new_faces][order], all_field[used], src[order], source[used])


def grid_faces(resolution: int) -> np.ndarray:
    """(2 (G-1)^2, 3) triangles of a G x G vertex grid (docs/run_folder.md triangulation).

    Cell ``(i, j)`` gives ``(i,j) (i,j+1) (i+1,j+1)`` and ``(i,j) (i+1,j+1) (i+1,j)``,
    counter-clockwise in UV (u = column, right; v = row, up); vertex ``(i, j)`` is ``i*G + j``.
    """
    G = int(resolution)
    i, j = np.meshgrid(np.arange(G - 1), np.arange(G - 1), indexing="ij")
    a = (i * G + j).ravel()
    b, c, d = a + 1, a + G + 1, a + G
    return np.stack([np.stack([a, b, c], 1), np.stack([a, c, d], 1)], 1).reshape(-1, 3)
