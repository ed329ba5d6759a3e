"""Small holes stay holes: flatten a region with its small holes filled, then drop the fill.

A scan or a cleaned-up mesh often has small holes (a missing face, a gap the scanner did
not see). :func:`texture.flatten.cut_to_disk` makes a disk of a region with holes by cutting
from every hole to the border: with many holes the cuts join them into a tree, and the
island becomes a ragged, branching shape with long seams that packs poorly (measured in
docs/unwrap.md). The holed rule of :mod:`texture.unwrap_islands`
keeps a region's holes only where its uncut conformal map is already within the bound, with
no slits.

Here each small hole (not the region's longest border loop, its outer border) is closed by
a fan of faces to a new vertex at the hole's centroid: the region becomes a disk (or, with
handles, is cut only for them), and is flattened like any disk: a start map, SLIM, slits.
Dropping the fill leaves each hole as a polygon inside the island: the fill faces stayed
unflipped and inside the border, so the hole's border neither crosses itself nor the rest.
A hole is small when its fan covers at most ``FILL_AREA`` of the region's area: the fill
then barely constrains the map (SLIM treats its faces as surface).

The filled region may need slits where the cut one would not: cuts from the holes to the
border also relieve a region's curvature, and the slits that replace them can open into
wide notches. So the caller keeps the filled flattening only where its seams (slits, cuts
for handles) are no longer than the cuts to a disk it saves (:func:`cut_seam`), and its
slits stop there (``max_added``): a slit past it is never relaxed. On an unseen cow (5.8k
faces) three merge trials' filled flattenings cut 6-8 slits each (33 s) that no trial could
use; bounded, the unwrap is the same byte for byte and its merge stage took 36 s, not 73.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mnacore.triangles import signed_areas, triangle_areas

from .flatten import cut_to_disk, relax_disk, start_map
from .relax import boundary_edges, boundary_length
from .slits import slit_island

#: a hole whose fan covers at most this share of the region's 3D area is filled for flattening
FILL_AREA = 0.02


@dataclass(frozen=True)
class Filled:
    """A region flattened with its small holes filled, the fill dropped: ``faces`` in the
    region's order into ``uv`` (isometric scale); ``source``: the region's vertex of each UV
    vertex; ``added``: the 3D length of seam its slits and cuts added; ``cut_edges``: the
    edges its cut to a disk (handles) took."""

    faces: np.ndarray
    uv: np.ndarray
    source: np.ndarray
    added: float
    cut_edges: int


def cut_seam(xyz: np.ndarray, faces: np.ndarray, disk) -> float:
    """3D length of the cuts :func:`texture.flatten.cut_to_disk` made (``disk``) in the region."""
    return 0.5 * (boundary_length(xyz[disk.source], disk.faces) - boundary_length(xyz, faces))


def hole_fans(xyz: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """(vertices with one centroid per filled hole appended, the faces with the fans appended
    after them), or None where no hole is small enough (or the region has one border loop)."""
    import igl

    faces = np.asarray(faces, np.int64)
    loops = [np.asarray(loop, np.int64) for loop in igl.boundary_loop_all(faces)]
    if len(loops) < 2:
        return None
    perimeter = [float(np.linalg.norm(xyz[lp] - xyz[np.roll(lp, -1)], axis=1).sum()) for lp in loops]
    outer = int(np.argmax(perimeter))
    loop_of = np.full(len(xyz), -1)
    for k, lp in enumerate(loops):
        loop_of[lp] = k
    he = boundary_edges(faces)  # in their faces' direction: a fill face runs the other way
    total = float(triangle_areas(xyz, faces).sum())
    points, fans = [xyz], [faces]
    n = len(xyz)
    for k, lp in enumerate(loops):
        if k == outer:
            continue
        edges = he[loop_of[he[:, 0]] == k]
        centre = xyz[lp].mean(0)
        fan = np.column_stack([edges[:, 1], edges[:, 0], np.full(len(edges), len(xyz))])
        if triangle_areas(np.vstack([xyz, centre]), fan).sum() > FILL_AREA * total:
            continue
        fan[:, 2] = n
        points.append(centre[None])
        fans.append(fan)
        n += 1
    if len(fans) == 1:
        return None
    return np.vstack(points), np.concatenate(fans)


def flatten_filled(xyz: np.ndarray, faces: np.ndarray, relax, target: float, max_slits: int,
                   max_added: float = np.inf) -> Filled | None:
    """The region ``(xyz, faces)`` flattened with its small holes filled (see module
    docstring), or None where no hole was filled, a step failed or the map stays above
    ``target`` after its slits. ``relax``: the SLIM options; slits while the energy excess
    exceeds ``target``, at most ``max_slits``.

    ``max_added``: the seam (cuts for handles and slits, :attr:`Filled.added`) a caller can
    use the flattening only under (a merge trial: the seam the union saves,
    :mod:`texture.merge`). Where the cuts reach it, or the slits would reach it while the map
    is still above ``target``, None: no slit is relaxed for a flattening the caller would refuse."""
    fill = hole_fans(xyz, faces)
    if fill is None:
        return None
    p, f = fill
    try:
        disk = cut_to_disk(p, f)
    except (RuntimeError, ValueError, KeyError, IndexError):
        return None
    budget = max_added - cut_seam(p, f, disk)
    if budget <= 0:
        return None
    x = p[disk.source]
    uv = start_map(x, disk.faces, relax.slim_max_faces)
    signed = signed_areas(uv, disk.faces)
    if not np.isfinite(uv).all() or (signed <= 0).any():
        return None
    uv = relax_disk(x, uv * np.sqrt(triangle_areas(x, disk.faces).sum() / signed.sum()), disk.faces, relax)[0]
    cut = slit_island(x, disk.faces, uv, relax, target, max_slits, budget)
    # refused above ``target`` after its slits too: the caller keeps a filled island as it is
    # (holed: no slits and no relaxation later), and the region cut to a disk is flattened to
    # the bound like every island. A 510-face region of an unseen scan (ogre) kept its filled
    # map at excess 233 (SLIM stalled at 243, and a slit's map measured -230 by a cancelling
    # det g, fixed in texture.distortion_faces.symmetric_dirichlet), where cut to a disk it
    # took three slits to 0.031; the split stage then halved 15 other islands around it
    if cut.stopped_by_length or not cut.excess_after <= target:
        return None
    # libigl's cut_mesh keeps the faces and their order: the input's faces come first
    real = cut.faces[:len(faces)]
    used, inv = np.unique(real, return_inverse=True)
    source = disk.source[cut.source[used]]
    if (source >= len(xyz)).any():  # a centroid is only in fill faces
        return None
    f_out = inv.reshape(-1, 3)
    added = 0.5 * (boundary_length(xyz[source], f_out) - boundary_length(xyz, faces))
    return Filled(f_out, cut.uv[used], source, added, disk.cut_edges)
