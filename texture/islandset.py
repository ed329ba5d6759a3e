"""The islands of a split-vertex UV mesh as the packer sees them, computed once per mesh.

:class:`IslandSet` holds the per-island vertex lists and, computed on first use, the
outline mesh handed to xatlas (:class:`OutlineMesh`) with the fit weight of every vertex.
Every packing stage (:mod:`texture.placement`, :mod:`texture.scale_search`,
:mod:`texture.shelf`, :mod:`texture.mirrors`) reads it and none changes it.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from mnacore.triangles import triangle_areas

from .outlines import island_outlines, refine_slivers

#: faces below this fraction of the median UV area carry no weight in the fit (xatlas drops them).
SOLID_FACE_REL = 1e-2


@dataclass(frozen=True)
class OutlineMesh:
    """What xatlas is handed: the islands' outlines over their own vertices (and, inside
    outlines re-triangulated for xatlas's rasteriser, vertices placed by theirs)."""

    uv: np.ndarray
    """(W + S, 2) outline vertices (chart units)."""
    faces: np.ndarray
    """(G, 3) outline faces, indices into ``uv``."""
    island: np.ndarray
    """(G,) island of each outline face."""
    src: np.ndarray
    """(W,) our vertex of each outline vertex."""
    weight: np.ndarray
    """(V,) fit weight per vertex of the whole mesh (0 off the outlines)."""
    frame: np.ndarray
    """(S, 3) for each vertex after the first W (inside a re-triangulated outline:
    :func:`texture.outlines.refine_slivers`), three outline vertices among the first W ..."""
    coef: np.ndarray
    """(S, 3) ... and its affine weights on them."""
    vert_island: np.ndarray
    """(W + S,) island of each outline vertex."""

    def at(self, pos: np.ndarray) -> np.ndarray:
        """The outline's vertices at the positions ``pos (V, 2)`` of the mesh's vertices (its
        first W are mesh vertices, the others affine combinations of them)."""
        real = pos[self.src]
        return np.concatenate([real, np.einsum("sk,skd->sd", self.coef, real[self.frame])])

@dataclass(frozen=True)
class IslandSet:
    """Islands ``island (F,)`` of the UV mesh ``(uv (V,2), faces (F,3))``; every vertex belongs
    to faces of one island.

    xatlas is handed each island's *outline*, not its faces (:attr:`outline`): the packer
    only sees the region an island covers, and an ear-clipped outline covers the same region
    with a tenth of the faces or fewer (each xatlas call about twice as fast, same layouts).
    The outline's vertices are the island's border vertices, so the fit in
    :func:`texture.placement.place` uses them and places the whole island with the same motion.
    """

    uv: np.ndarray
    faces: np.ndarray
    island: np.ndarray
    outlines: bool = True

    @classmethod
    def of(cls, uv, faces, island, outlines: bool = True) -> IslandSet:
        return cls(np.asarray(uv, np.float64), np.asarray(faces, np.int64), np.asarray(island, np.int64), outlines)

    @cached_property
    def n(self) -> int:
        return int(self.island.max()) + 1

    @cached_property
    def vert_island(self) -> np.ndarray:
        """(V,) island of each vertex (-1 for a vertex of no face)."""
        vert_island = np.full(len(self.uv), -1)
        vert_island[self.faces.ravel()] = np.repeat(self.island, 3)
        return vert_island

    @cached_property
    def area(self) -> float:
        return float(triangle_areas(self.uv, self.faces).sum())

    @cached_property
    def verts(self) -> list[np.ndarray]:
        """Vertex indices of each island."""
        used = np.flatnonzero(self.vert_island >= 0)
        order = used[np.argsort(self.vert_island[used], kind="stable")]
        return np.split(order, np.cumsum(np.bincount(self.vert_island[used], minlength=self.n))[:-1])

    @cached_property
    def outline(self) -> OutlineMesh:
        x_faces = island_outlines(self.uv, self.faces, self.island) if self.outlines else self.faces
        src, inverse = np.unique(x_faces, return_inverse=True)
        x_island = self.vert_island[x_faces[:, 0]]
        weight = self._fit_weight(x_faces, x_island)
        uv, faces = self.uv[src], inverse.reshape(-1, 3)
        frame, coef = np.zeros((0, 3), np.int64), np.zeros((0, 3))
        if self.outlines:  # fans of slivers cost xatlas's rasteriser the most
            faces, x_island, frame, coef = refine_slivers(uv, faces, x_island)
        mesh = OutlineMesh(uv, faces, x_island, src, weight, frame, coef,
                           self.vert_island[src[np.concatenate([np.arange(len(src)), frame[:, 0]])]])
        return replace(mesh, uv=mesh.at(self.uv))

    def _fit_weight(self, x_faces: np.ndarray, x_island: np.ndarray) -> np.ndarray:
        """Vertex weight: area of its solid faces, so slivers xatlas drops never steer the fit
        ("solid" against the island's own median: outlines and whole islands mix)."""
        area = triangle_areas(self.uv, x_faces)
        order = np.argsort(x_island, kind="stable")
        cuts = np.cumsum(np.bincount(x_island, minlength=self.n))[:-1]
        median = np.zeros(self.n)
        for i, a in enumerate(np.split(area[order], cuts)):
            median[i] = np.median(a) if len(a) else 0.0
        solid = area > SOLID_FACE_REL * median[x_island]
        return np.bincount(x_faces[solid].ravel(), np.repeat(area[solid], 3), len(self.uv))

    def outline_mirrored(self, flip: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:attr:`outline` arrays with the islands where ``flip`` (n,) is set reflected (u -> -u)."""
        o = self.outline
        if not flip.any():
            return o.uv, o.faces, o.island
        uv = o.uv.copy()
        uv[flip[o.vert_island], 0] *= -1.0  # the inner vertices' affine weights survive a mirror
        return uv, o.faces, o.island

    def verify(self, uv: np.ndarray, resolution: int) -> tuple[int, float]:
        """:func:`texture.verify.verify_packing` of the placement ``uv (V, 2)``, rasterised over
        the outlines (the same region per island, so the same texels up to centres lying
        exactly on an outline's inner edges), by runs of texels (outline faces are long fans)."""
        from .verify import verify_packing

        o = self.outline
        return verify_packing(o.at(uv), o.faces, o.island, resolution)

    def inside(self, px: np.ndarray, resolution: int) -> bool:
        """Whether every island vertex of ``px`` (V, 2 texels) lies in ``[0, resolution]^2``."""
        used = np.concatenate(self.verts)
        return bool(px[used].min() >= 0 and px[used].max() <= resolution)
