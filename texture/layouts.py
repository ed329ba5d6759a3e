"""Pieces as islands: each piece prepared once (welded, islands split), merged into one
UV mesh, or with one island cut in two.

A :class:`Prepared` piece is computed once per piece and then shared: by the island
counts of the orientation stage, the relaxation, the unmirroring and every candidate
layout of the packing search (the layouts share all pieces but the cut one).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mnacore.triangles import signed_areas

from .clip import UV_COLUMNS, clip_mesh
from .islands import unique_rows, uv_islands
from .trim import Piece


@dataclass(frozen=True)
class Prepared:
    """A piece welded (:func:`welded`) with vertices shared by islands split
    (:func:`split_shared`), and the island of each of its faces.

    Attributes:
        source: the piece as given (what a cut clips).
        piece: the prepared piece (same faces, in the same order).
        island: (F,) island id per face, 0-based within the piece (None for an empty piece).
    """

    source: Piece
    piece: Piece
    island: np.ndarray | None

    @property
    def n_islands(self) -> int:
        return 0 if self.island is None else int(self.island.max()) + 1


def prepare(p: Piece) -> Prepared:
    """``p`` prepared for packing (see :class:`Prepared`)."""
    if len(p.faces) == 0:
        return Prepared(p, p, None)
    q = welded(p)
    isl = uv_islands(q.faces, q.uv)
    return Prepared(p, split_shared(q, isl), isl)


def welded(p: Piece) -> Piece:
    """One vertex per distinct (UV, 3D) point: clipping can leave exact duplicates, which
    :func:`uv_islands` treats as one point but xatlas (by index) as a cut, splitting the island."""
    first, inverse = unique_rows(np.column_stack([p.uv, p.xyz]))
    if len(first) == len(p.uv):
        return p
    return Piece(p.chart, p.xyz[first], p.uv[first], inverse.reshape(-1)[p.faces])


def split_shared(p: Piece, island: np.ndarray) -> Piece:
    """One vertex per (vertex, island): islands touching at a single vertex (connected through
    no edge, so separate islands) must not share it, or packing one would move the other's corner."""
    n = int(island.max()) + 1
    key = p.faces.ravel() * n + np.repeat(island, 3)
    uniq, inverse = np.unique(key, return_inverse=True)
    if len(uniq) == len(p.xyz):
        return p
    return Piece(p.chart, p.xyz[uniq // n], p.uv[uniq // n], inverse.reshape(-1, 3))


def island_count(layout: list[Prepared]) -> int:
    """Islands the prepared pieces make (as :func:`merge` numbers them)."""
    return sum(p.n_islands for p in layout)


@dataclass(frozen=True)
class Merged:
    """Prepared pieces concatenated into one split-vertex mesh.

    Attributes:
        xyz: (V, 3) unit-ball positions.
        uv: (V, 2) chart-local UVs.
        faces: (F, 3).
        chart: (F,) chart per face.
        island: (F,) island per face, numbered piece by piece.
    """

    xyz: np.ndarray
    uv: np.ndarray
    faces: np.ndarray
    chart: np.ndarray
    island: np.ndarray

    @property
    def islands(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(uv, faces, island): what the packer takes."""
        return self.uv, self.faces, self.island


def merge(layout: list[Prepared]) -> Merged:
    """Concatenate the non-empty prepared pieces."""
    xyz, uv, faces, chart, island = [], [], [], [], []
    v_off = i_off = 0
    for pp in layout:
        if pp.island is None:
            continue
        p = pp.piece
        xyz.append(p.xyz)
        uv.append(p.uv)
        faces.append(p.faces + v_off)
        chart.append(np.full(len(p.faces), p.chart))
        island.append(pp.island + i_off)
        v_off += len(p.xyz)
        i_off += pp.n_islands
    if not faces:
        raise ValueError("no chart has any in-domain surface left: nothing to texture")
    return Merged(*(np.concatenate(a) for a in (xyz, uv, faces, chart, island)))


def merge_pieces(pieces: list[Piece]) -> Merged:
    """:func:`merge` of pieces prepared here."""
    return merge([prepare(p) for p in pieces])


def unmirrored(pp: Prepared) -> Piece:
    """The prepared piece with every island whose UVs run clockwise, seen from its faces'
    front (the side their winding faces), reflected (u -> -u): a texture then reads the right
    way round from outside. Flattening and packing never reflect (SLIM is flip-free, the
    packer only rotates), so this holds in the packed atlas."""
    if pp.island is None:
        return pp.source
    q, isl = pp.piece, pp.island
    mirrored = np.bincount(isl, weights=signed_areas(q.uv, q.faces)) < 0
    if not mirrored.any():
        return pp.source
    flip = np.zeros(len(q.uv), bool)
    flip[q.faces[mirrored[isl]].ravel()] = True  # split vertices: each belongs to one island
    uv = q.uv.copy()
    uv[flip, 0] *= -1.0
    return Piece(q.chart, q.xyz, uv, q.faces)


def cut_island(pieces: list[Piece], k: int, island: int, long_axis: bool = True,
               fraction: float | None = None) -> list[Piece]:
    """``pieces`` with island ``island`` of piece ``k`` cut in two by a straight UV line.

    The line runs across the principal axis of the island's UV area (``long_axis``) or along
    it, through the island's UV centroid (``fraction`` None) or at the position that leaves
    ``fraction`` of the island's UV area (by face centre) on the low side of the axis: 0.25
    cuts about a quarter off one end, 0.75 off the other. The cut is an iso-line cut like
    every other border; the parts become separate pieces (same chart). The result lists the
    other pieces in order, then the rest of piece ``k``, then the two halves.
    """
    if fraction is not None and not 0.0 < fraction < 1.0:
        raise ValueError(f"cut_island: fraction must lie in (0, 1), got {fraction}")
    p = pieces[k]
    sel = uv_islands(p.faces, p.uv) == island
    out = [q for j, q in enumerate(pieces) if j != k]
    if (~sel).any():
        out.append(Piece(p.chart, p.xyz, p.uv, p.faces[~sel]))
    return out + _halves(Piece(p.chart, p.xyz, p.uv, p.faces[sel]), _cut_field(p, sel, long_axis, fraction))


def cut_layout(layout: list[Prepared], k: int, island: int, long_axis: bool = True,
               fraction: float | None = None) -> list[Prepared]:
    """:func:`cut_island` on prepared pieces: only the new pieces are prepared."""
    cut = cut_island([pp.source for pp in layout], k, island, long_axis, fraction)
    kept = [pp for j, pp in enumerate(layout) if j != k]
    return kept + [prepare(p) for p in cut[len(kept):]]


def _cut_field(p: Piece, sel: np.ndarray, long_axis: bool, fraction: float | None) -> np.ndarray:
    """(V,) signed distance of every vertex of ``p`` from the cut line of the faces ``sel``."""
    w = p.uv_area()[sel]
    centre = p.uv[p.faces[sel]].mean(1)
    c = (centre * w[:, None]).sum(0) / w.sum()
    d = centre - c
    axis = np.linalg.eigh((d * w[:, None]).T @ d)[1][:, -1 if long_axis else 0]
    at = 0.0
    if fraction is not None:
        proj = d @ axis
        order = np.argsort(proj, kind="stable")
        cum = np.cumsum(w[order])
        at = proj[order][min(int(np.searchsorted(cum, fraction * cum[-1])), len(order) - 1)]
    return (p.uv - c) @ axis - at


def _halves(p: Piece, field: np.ndarray, passes: int = 4) -> list[Piece]:
    """``p`` cut at ``field = 0`` into exactly two islands where possible.

    A straight line across a non-convex island can leave several pieces on one side: every
    piece but the largest on each side goes over to the other side (its vertices' field
    changes sign, and the cut is redone), so the cut adds one island, not several.
    """
    attrs = np.column_stack([p.xyz, p.uv])
    field = field.copy()
    for _ in range(passes):
        halves, changed = [], False
        for sign in (1.0, -1.0):
            c = clip_mesh(attrs, p.faces, sign * field, plane=UV_COLUMNS)
            half = Piece(p.chart, c.attrs[:, :3], c.attrs[:, 3:5], c.faces)
            halves.append(half)
            if len(half.faces) == 0:
                continue
            isl = uv_islands(half.faces, half.uv)
            if isl.max() == 0:
                continue
            keep = int(np.argmax(np.bincount(isl, weights=half.uv_area())))
            verts = c.source_vertex[np.unique(half.faces[isl != keep])]
            verts = verts[verts >= 0]
            if len(verts):
                field[verts] = -sign * np.maximum(np.abs(field[verts]), 1e-9)
                changed = True
        if not changed:
            break
    return [h for h in halves if len(h.faces)]
