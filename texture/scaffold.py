"""SLIM that cannot overlap: libigl's SCAF (a scaffold mesh around the island).

Free SLIM (:func:`texture.relax.relax_island`) lowers the symmetric Dirichlet energy
without ever flipping a face, but nothing stops the island's border from running over
itself. Where the isometric optimum itself overlaps, it does: a border vertex whose 3D
faces span more than a full turn (a saddle of a marching-cubes surface on a chart border
or on a cut to a disk: 2.0-3.7 pi on a 45k-face one) cannot lie flat without its fan
lapping over, and the border around near-full-turn vertices folds into the notches next
to it. The guarded run (border vertices held near each crossing, the step retried) stalls
there when the very first iteration already crosses: from the start map every step
crosses somewhere (two 21k-face disks of that surface ended at energy excess 124 and 207,
faces squashed flat, where free SLIM reached 0.29 with 30 small crossings).

SCAF (Jiang, Schaefer and Panozzo, "Simplicial Complex Augmentation Framework for
Bijective Maps", 2017; ``igl.triangle.scaf_precompute`` /
``scaf_solve``) triangulates the plane around the island and minimises the island's
energy plus a scaffold energy that becomes infinite as a scaffold triangle collapses: the
border can come close to itself but never cross. On those two disks it reached 0.29 and
0.34 in 108 and 85 iterations (0.1 s each), injective after every one.

SCAF's scaffold mesher works in absolute units: an island of 3D area 0.13 gave NaN after
one iteration and the next call never returned. Every island is therefore solved at unit
3D area (the energy excess is scale-free) and no solve follows a non-finite one.
"""
from __future__ import annotations

import numpy as np

from mnacore.triangles import triangle_areas


def relax_scaffold(xyz: np.ndarray, uv: np.ndarray, faces: np.ndarray, iterations: int,
                   min_gain: float) -> tuple[np.ndarray, int, float] | None:
    """(UVs, iterations, energy excess) of SCAF from the injective (counter-clockwise:
    :func:`texture.relax.is_injective`) map ``uv`` (any scale: returned at its scale),
    stopping where an iteration lowers the excess by less than ``min_gain`` or raises it;
    None where the start is not injective or SCAF's result is not (it never was here: a
    check, not a path)."""
    import igl
    import igl.triangle as tri

    from .relax import energy_excess, is_injective

    faces = np.asarray(faces, np.int64)
    uv = np.asarray(uv, np.float64)
    area3 = float(triangle_areas(xyz, faces).sum())
    if iterations <= 0 or len(faces) < 2 or area3 <= 0 or not is_injective(uv, faces):
        return None
    # unit 3D area, the UVs at that scale too (an injective start is counter-clockwise, as
    # SCAF's rotations need)
    s = 1.0 / np.sqrt(area3)
    x = np.asfortranarray(xyz * s, np.float64)
    start = uv * s
    data = tri.SCAFData()
    tri.scaf_precompute(x, np.asfortranarray(faces, np.int32), np.asfortranarray(start),
                        igl.SYMMETRIC_DIRICHLET, np.zeros(0, np.int32), np.zeros((0, 2), order="F"), 0.0, data)
    current, excess, done = start, energy_excess(x, start, faces), 0
    n = len(x)
    while done < iterations:
        nxt = np.array(tri.scaf_solve(1, data))[:n, :2]  # the scaffold's vertices follow the island's
        new = energy_excess(x, nxt, faces) if np.isfinite(nxt).all() else np.inf
        if not new < excess:
            break
        gain = excess - new
        current, excess, done = nxt, new, done + 1
        if gain < min_gain:
            break
    out = current / s
    if not is_injective(out, faces):
        return None
    return out, done, float(excess)
