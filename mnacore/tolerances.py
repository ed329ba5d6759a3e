"""Tolerances shared by every stage, each defined once, in the unit-ball frame (DESIGN).

The unit ball has diameter 2, so ``SURFACE_TOL = 0.02`` is 1 % of the shape's diameter:
the F-score threshold of the paper and of DESIGN, and the distance within which two
surfaces (a chart and the input, two charts, an island border and the input's boundary)
count as the same surface.
"""
from __future__ import annotations

#: 1 % of the unit ball's diameter: "on the surface" (F-score threshold, covering, boundary)
SURFACE_TOL = 0.02
#: two charts within this of each other near a point (0.5 % of the diameter) both reach it:
#: which of them takes it is decided by something other than distance (the unwrap's face
#: labels: depth in the domain; a fit's exclusive PU labels: the label value)
NEAR_TOL = SURFACE_TOL / 2
