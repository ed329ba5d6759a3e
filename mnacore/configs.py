"""One strict loader for config dataclasses: a mapping (YAML, JSON) -> a (nested) dataclass.

Unknown keys and wrong types raise ``MnaError`` naming the key (``config.loss.w_orient``);
keys left out keep the dataclass's defaults. Types follow the defaults: a bool field takes
only true/false, an int field only integers, a float field numbers (and strings such as
``1e-3``, which YAML 1.1 reads as strings), a nested dataclass a mapping, a ``list[T]``
field a list of T (a ``list[str]`` also a comma-separated string). Ranges are each
config's own ``validate()``.
"""
from __future__ import annotations

import dataclasses
import typing
from dataclasses import fields
from typing import Any

from .errors import MnaError


def from_dict(data: dict, cls: type, where: str = "config") -> Any:
    """Build a (nested) dataclass from a dict, rejecting unknown keys and wrong types."""
    if not isinstance(data, dict):
        raise MnaError(f"{where} must be a mapping, got {type(data).__name__}")
    known = {f.name: f for f in fields(cls)}
    unknown = sorted(set(data) - set(known))
    if unknown:
        raise MnaError(f"unknown key(s) in {where}: {', '.join(unknown)}")
    kwargs = {}
    defaults = cls()
    hints = typing.get_type_hints(cls)
    for name, value in data.items():
        default = getattr(defaults, name)
        if dataclasses.is_dataclass(default):
            kwargs[name] = from_dict(value, type(default), f"{where}.{name}")
        elif isinstance(default, list):
            kwargs[name] = _coerce_list(value, hints[name], f"{where}.{name}")
        else:
            kwargs[name] = _coerce(value, default, f"{where}.{name}")
    return cls(**kwargs)


def _coerce_list(value: Any, hint: Any, where: str) -> list:
    (item,) = typing.get_args(hint)  # a list field must say its item type: list[int], list[str]
    if item is str and isinstance(value, str):
        value = [v.strip() for v in value.split(",") if v.strip()]
    if not isinstance(value, list) or not all(isinstance(v, item) and not isinstance(v, bool) for v in value):
        raise MnaError(f"{where} must be a list of {item.__name__}, got {value!r}")
    return list(value)


def _coerce(value: Any, default: Any, where: str) -> Any:
    if default is None or value is None:
        if value is not None and not isinstance(value, (int, float, str)):
            raise MnaError(f"{where} has the wrong type: {type(value).__name__}")
        return value
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise MnaError(f"{where} must be true or false, got {value!r}")
        return value
    if isinstance(default, int) and not isinstance(value, bool) and isinstance(value, int):
        return value
    if isinstance(default, float) and not isinstance(value, bool) and isinstance(value, (int, float)):
        return float(value)
    if isinstance(default, float) and isinstance(value, str):
        # YAML 1.1 reads 1e-3 (no dot) as a string
        try:
            return float(value)
        except ValueError:
            pass
    if isinstance(default, str) and isinstance(value, str):
        return value
    raise MnaError(f"{where} must be {type(default).__name__}, got {value!r}")
