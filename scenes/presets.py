"""Scene presets as data: cameras, lights, ground, materials, heat-map colours.

A preset is a YAML or JSON file (``scenes/studio.yaml`` and ``scenes/plain.yaml`` ship
with the package; a user can pass their own path). It is parsed into the small frozen
dataclasses below, with every key checked: an unknown key, a wrong type or an
out-of-range value is an ``MnaError`` (a ``ValueError``) naming the file and the key path
(``lights[0].intensity``), never a silent default.

Lengths are in units of the mesh's bounding-sphere radius ``r`` (so one preset frames a
mouse and a house alike); angles are in degrees. Directions use azimuth/elevation in
the frame ``(right, up, front)`` built from the preset's ``up`` and ``front`` axes:
azimuth 0, elevation 0 looks at the mesh from ``front``; azimuth 90 from ``right``;
elevation 90 from above. Example: with ``up = +y`` and ``front = +z``, the ``side`` view
(azimuth 90) puts the camera on the ``+x`` axis.
"""
from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from mnacore.configs import ConfigError, from_dict
from mnacore.errors import MnaError

PRESET_DIR = Path(__file__).resolve().parent
BUILTIN_PRESETS = ("studio", "plain")
DEFAULT_PRESET = "studio"


@dataclass(frozen=True)
class ViewSpec:
    """A camera direction around the mesh."""

    azimuth: float = 0.0
    """degrees around ``up``, 0 = from ``front``, 90 = from ``right``."""
    elevation: float = 0.0
    """degrees above the horizontal plane, 90 = from straight above."""


@dataclass(frozen=True)
class CameraSpec:
    fov: float = 30.0
    """field of view in degrees along the smaller image axis."""
    margin: float = 1.08
    """the bounding sphere of radius ``r`` is framed as if its radius were ``margin * r``."""
    turntable_elevation: float = 20.0
    """elevation in degrees of the ``--turntable N`` views (azimuths ``360 k / N``)."""


@dataclass(frozen=True)
class LightSpec:
    """A square area light facing the mesh centre."""

    azimuth: float = 0.0
    elevation: float = 45.0
    distance: float = 4.0
    """from the mesh centre, in units of ``r``."""
    size: float = 1.5
    """side of the square, in units of ``r``."""
    intensity: float = 5.0
    """emitted radiance; irradiance at the centre is about ``intensity * size^2 / distance^2`` for any ``r``."""
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)


@dataclass(frozen=True)
class GroundSpec:
    enabled: bool = True
    offset: float = 0.0
    """gap between the mesh's lowest point and the plane, in units of ``r``."""
    size: float = 12.0
    """side of the square plane, in units of ``r``."""
    color: tuple[float, float, float] = (0.8, 0.8, 0.8)


@dataclass(frozen=True)
class MaterialSpec:
    checker_squares: float = 16.0
    """checker squares across the bounding sphere's diameter: the 3D square side is ``2 r / checker_squares``."""
    checker_colors: tuple[tuple[float, float, float], tuple[float, float, float]] = (
        (0.85, 0.85, 0.85), (0.12, 0.12, 0.12))
    """the two checker colours (sRGB, 0..1)."""
    base_color: tuple[float, float, float] = (0.7, 0.7, 0.7)
    """colour of an untextured mesh (``--texture none``)."""
    texture_size: int = 2048
    """side in pixels of generated checker / UV-grid textures."""


@dataclass(frozen=True)
class HeatmapSpec:
    cmap: str = "viridis"
    """matplotlib colour map for per-face distortion."""
    percentile: float = 95.0
    """the colour scale tops out at this percentile of all faces of all methods in one figure."""
    chart_cmap: str = "tab20"
    """categorical colour map for per-chart colours."""


@dataclass(frozen=True)
class Preset:
    """Everything about a scene except the mesh and the material kind."""

    name: str = "custom"
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    front: tuple[float, float, float] = (0.0, 0.0, 1.0)
    camera: CameraSpec = field(default_factory=CameraSpec)
    views: dict[str, ViewSpec] = field(default_factory=dict)
    lights: tuple[LightSpec, ...] = ()
    lights_follow_camera: bool = True
    """light azimuths are relative to each view's azimuth, so every view is lit alike."""
    environment: float = 0.15
    """radiance of the constant environment (0 = black)."""
    background: tuple[float, float, float] | None = (1.0, 1.0, 1.0)
    """PNG background behind the mesh (sRGB); ``null`` keeps the environment visible."""
    ground: GroundSpec = field(default_factory=GroundSpec)
    material: MaterialSpec = field(default_factory=MaterialSpec)
    heatmap: HeatmapSpec = field(default_factory=HeatmapSpec)
    max_depth: int = 6
    """path-tracer bounce limit."""


