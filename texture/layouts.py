"""Pieces as islands: each piece prepared once (welded, islands split), or merged into one UV mesh.

A :class:`Prepared` piece is computed once per piece and then shared: by the island
counts of the orientation stage, the relaxation, the unmirroring and the islands handed
to the packing search (:func:`texture.atlas_stages.layout_islands`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mnacore.triangles import signed_areas

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
