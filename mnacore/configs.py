"""One strict loader for config dataclasses: a mapping (YAML, JSON) -> a (nested) dataclass.

Unknown keys and wrong types raise :class:`ConfigError` (an ``MnaError``) naming the key
(``config.loss.w_orient``); keys left out keep the dataclass's defaults. Types follow the
defaults: a bool field takes only true/false, an int field only integers, a float field
numbers (and strings such as ``1e-3``, which YAML 1.1 reads as strings), a nested
dataclass a mapping, a ``list[T]`` field a list of T (a ``list[str]`` also a
comma-separated string). Fields annotated as tuples or dicts take lists and mappings, item by
item (``tuple[float, float, float]``: a list of three numbers; ``tuple[LightSpec, ...]``: a
list of mappings; ``dict[str, ViewSpec]``: a mapping of mappings). Ranges are each
config's own ``validate()``.
"""
from __future__ import annotations

import dataclasses
import types
import typing
from dataclasses import fields
from typing import Any

from .errors import MnaError

_WORDS = {"float": "a number", "int": "an integer", "str": "a string"}


class ConfigError(MnaError):
    """A mapping that does not fit its config dataclass.

    ``str(error)`` is the message (``config.lr must be float, got 'fast'``); ``key`` is the
    dotted path of the offending key (``lights[0].brightness``) and ``problem`` what is wrong
    with it (``expected a number, got 'fast'``), for callers that word their errors
    differently (scene presets).
    """

    def __init__(self, message: str, key: str, problem: str):
        super().__init__(message)
        self.key, self.problem = key, problem


def _join(where: str, name: str) -> str:
    return f"{where}.{name}" if where else name


def from_dict(data: dict, cls: type, where: str = "config") -> Any:
    """Build a (nested) dataclass from a dict, rejecting unknown keys and wrong types."""
    if not isinstance(data, dict):
        got = type(data).__name__
        raise ConfigError(f"{where} must be a mapping, got {got}", where, f"expected a mapping, got {got}")
    known = [f.name for f in fields(cls)]
    unknown = sorted(set(data) - set(known))
    if unknown:
        raise ConfigError(f"unknown key(s) in {where}: {', '.join(unknown)}", _join(where, unknown[0]),
                          f"unknown key; allowed: {', '.join(known)}")
    kwargs = {}
    defaults = cls()
    hints = typing.get_type_hints(cls)
    for name, value in data.items():
        default = getattr(defaults, name)
        key = _join(where, name)
        if dataclasses.is_dataclass(default):
            kwargs[name] = from_dict(value, type(default), key)
        elif isinstance(default, list):
            kwargs[name] = _coerce_list(value, hints[name], key)
        elif isinstance(value, (list, tuple, dict)) and _container_hint(hints[name]) is not None:
            kwargs[name] = _container(value, _container_hint(hints[name]), key)
        else:
            kwargs[name] = _coerce(value, default, key)
    return cls(**kwargs)


def _coerce_list(value: Any, hint: Any, where: str) -> list:
    (item,) = typing.get_args(hint)  # a list field must say its item type: list[int], list[str]
    if item is str and isinstance(value, str):
        value = [v.strip() for v in value.split(",") if v.strip()]
    if not isinstance(value, list) or not all(isinstance(v, item) and not isinstance(v, bool) for v in value):
        raise ConfigError(f"{where} must be a list of {item.__name__}, got {value!r}", where,
                          f"expected a list of {item.__name__}, got {value!r}")
    return list(value)


def _container_hint(hint: Any):
    """``hint`` when it is a tuple or dict type (``X | None`` unwrapped), else None."""
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        hint = args[0] if len(args) == 1 else None
    return hint if typing.get_origin(hint) in (tuple, dict) else None


def _item(value: Any, hint: Any, where: str) -> Any:
    """One item of a container field, by its annotation."""
    if dataclasses.is_dataclass(hint):
        return from_dict(value, hint, where)
    if typing.get_origin(hint) in (tuple, dict):
        return _container(value, hint, where)
    return _coerce(value, hint(), where)


def _container(value: Any, hint: Any, where: str) -> Any:
    args = typing.get_args(hint)
    if typing.get_origin(hint) is dict:
        if not isinstance(value, dict):
            raise ConfigError(f"{where} must be a mapping, got {value!r}", where, f"expected a mapping, got {value!r}")
        return {str(k): _item(v, args[1], _join(where, str(k))) for k, v in value.items()}
    variadic = len(args) == 2 and args[1] is Ellipsis
    if not isinstance(value, (list, tuple)) or (not variadic and len(value) != len(args)):
        what = "a list" if variadic else f"a list of {len(args)} items"
        raise ConfigError(f"{where} must be {what}, got {value!r}", where, f"expected {what}, got {value!r}")
    kinds = [args[0]] * len(value) if variadic else args
    return tuple(_item(v, k, f"{where}[{i}]") for i, (v, k) in enumerate(zip(value, kinds)))


def _wrong(where: str, expected: str, value: Any) -> ConfigError:
    words = "true or false" if expected == "true or false" else _WORDS.get(expected, expected)
    return ConfigError(f"{where} must be {expected}, got {value!r}", where, f"expected {words}, got {value!r}")


def _coerce(value: Any, default: Any, where: str) -> Any:
    if default is None or value is None:
        if value is not None and not isinstance(value, (int, float, str)):
            raise ConfigError(f"{where} has the wrong type: {type(value).__name__}", where,
                              f"wrong type: {type(value).__name__}")
        return value
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise _wrong(where, "true or false", value)
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
    raise _wrong(where, type(default).__name__, value)
