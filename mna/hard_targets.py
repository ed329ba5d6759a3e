"""Hard-example targets: each step, extra target points drawn where the fit errs most (issue 18).

L_rec is a unidirectional Chamfer from targets to the charts, so a part of the surface that
no chart reaches is pulled on only by the few targets that happen to land there. Where a
fit stalls (the handles of a high-genus shape, small parts of an assembly), those parts
have the largest error; drawing *extra* targets there in proportion to that error pulls on
them harder, without changing the uniform draw.

Why extra and not a share of the usual targets: the occupancy nets learn from PU labels
(a chart sample is positive when it is some target's nearest), and PU learning assumes the
labelled positives are a uniform sample of the surface. Only the uniform targets label
positives (:func:`mna.objective.atlas_losses`, ``labelled``); the hard ones only enter
L_rec (and L_dist, L_orient through the positives they pull on).

The error is remembered per **cell** of a 3D grid over the surface, not per face: a step's
targets land on a face of a fine mesh only every few dozen steps, while cells are sized so
that one uniform draw puts about one target in each (about ``targets`` occupied cells),
so every cell's error is refreshed every step or two, whatever the mesh's resolution.
"""
from __future__ import annotations

import numpy as np
import torch

from mna.data import Surface

#: weight of a step's observation in a cell's running error (an exponential moving
#: average): about the last two observations count, so a region that the charts have
#: just reached stops drawing extra targets within a few steps.
EMA = 0.5
#: refinements of the cell size towards the wanted number of occupied cells.
SIZE_ROUNDS = 4


def cell_labels(centers: np.ndarray, wanted: int) -> np.ndarray:
    """Cell index of every element centre on a grid sized for about ``wanted`` occupied cells.

    On a surface the number of occupied cells grows as ``1 / size^2``, so the size is
    rescaled by ``sqrt(occupied / wanted)`` a few times from a start that suits the unit ball.
    """
    size = 2.0 / np.sqrt(max(wanted, 1))
    labels = np.zeros(len(centers), dtype=np.int64)
    for _ in range(SIZE_ROUNDS):
        keys = np.floor(centers / size).astype(np.int64)
        _, labels = np.unique(keys, axis=0, return_inverse=True)
        occupied = int(labels.max()) + 1
        size *= np.sqrt(occupied / max(wanted, 1))
    return labels.reshape(-1)


class HardTargets:
    """Draws ``count`` extra targets per step in proportion to each cell's running error."""

    def __init__(self, surface: Surface, count: int, cells: int):
        self.surface, self.count = surface, count
        self.cell_of = cell_labels(surface.element_centers, cells)
        self.error = np.zeros(int(self.cell_of.max()) + 1)
        """running mean distance (unit ball) from a cell's targets to their nearest chart sample."""
        self.seen = np.zeros(len(self.error), dtype=bool)

    def draw(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
        """Points, normals and elements of the extra targets; area-uniform until an error is known."""
        if not self.seen.any():
            return self.surface.sample_elements(self.count, rng)
        # cells never observed yet count as the mean observed error: no region is starved
        err = np.where(self.seen, self.error, self.error[self.seen].mean())
        weight = err[self.cell_of]
        if not weight.sum() > 0:
            return self.surface.sample_elements(self.count, rng)
        return self.surface.sample_elements(self.count, rng, weight=weight)

    def record(self, elements: np.ndarray, distance: np.ndarray) -> None:
        """Update the cells of ``elements`` with their targets' ``distance`` to the charts."""
        cells = self.cell_of[elements]
        total = np.bincount(cells, weights=distance, minlength=len(self.error))
        hits = np.bincount(cells, minlength=len(self.error))
        hit = hits > 0
        mean = total[hit] / hits[hit]
        old = self.error[hit]
        self.error[hit] = np.where(self.seen[hit], (1 - EMA) * old + EMA * mean, mean)
        self.seen |= hit

    def state_dict(self) -> dict:
        # tensors, so a checkpoint stays loadable with torch.load(weights_only=True)
        return {"error": torch.from_numpy(self.error.copy()), "seen": torch.from_numpy(self.seen.copy())}

    def load_state_dict(self, state: dict) -> None:
        self.error = state["error"].numpy().astype(np.float64)
        self.seen = state["seen"].numpy().astype(bool)
