"""Chamfer distance and F-score between point sets, in the unit-ball frame (numpy + scipy).

Same definitions as DESIGN (and ``mna.metrics``, which is torch-side and so not
importable here): ``chamfer = mean |x -> Y|^2 + mean |y -> X|^2``; ``fscore`` = harmonic
mean of precision and recall at 0.02 (1 % of the unit ball's diameter), in percent.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.spatial import cKDTree

FSCORE_THRESHOLD = 0.02
POINTS = 25000


class PointMetrics(NamedTuple):
    chamfer: float
    fscore: float
    precision: float
    recall: float


def chamfer_fscore(pred: np.ndarray, ref: np.ndarray, threshold: float = FSCORE_THRESHOLD) -> PointMetrics:
    """Chamfer (squared, both ways) and F-score (percent) of ``pred (P, 3)`` against ``ref (R, 3)``."""
    if len(pred) == 0 or len(ref) == 0:
        return PointMetrics(float("inf"), 0.0, 0.0, 0.0)
    d_pr = cKDTree(ref).query(pred)[0]
    d_rp = cKDTree(pred).query(ref)[0]
    precision = 100.0 * float((d_pr < threshold).mean())
    recall = 100.0 * float((d_rp < threshold).mean())
    f = 0.0 if precision + recall == 0 else 2 * precision * recall / (precision + recall)
    return PointMetrics(float((d_pr ** 2).mean() + (d_rp ** 2).mean()), f, precision, recall)
