"""Spikes: thin protrusions of an island's flattened outline, cut off at their necks for packing.

A limb, a tail or an arm that the chart assignment left on a body's island unrolls as a
thin strip sticking out of the body's blob: it widens the island's footprint by its whole
length, and what lies beside it stays empty (a cow's legs and tail, a mascot's arm, a
starfish's arm). The packing search's halvings (:func:`texture.halving.halve_across`) cut
across the island's principal axes at 15-85 % of its area, so they never cut such a strip
off; they cut the body in two instead (the cow: three such halvings, 2.5 units of seam,
utilisation 0.58). Cut at its neck, a strip costs only its width in seam, and packs as an
island of its own in the gaps the others leave.

:func:`spike_cuts` finds the protrusions as what a morphological *opening* of the
island's UV footprint removes: the footprint rasterised, eroded by a disk of radius ``r``
and dilated back; anything narrower than ``2 r`` vanishes. ``r`` is a fraction
(:data:`RADIUS_FRACTIONS`) of the footprint's largest inscribed radius, so the rule is
the same at any scale and any mesh resolution: a protrusion is thin *relative to the
island's own body*. Each connected removed piece that reaches farther than ``r`` from
the opened body (an opening also rounds every corner off, to a depth of ``(sqrt 2 - 1)
r``: a square's four corners are not protrusions) and holds :data:`MIN_SHARE` to
:data:`MAX_SHARE` of the island's area is a candidate; its cut is the shortest between
its far end and the body (a minimum cut through the faces near the neck, then its ears
moved: :func:`texture.ears.smooth_cut`). The island's UVs are kept, so flips, overlap and
distortion do not change; whether a candidate is made is the packing search's call
(:mod:`texture.unwrap_layout`), like every halving's.
"""
from __future__ import annotations

import numpy as np
from scipy import ndimage

from mnacore.triangles import triangle_areas

from .borders import min_cut_labels
from .ears import smooth_cut
from .halving import BAND_MAX_FACES, ZIGZAG, _one_piece, _pieces, _sub_island
from .raster import face_id_image, uv_to_pixel
from .unwrap_islands import Island

#: texels along the longer side of an island's footprint: the smallest opening (``r`` of 0.22
#: of the largest inscribed radius) is 14 texels wide on a footprint whose body is a third
#: of its length wide, and openings under 2 texels are not made; the raster costs one pass
#: over the faces
RASTER = 192
#: opening radii, as fractions of the footprint's largest inscribed radius: from
#: protrusions about as wide as the body's own half down to a fifth of that
RADIUS_FRACTIONS = (0.5, 0.33, 0.22)
#: the shares of the island's 3D area a protrusion may hold: a smaller one barely changes
#: the footprint, a larger one is half the island (the halvings' cuts)
MIN_SHARE, MAX_SHARE = 0.01, 0.45


def _footprint(isl: Island) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(face (RASTER, RASTER) covering each texel (-1: none), mask of the texels the island
    covers, each face's centroid texel (row, col), UV length of a texel)."""
    lo = isl.uv.min(0)
    ext = max(float(np.ptp(isl.uv, axis=0).max()), 1e-300)
    # texel centres at k + 0.5 of RASTER: the footprint spans texels 0 .. RASTER - 1
    t = ((isl.uv - lo) / ext * (RASTER - 1) + 0.5) / RASTER
    face, _ = face_id_image(t[isl.faces], RASTER, RASTER)
    mask = face >= 0
    mask |= ndimage.binary_closing(mask)  # faces thinner than a texel leave holes in a strip
    col, row = np.clip(np.rint(uv_to_pixel(t[isl.faces].mean(1), RASTER, RASTER)), 0, RASTER - 1).astype(np.int64).T
    return face, mask, np.stack([row, col]), ext / (RASTER - 1)


def spike_cuts(isl: Island, adj) -> list[tuple[list[Island], float, dict]]:
    """Each protrusion of ``isl`` cut off (see module docstring): ``([body, protrusion], 3D
    length of the cut, {"radius_fraction", "share"})``, distinct cuts only. ``adj``: the
    island's face adjacency (:func:`texture.regions.face_adjacency`)."""
    if len(isl.faces) < 8:
        return []
    face, mask, (row, col), texel = _footprint(isl)
    inside = ndimage.distance_transform_edt(mask)
    area = triangle_areas(isl.xyz, isl.faces)
    total = float(area.sum())
    out, made = [], []
    for frac in RADIUS_FRACTIONS:
        r = frac * float(inside.max())
        if r < 2.0:  # an opening by a disk of a texel or two is the raster's noise
            continue
        body = (ndimage.distance_transform_edt(inside < r) <= r) & mask  # the opening
        to_body = ndimage.distance_transform_edt(~body)[row, col]
        in_body = body[row, col]
        count, piece = _pieces(adj, ~in_body)
        outside = np.flatnonzero(~in_body)
        shares = np.bincount(piece, weights=area[outside], minlength=count) / total
        for p in np.flatnonzero((shares >= MIN_SHARE) & (shares <= MAX_SHARE)):
            sel = np.zeros(len(area), bool)
            sel[outside[piece == p]] = True
            # the body's faces within r of the protrusion: room for the cut on the body's side
            near = ndimage.distance_transform_edt(~np.isin(face, np.flatnonzero(sel)))[row, col] <= r
            lo = _neck_cut(isl, adj, sel, to_body, in_body & near, r)
            if lo is None or any(np.array_equal(lo, m) for m in made):
                continue
            share = float(area[lo].sum() / total)
            if not MIN_SHARE <= share <= MAX_SHARE:  # the neck's cut ran out to a tip, or into the body
                continue
            cut = float(adj.length[lo[adj.a] != lo[adj.b]].sum())
            # no line of the mesh runs across the neck (a cut much longer than the opening's width)
            if cut > ZIGZAG * 2.0 * r * texel:
                continue
            made.append(lo)
            out.append(([_sub_island(isl, np.flatnonzero(~lo)), _sub_island(isl, np.flatnonzero(lo))], cut,
                        {"radius_fraction": frac, "share": share}))
    return out


def _neck_cut(isl: Island, adj, sel: np.ndarray, to_body: np.ndarray, near_body: np.ndarray,
              r: float) -> np.ndarray | None:
    """The faces cut off with the protrusion ``sel``: the shortest cut (a minimum cut) between
    its faces farther than ``r`` texels from the opened body (``to_body``: each face's
    distance) and the body's faces, through the protrusion's nearer faces and ``near_body``
    (the body's faces within ``r`` of it), its ears then moved; the plain border of ``sel``
    where the minimum cut leaves a side in pieces or would run over more than
    :data:`texture.halving.BAND_MAX_FACES` faces. None where a side is not one piece, or
    where nothing of ``sel`` lies farther than ``r`` from the body (a stub)."""
    far = sel & (to_body > r)
    if not far.any():  # a stub, not a protrusion: an opening rounds every corner off by 0.41 r
        return None
    free = (sel & ~far) | near_body
    if 0 < free.sum() <= BAND_MAX_FACES:
        got = min_cut_labels(far.astype(np.int64), free, adj, 0, 1) == 1
        if _one_piece(adj, got) and _one_piece(adj, ~got):
            return smooth_cut(isl, got)[0]
    if not (_one_piece(adj, sel) and _one_piece(adj, ~sel)):
        return None
    return smooth_cut(isl, sel)[0]

