"""Nearest neighbours through real libraries: scipy's cKDTree on the CPU, chunked cdist on CUDA."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import torch
from scipy.spatial import cKDTree

from mna.model import flush_denormals

#: query rows per torch.cdist chunk on CUDA (bounds memory at chunk x reference).
CDIST_CHUNK = 4096


class Nearest(NamedTuple):
    """``dist2 (Q,)`` squared distance to, and ``index (Q,)`` of, each query's nearest reference."""

    dist2: torch.Tensor
    index: torch.Tensor


def nearest(query: torch.Tensor, reference: torch.Tensor, workers: int = -1) -> Nearest:
    """Nearest ``reference (R, 3)`` point of every ``query (Q, 3)`` point (no gradient)."""
    if query.device.type == "cpu":
        with flush_denormals(False):  # scipy runs in the CPU's normal mode
            tree = cKDTree(reference.detach().double().numpy())
            d, i = tree.query(query.detach().double().numpy(), k=1, workers=workers)
        return Nearest(torch.from_numpy(d**2).to(query.dtype), torch.from_numpy(i.astype(np.int64)))
    dists, idxs = [], []
    for chunk in query.detach().split(CDIST_CHUNK):
        d = torch.cdist(chunk, reference.detach())
        m, j = d.min(dim=1)
        dists.append(m**2)
        idxs.append(j)
    return Nearest(torch.cat(dists), torch.cat(idxs))

