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

Measured on seven hard shapes (benchmarks/RESULTS.md, fit_quality_hard): -1.0 to +1.7 F
points and more distortion, so no preset draws hard targets; the :class:`ErrorMap` also
serves chart growth (:mod:`mna.grow`).
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


class ErrorMap:
    """Running distance from the surface to the charts, per cell of a grid over the surface.

    Fed every step with the targets' distances to their nearest chart sample; read by the
    hard-target draw (where to pull harder) and by chart growth (:mod:`mna.grow`: where the
    charts leave a gap)."""

    def __init__(self, surface: Surface, cells: int):
        self.surface = surface
        self.cell_of = cell_labels(surface.element_centers, cells)
        n = int(self.cell_of.max()) + 1
        weight = surface.face_areas if surface.is_mesh else np.ones(surface.element_count)
        mass = np.bincount(self.cell_of, weights=weight, minlength=n)
        self.area = mass / mass.sum()
        """each cell's share of the surface (mesh area, or point count for a cloud), summing to 1."""
        self.center = np.stack([np.bincount(self.cell_of, weights=weight * c, minlength=n)
                                for c in surface.element_centers.T], 1) / np.maximum(mass, 1e-300)[:, None]
        """(cells, 3) area-weighted centre of each cell (unit-ball frame)."""
        self.error = np.zeros(n)
        """running mean distance (unit ball) from a cell's targets to their nearest chart sample."""
        self.seen = np.zeros(n, dtype=bool)

    def record(self, elements: np.ndarray, distance: np.ndarray) -> None:
        """Update the cells of ``elements`` with their targets' ``distance`` to the charts."""
        n = len(self.error)
        cells = self.cell_of[elements]
        total = np.bincount(cells, weights=distance, minlength=n)
        hits = np.bincount(cells, minlength=n)
        hit = hits > 0
        mean = total[hit] / hits[hit]
        old = self.error[hit]
        self.error[hit] = np.where(self.seen[hit], (1 - EMA) * old + EMA * mean, mean)
        self.seen |= hit

    def filled(self) -> np.ndarray:
        """The errors, cells never observed counting as the mean observed error (none starved)."""
        if not self.seen.any():
            return np.zeros_like(self.error)
        return np.where(self.seen, self.error, self.error[self.seen].mean())

    def state_dict(self) -> dict:
        # tensors, so a checkpoint stays loadable with torch.load(weights_only=True)
        return {"error": torch.from_numpy(self.error.copy()), "seen": torch.from_numpy(self.seen.copy())}

    def load_state_dict(self, state: dict) -> None:
        self.error = state["error"].numpy().astype(np.float64)
        self.seen = state["seen"].numpy().astype(bool)


class HardTargets:
    """Draws ``count`` extra targets per step in proportion to each cell's running error."""

    def __init__(self, errors: ErrorMap, count: int):
        self.errors, self.count = errors, count

    def draw(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
        """Points, normals and elements of the extra targets; area-uniform until an error is known."""
        surface = self.errors.surface
        weight = self.errors.filled()[self.errors.cell_of]
        if not weight.sum() > 0:
            return surface.sample_elements(self.count, rng)
        return surface.sample_elements(self.count, rng, weight=weight)
