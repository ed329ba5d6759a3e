"""The chart grid: UV coordinates of a ``G x G`` vertex grid over ``[-1, 1]^2`` and its triangles.

One layout for the fit's extraction (``charts.npz``), the texture stage and the tests
(docs/run_folder.md). Vertex ``(i, j)`` (row ``i``, column ``j``) is ``i * G + j`` and sits at
``uv = (u_j, v_i)`` with ``u_j = -1 + 2 j / (G - 1)``: ``u`` along columns (right), ``v``
along rows (up).
"""
from __future__ import annotations

import numpy as np


def grid_uv(resolution: int) -> np.ndarray:
    """``(G, G, 2)`` grid: ``uv[i, j] = (u_j, v_i)``, ``u_j = -1 + 2 j / (G - 1)``.

    Example: ``grid_uv(3)[0, 2] == (1, -1)`` and ``grid_uv(3)[2, 0] == (-1, 1)``.
    """
    t = np.linspace(-1.0, 1.0, int(resolution))
    v, u = np.meshgrid(t, t, indexing="ij")
    return np.stack([u, v], -1)


def grid_faces(resolution: int) -> np.ndarray:
    """``(2 (G-1)^2, 3)`` triangles of a ``G x G`` vertex grid, counter-clockwise in UV.

    Cell ``(i, j)`` gives ``(i,j) (i,j+1) (i+1,j+1)`` and ``(i,j) (i+1,j+1) (i+1,j)``, in
    that order, cell after cell (row-major): faces ``2 c`` and ``2 c + 1`` are cell ``c``.
    """
    G = int(resolution)
    i, j = np.meshgrid(np.arange(G - 1), np.arange(G - 1), indexing="ij")
    a = (i * G + j).ravel()
    b, c, d = a + 1, a + G + 1, a + G
    return np.stack([np.stack([a, b, c], 1), np.stack([a, c, d], 1)], 1).reshape(-1, 3)
