"""The weighted similarity fit that recovers how xatlas placed an island (rotation, and a
reflection only where xatlas really mirrored), so the packer can re-place the island exactly."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: a reflection is chosen only when it fits this much better than the best rotation.
REFLECTION_GAIN = 0.5


@dataclass
class Similarity:
    """``dst ~ scale * src @ rotation.T + translation``; ``rotation`` orthogonal, det +-1."""

    scale: float
    rotation: np.ndarray
    translation: np.ndarray


def similarity_fit(src: np.ndarray, dst: np.ndarray, weights: np.ndarray | None = None) -> Similarity:
    """Weighted least-squares similarity ``src (P,2) -> dst (P,2)`` (Umeyama 1991, eq. 40-42).

    With centred points ``x = src - mu_s``, ``y = dst - mu_d`` and ``H = sum w x y^T = U S V^T``:
    ``R = V diag(1, d) U^T``, ``s = tr(diag(1, d) S) / sum w |x|^2``. ``d = 1`` is the
    unconstrained optimum; when that ``R`` is a reflection (det -1) it is kept only if its
    residual is under ``REFLECTION_GAIN`` times that of the best rotation (``d = -1``), i.e.
    only when the target really is mirrored. Zero total weight or zero spread
    (a degenerate island) gives the identity rotation, scale 1, centroid-to-centroid.
    """
    src, dst = np.asarray(src, np.float64), np.asarray(dst, np.float64)
    w = np.ones(len(src)) if weights is None else np.asarray(weights, np.float64)
    if len(src) == 0 or w.sum() <= 0:
        return Similarity(1.0, np.eye(2), np.zeros(2) if len(src) == 0 else dst.mean(0) - src.mean(0))
    w = w / w.sum()
    mu_s, mu_d = w @ src, w @ dst
    x, y = src - mu_s, dst - mu_d
    var = float(w @ (x * x).sum(1))
    if var <= 1e-30:
        return Similarity(1.0, np.eye(2), mu_d - mu_s)
    U, S, Vt = np.linalg.svd((x * w[:, None]).T @ y)

    def fit(d):
        D = np.diag([1.0, d])
        R = Vt.T @ D @ U.T
        s = float(S @ np.diag(D)) / var
        return float(w @ ((s * x @ R.T - y) ** 2).sum(1)), s, R

    err, s, R = fit(1.0)  # the unconstrained optimum R = V U^T
    if np.linalg.det(R) < 0:  # it is a reflection: keep it only if it clearly beats the best rotation
        err_rot, s_rot, R_rot = fit(-1.0)
        if not err < REFLECTION_GAIN * err_rot:
            s, R = s_rot, R_rot
    return Similarity(s, R, mu_d - s * mu_s @ R.T)


@dataclass
class Rotations:
    """:func:`similarity_fit`'s rotation of many point sets at once, with the weighted means
    it fits about: ``dst ~ s (src - mean_src) @ rotation[k].T + mean_dst`` for set ``k``."""

    rotation: np.ndarray
    """(K, 2, 2), the identity for a set of zero total weight or zero spread"""
    mean_src: np.ndarray
    """(K, 2)"""
    mean_dst: np.ndarray
    """(K, 2)"""
    weight: np.ndarray
    """(K,) total weight of each set"""


def similarity_rotations(src: np.ndarray, dst: np.ndarray, weights: np.ndarray, group: np.ndarray,
                         n: int) -> Rotations:
    """The rotation (or reflection) :func:`similarity_fit` gives each of ``n`` point sets, the
    points ``src, dst (P, 2)`` with ``weights (P,)`` of set ``group (P,)`` (ids ``0..n-1``),
    all at once: the same sums and 2x2 SVDs, batched (a placement of 1,500 islands fitted them
    one by one in 0.3 s, a quarter of the packing's time)."""
    src, dst = np.asarray(src, np.float64), np.asarray(dst, np.float64)
    w, group = np.asarray(weights, np.float64), np.asarray(group, np.int64)

    def sums(values: np.ndarray) -> np.ndarray:
        return np.bincount(group, weights=values, minlength=n)

    total = sums(w)
    safe = np.where(total > 0, total, 1.0)
    wn = w / safe[group]
    mu_s = np.stack([sums(wn * src[:, 0]), sums(wn * src[:, 1])], 1)
    mu_d = np.stack([sums(wn * dst[:, 0]), sums(wn * dst[:, 1])], 1)
    x, y = src - mu_s[group], dst - mu_d[group]
    var = sums(wn * (x * x).sum(1))
    H = np.stack([np.stack([sums(wn * x[:, i] * y[:, j]) for j in range(2)], 1) for i in range(2)], 1)
    U, S, Vt = np.linalg.svd(H)
    V, Ut = np.swapaxes(Vt, 1, 2), np.swapaxes(U, 1, 2)
    safe_var = np.where(var > 1e-30, var, 1.0)

    def fit(d: float) -> tuple[np.ndarray, np.ndarray]:
        R = V @ (np.array([1.0, d])[:, None] * Ut)
        s = (S[:, 0] + d * S[:, 1]) / safe_var
        r = s[group, None] * np.einsum("pij,pj->pi", R[group], x) - y
        return sums(wn * (r * r).sum(1)), R

    err, R = fit(1.0)
    reflected = np.linalg.det(R) < 0
    if reflected.any():  # a reflection is kept only where it clearly beats the best rotation
        err_rot, R_rot = fit(-1.0)
        back = reflected & ~(err < REFLECTION_GAIN * err_rot)
        R[back] = R_rot[back]
    R[(total <= 0) | (var <= 1e-30)] = np.eye(2)
    return Rotations(R, mu_s, mu_d, total)
