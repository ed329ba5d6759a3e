"""Checkpoint files (``checkpoint.pt``): plain data only, never code.

A checkpoint holds tensors, numbers, strings, ``None`` and lists/tuples/dicts of them (the
optimiser's, scheduler's and RNGs' states included: torch's RNG state is a uint8 tensor,
numpy's a dict of ints). It is read with ``torch.load(weights_only=True)``, which refuses
any other pickled object: checkpoints are shared between people, and unpickling an
arbitrary object runs code chosen by whoever wrote the file.
"""
from __future__ import annotations

import os
import pickle
from pathlib import Path
from typing import Any

import torch

from mna.atomic import atomic_path
from mna.errors import MnaError

_SCALARS = (bool, int, float, str, bytes, type(None), torch.Tensor, torch.dtype, torch.device)


def plain_data_problem(obj: Any, where: str = "state") -> str | None:
    """The path and type of the first value that is not plain data, or None if all are."""
    if isinstance(obj, _SCALARS):
        return None
    if isinstance(obj, dict):  # OrderedDict and Counter (MultiStepLR's milestones) are dicts too
        for key, value in obj.items():
            if not isinstance(key, (str, int)):
                return f"{where} has a key of type {type(key).__name__}"
            problem = plain_data_problem(value, f"{where}[{key!r}]")
            if problem:
                return problem
        return None
    if isinstance(obj, (list, tuple)):
        for i, value in enumerate(obj):
            problem = plain_data_problem(value, f"{where}[{i}]")
            if problem:
                return problem
        return None
    return f"{where} is a {type(obj).__module__}.{type(obj).__name__}"


def write_state(path: str | os.PathLike, state: dict) -> None:
    """Save ``state`` atomically; refuse anything ``read_state`` could not load back."""
    problem = plain_data_problem(state)
    assert problem is None, f"checkpoint state must be plain data: {problem}"  # a bug in the caller
    with atomic_path(path) as tmp:
        torch.save(state, tmp)


def read_state(path: str | os.PathLike, map_location: str | torch.device = "cpu") -> dict:
    """Load a checkpoint written by :func:`write_state` without running any code from it.

    Raises ``MnaError`` (one line naming the file) when the file holds other Python objects
    (e.g. a crafted pickle), is not a torch file, is truncated, or is not a dict.
    """
    path = Path(path)
    try:
        state = torch.load(path, map_location=map_location, weights_only=True)
    except pickle.UnpicklingError:
        raise MnaError(f"refusing to load {path}: it holds Python objects, not only tensors, numbers and "
                       f"strings (opening such a file can run code; only load checkpoints written by mna)") from None
    except FileNotFoundError:
        raise MnaError(f"checkpoint not found: {path}") from None
    except Exception as exc:  # torch raises many types on a file that is not a checkpoint
        raise MnaError(f"cannot read checkpoint {path}: not a torch checkpoint or truncated "
                       f"({type(exc).__name__})") from None
    if not isinstance(state, dict):
        raise MnaError(f"cannot read checkpoint {path}: expected a dict, got {type(state).__name__}")
    return state