def _fail(source: str, key: str, msg: str):
    raise MnaError(f"preset {source}: {key}: {msg}")


def _number(source: str, key: str, value: Any, lo: float | None = None, hi: float | None = None) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        _fail(source, key, f"expected a number, got {value!r}")
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        _fail(source, key, f"{value!r} is outside [{lo}, {hi}]")
    return float(value)


def _colors(preset: Preset) -> list[tuple[str, tuple[float, float, float]]]:
    """(key, colour) of every colour in the preset."""
    out = [("ground.color", preset.ground.color), ("material.base_color", preset.material.base_color)]
    out += [(f"material.checker_colors[{i}]", c) for i, c in enumerate(preset.material.checker_colors)]
    out += [(f"lights[{i}].color", light.color) for i, light in enumerate(preset.lights)]
    return out + ([("background", preset.background)] if preset.background is not None else [])


def _check(preset: Preset, source: str) -> Preset:
    import numpy as np

    up, front = np.asarray(preset.up), np.asarray(preset.front)
    if np.linalg.norm(up) == 0 or np.linalg.norm(front) == 0:
        _fail(source, "up/front", "axes must be non-zero")
    cos = abs(up @ front) / (np.linalg.norm(up) * np.linalg.norm(front))
    if cos > 0.99:
        _fail(source, "up/front", "axes must not be parallel")
    cam = preset.camera
    _number(source, "camera.fov", cam.fov, 1.0, 170.0)
    _number(source, "camera.margin", cam.margin, 1.0, None)
    _number(source, "environment", preset.environment, 0.0, None)
    _number(source, "material.checker_squares", preset.material.checker_squares, 1.0, 4096.0)
    _number(source, "material.texture_size", preset.material.texture_size, 16, 16384)
    _number(source, "heatmap.percentile", preset.heatmap.percentile, 1.0, 100.0)
    _number(source, "max_depth", preset.max_depth, 1, None)
    for key, color in _colors(preset):
        for i, v in enumerate(color):
            _number(source, f"{key}[{i}]", v, 0.0, None)
    for i, light in enumerate(preset.lights):
        _number(source, f"lights[{i}].distance", light.distance, 1.0, None)
        _number(source, f"lights[{i}].size", light.size, 0.0, None)
        _number(source, f"lights[{i}].intensity", light.intensity, 0.0, None)
    if not preset.views:
        _fail(source, "views", "a preset needs at least one view")
    return preset


def preset_from_dict(data: dict, source: str = "<dict>") -> Preset:
    """Build (:func:`mnacore.configs.from_dict`) and validate a preset from plain data (the
    parsed YAML/JSON); errors name the file and the key path."""
    try:
        preset = from_dict(data, Preset, "")
    except ConfigError as exc:
        _fail(source, exc.key or "<root>", exc.problem)
    return _check(preset, source)


def load_preset(name_or_path: str | Path | Preset | None = None) -> Preset:
    """Load a built-in preset by name (``studio``, ``plain``) or a user's YAML/JSON file.

    A ``Preset`` instance is returned as it is (so code can pass a modified preset).
    """
    if isinstance(name_or_path, Preset):
        return name_or_path
    if name_or_path is None:
        name_or_path = DEFAULT_PRESET
    text_name = str(name_or_path)
    path = PRESET_DIR / f"{text_name}.yaml" if text_name in BUILTIN_PRESETS else Path(text_name)
    if not path.is_file():
        raise MnaError(f"preset {text_name!r} not found: give one of {', '.join(BUILTIN_PRESETS)} "
                         "or the path of a YAML/JSON preset file")
    text = path.read_text()
    try:
        data = json.loads(text) if path.suffix.lower() == ".json" else yaml.safe_load(text)
    except (json.JSONDecodeError, yaml.YAMLError) as exc:
        first = str(exc).strip().splitlines()[0]
        raise MnaError(f"preset {path}: cannot parse: {first}") from None
    data = {} if data is None else data
    data.setdefault("name", path.stem)
    return preset_from_dict(data, str(path))


def preset_to_dict(preset: Preset) -> dict:
    """Plain data of a preset (saved beside renders so they can be reproduced)."""
    return dataclasses.asdict(preset)
