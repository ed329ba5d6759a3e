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

Slivers: an iso-line passing within a small fraction ``t`` of an edge from a vertex would
leave triangles of area ~``t`` (or ``t^2``) of their face, down to float rounding. With
``plane`` (the two attribute columns of a flat parameterisation, the UVs), a vertex whose
nearest crossing lies within ``SNAP_FRACTION`` of an edge from it is moved onto that
crossing and becomes an *on-line* vertex (field 0): faces then keep it as a corner and no
cut point is made beside it. The border is still the field's piecewise-linear iso-line, and
every cut point sits at least ``SNAP_FRACTION`` of its edge from both ends. A snap that
would shrink an incident face below ``SNAP_MIN_AREA`` of its area in ``plane`` (or turn it
over) is not made. The rule is symmetric in the sign of ``field``, so clipping with
``field`` and ``-field`` gives two halves with the same border.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from mnacore.triangles import signed_areas

#: field values with |f| below this fraction of max|f| are on the line (exactly 0).
SNAP_REL = 1e-7
#: a vertex within this fraction of an edge from the crossing on it moves onto the crossing.
#: Cut triangles then keep at least ~SNAP_FRACTION^2 of their face's area (2 %).
SNAP_FRACTION = 0.15
#: the UV columns of the (xyz, uv, ...) attribute rows every caller clips
UV_COLUMNS = (3, 4)
#: a snap may shrink an incident face (area in ``plane``) to no less than this fraction.
SNAP_MIN_AREA = 0.25


class Clipped(NamedTuple):
    attrs: np.ndarray  # (V', D) interpolated attributes of the kept mesh
    faces: np.ndarray  # (F', 3) int64, same orientation as the input faces
    field: np.ndarray  # (V',) field value (0 on cut vertices)
    source_face: np.ndarray  # (F',) input face each output face came from
    source_vertex: np.ndarray  # (V',) input vertex each output vertex is (-1 for cut points)


def _snap(attrs: np.ndarray, faces: np.ndarray, field: np.ndarray, plane) -> tuple[np.ndarray, np.ndarray]:
    """Move vertices within ``SNAP_FRACTION`` of a crossing onto it (see module docstring)."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e = e[np.sign(field[e[:, 0]]) * np.sign(field[e[:, 1]]) < 0]
    if len(e) == 0:
        return attrs, field
    t = np.abs(field[e[:, 0]]) / (np.abs(field[e[:, 0]]) + np.abs(field[e[:, 1]]))  # from e[:, 0]
    near = np.concatenate([e[:, 0], e[:, 1]])
    frac = np.concatenate([t, 1.0 - t])
    far = np.concatenate([e[:, 1], e[:, 0]])
    ok = frac < SNAP_FRACTION
    near, frac, far = near[ok], frac[ok], far[ok]
    if len(near) == 0:
        return attrs, field
    order = np.lexsort((frac, near))  # per vertex, its nearest crossing first
    near, frac, far = near[order], frac[order], far[order]
    first = np.r_[True, near[1:] != near[:-1]]
    near, frac, far = near[first], frac[first], far[first]
    target = (1 - frac)[:, None] * attrs[near] + frac[:, None] * attrs[far]
    cols = list(plane)
    before = signed_areas(attrs[:, cols], faces)
    snapped = np.ones(len(near), bool)
    for _ in range(4):  # un-snap vertices whose faces would shrink too much or turn over
        moved = attrs.copy()
        moved[near[snapped]] = target[snapped]
        after = signed_areas(moved[:, cols], faces)
        bad = ~((after * np.sign(before) >= SNAP_MIN_AREA * np.abs(before)) | (before == 0))
        if not bad.any():
            break
        bad_vertex = np.zeros(len(attrs), bool)
        bad_vertex[faces[bad].ravel()] = True
        snapped &= ~bad_vertex[near]
    else:
        return attrs, field
    field = field.copy()
    field[near[snapped]] = 0.0
    return moved, field


@dataclass(frozen=True)
class _Cases:
    """Faces by how the iso-line crosses them, each partial face rotated so that, for 1 inside,
    corner 0 is inside (and, with one on-line corner, corner 1 is outside); for 2 inside,
    corner 2 is outside (rotation keeps the orientation).

    Attributes:
        full, one, two, mixed: (F,) masks: no corner outside (and one inside); 1 inside 2
            outside; 2 inside 1 outside; inside, on-line, outside (one triangle).
        rot: (F, 3) the faces rotated as above.
        m_out1: (mixed faces,) whether corner 1 (else corner 2) of a mixed face is outside.
    """

    full: np.ndarray
    one: np.ndarray
    two: np.ndarray
    mixed: np.ndarray
    rot: np.ndarray
    m_out1: np.ndarray


def _cases(faces: np.ndarray, field: np.ndarray) -> _Cases:
    fin = (field > 0)[faces]
    fout = (field < 0)[faces]
    n_in, n_out = fin.sum(1), fout.sum(1)
    shift = np.zeros(len(faces), np.int64)
    mixed = (n_in == 1) & (n_out == 1)
    one, two = (n_in == 1) & (n_out == 2), (n_in == 2) & (n_out == 1)
    shift[one] = np.argmax(fin[one], axis=1)
    shift[two] = (np.argmin(~fout[two], axis=1) + 1) % 3
    shift[mixed] = np.argmax(fin[mixed], axis=1)
    idx = (np.arange(3)[None, :] + shift[:, None]) % 3
    rot = np.take_along_axis(faces, idx, axis=1)
    m_out1 = field[rot[mixed][:, 1]] < 0
    return _Cases((n_in > 0) & (n_out == 0), one, two, mixed, rot, m_out1)


def _cut_points(attrs: np.ndarray, field: np.ndarray, c: _Cases) -> tuple[np.ndarray, np.ndarray]:
    """(cut point attributes, id of the cut point of every cut edge in :func:`_split_faces`'s
    order): one point per cut edge (inside vertex, outside vertex), linear in ``field``."""
    V = len(attrs)
    rm, r1, r2 = c.rot[c.mixed], c.rot[c.one], c.rot[c.two]
    e_mixed = np.where(c.m_out1[:, None], rm[:, [0, 1]], rm[:, [0, 2]])
    e1 = np.concatenate([r1[:, [0, 1]], r1[:, [0, 2]], r2[:, [1, 2]], r2[:, [0, 2]], e_mixed])
    key = np.minimum(e1[:, 0], e1[:, 1]) * V + np.maximum(e1[:, 0], e1[:, 1])
    ukey, first, inv = np.unique(key, return_index=True, return_inverse=True)
    a, b = e1[first, 0], e1[first, 1]
    t = field[a] / (field[a] - field[b])
    return (1 - t)[:, None] * attrs[a] + t[:, None] * attrs[b], V + inv.reshape(-1)


def _split_faces(faces: np.ndarray, c: _Cases, cut_id: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(kept and new faces, source face of each)."""
    n1, n2 = int(c.one.sum()), int(c.two.sum())
    c_ab, c_ac = cut_id[:n1], cut_id[n1:2 * n1]
    c_bc, c_ac2 = cut_id[2 * n1:2 * n1 + n2], cut_id[2 * n1 + n2:2 * n1 + 2 * n2]
    c_m = cut_id[2 * n1 + 2 * n2:]
    rm, r1, r2 = c.rot[c.mixed], c.rot[c.one], c.rot[c.two]
    # inside p, then (cut, on-line z) or (z, cut) in the face's own corner order
    tri_mixed = np.where(c.m_out1[:, None], np.stack([rm[:, 0], c_m, rm[:, 2]], 1),
                         np.stack([rm[:, 0], rm[:, 1], c_m], 1))
    new_faces = np.concatenate([
        faces[c.full],
        np.stack([r1[:, 0], c_ab, c_ac], 1),
        np.stack([r2[:, 0], r2[:, 1], c_bc], 1),
        np.stack([r2[:, 0], c_bc, c_ac2], 1),
        tri_mixed.reshape(-1, 3),
    ])
    src = np.concatenate([np.flatnonzero(c.full), np.flatnonzero(c.one), np.flatnonzero(c.two),
                          np.flatnonzero(c.two), np.flatnonzero(c.mixed)])
    return new_faces, src


def clip_mesh(attrs: np.ndarray, faces: np.ndarray, field: np.ndarray, plane: tuple[int, int] | None = None) -> Clipped:
    """Keep ``{field > 0}`` of the mesh ``(attrs (V, D), faces (F, 3))``; see module docstring.

    ``plane``: the two columns of ``attrs`` that hold a flat parameterisation (UVs); given,
    vertices close to the iso-line snap onto it instead of leaving slivers. Unused vertices
    are removed; output vertex order is the kept input vertices (in input order) followed
    by the cut points (sorted by edge). A snapped vertex keeps its ``source_vertex``.
    """
    attrs = np.asarray(attrs, np.float64)
    faces = np.asarray(faces, np.int64)
    field = np.asarray(field, np.float64).copy()
    scale = float(np.abs(field).max()) if len(field) else 0.0
    field[np.abs(field) <= SNAP_REL * scale] = 0.0
    if plane is not None and len(faces):
        attrs, field = _snap(attrs, faces, field, plane)
    cases = _cases(faces, field)
    cut_attrs, cut_id = _cut_points(attrs, field, cases)
    new_faces, src = _split_faces(faces, cases, cut_id)
    V = len(attrs)
    all_attrs = np.concatenate([attrs, cut_attrs])
    all_field = np.concatenate([field, np.zeros(len(cut_attrs))])
    used = np.zeros(len(all_attrs), bool)
    used[new_faces.ravel()] = True
    remap = np.cumsum(used) - 1
    order = np.argsort(src, kind="stable")
    source = np.concatenate([np.arange(V), np.full(len(cut_attrs), -1)])
    return Clipped(all_attrs[used], remap[new_faces][order], all_field[used], src[order], source[used])
