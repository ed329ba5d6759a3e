"""Mitsuba 3 scenes as plain dicts, their Mitsuba XML, and rendering them.

``scene_dict`` builds a plain-data scene in Mitsuba's dict format, except that
transforms are numpy ``(4, 4)`` / ``(3, 3)`` arrays and file names are relative to a
scene folder. ``to_mitsuba`` turns it into what ``mi.load_dict`` takes (current
variant); ``scene_xml`` into a Mitsuba scene file that ``mitsuba scene.xml`` (or
``mi.load_file``) renders to the same image, because both load the same PLY and
texture files from the scene folder.

Scale: all lengths come from the mesh's bounding sphere ``(c, r)`` and the preset
(see ``scenes.presets``), so a scene looks the same for any mesh size.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any
from xml.sax.saxutils import quoteattr

import numpy as np

from render.images import srgb_to_linear
from scenes.cameras import BoundingSphere, Camera, direction, world_frame
from scenes.presets import Preset

#: XML tag of each plugin type we emit
PLUGIN_TAGS = {
    "path": "integrator", "direct": "integrator", "perspective": "sensor", "independent": "sampler",
    "hdrfilm": "film", "gaussian": "rfilter", "box": "rfilter", "diffuse": "bsdf", "twosided": "bsdf",
    "bitmap": "texture", "checkerboard": "texture", "mesh_attribute": "texture", "ply": "shape",
    "obj": "shape", "rectangle": "shape", "area": "emitter", "constant": "emitter",
}


def rgb(value) -> dict:
    """Mitsuba RGB spectrum dict (linear values)."""
    return {"type": "rgb", "value": [float(x) for x in np.broadcast_to(np.asarray(value, float), 3)]}


def look_at(origin, target, up) -> np.ndarray:
    """Mitsuba ``look_at`` matrix: columns ``left, up', forward, origin`` (local +z -> target)."""
    return Camera("", np.asarray(origin, float), np.asarray(target, float), np.asarray(up, float),
                  1.0, 1, 1).to_world()


def material_bitmap(filename: str) -> dict:
    """Diffuse BSDF whose albedo is an image file (8-bit sRGB decoded by Mitsuba), an atlas:
    clamped at its edge as the exported GLB declares (:data:`texture.export.ATLAS_SAMPLER`),
    so an island at the atlas border never takes colour from the opposite border."""
    return {"type": "diffuse", "reflectance": {"type": "bitmap", "filename": filename,
                                                "filter_type": "bilinear", "wrap_mode": "clamp"}}


def material_procedural_checker(frequency: float, colors) -> dict:
    """Diffuse BSDF with Mitsuba's checkerboard at ``frequency`` squares per UV unit.

    Mitsuba's checkerboard has period 1 in UV (2 squares), hence the ``frequency / 2`` scale.
    """
    to_uv = np.diag([frequency / 2, frequency / 2, 1.0])
    return {"type": "diffuse", "reflectance": {
        "type": "checkerboard", "color0": rgb(srgb_to_linear(colors[0])),
        "color1": rgb(srgb_to_linear(colors[1])), "to_uv": to_uv}}


def material_vertex_colors() -> dict:
    """Diffuse BSDF coloured by the mesh's ``vertex_color`` attribute (linear RGB)."""
    return {"type": "diffuse", "reflectance": {"type": "mesh_attribute", "name": "vertex_color"}}


def material_plain(color_srgb) -> dict:
    return {"type": "diffuse", "reflectance": rgb(srgb_to_linear(color_srgb))}


def _area_light(light, camera_azimuth: float, sphere: BoundingSphere, preset: Preset) -> dict:
    az = light.azimuth + (camera_azimuth if preset.lights_follow_camera else 0.0)
    d = direction(az, light.elevation, preset.up, preset.front)
    _, up, front = world_frame(preset.up, preset.front)
    pos = sphere.center + light.distance * sphere.radius * d
    lup = front if abs(d @ up) > 0.999 else up
    half = light.size * sphere.radius / 2
    to_world = look_at(pos, sphere.center, lup) @ np.diag([half, half, 1.0, 1.0])
    return {"type": "rectangle", "to_world": to_world,
            "emitter": {"type": "area", "radiance": rgb(np.asarray(light.color) * light.intensity)}}


def _ground(sphere: BoundingSphere, lowest: float, preset: Preset) -> dict:
    """Square diffuse plane under the mesh, normal = up, at ``lowest`` - offset (along up)."""
    _, up, front = world_frame(preset.up, preset.front)
    right = np.cross(up, front)
    half = preset.ground.size * sphere.radius / 2
    centre = sphere.center + ((lowest - sphere.center @ up) - preset.ground.offset * sphere.radius) * up
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = front * half, right * half, up, centre
    return {"type": "rectangle", "to_world": m, "bsdf": material_plain(preset.ground.color)}


def camera_azimuth(camera: Camera, preset: Preset) -> float:
    """Azimuth (degrees) of ``camera`` about the mesh centre, in the preset's frame."""
    right, _, front = world_frame(preset.up, preset.front)
    d = camera.origin - camera.target
    return math.degrees(math.atan2(d @ right, d @ front))


def sensor(camera: Camera, spp: int) -> dict:
    dist = float(np.linalg.norm(camera.origin - camera.target))
    return {"type": "perspective", "fov": float(camera.fov), "fov_axis": "smaller",
            "near_clip": 0.01 * dist, "far_clip": 100.0 * dist, "to_world": camera.to_world(),
            "sampler": {"type": "independent", "sample_count": int(spp)},
            "film": {"type": "hdrfilm", "width": int(camera.width), "height": int(camera.height),
                     "pixel_format": "rgba", "rfilter": {"type": "gaussian"}}}


def scene_dict(mesh_file: str, material: dict, camera: Camera, sphere: BoundingSphere, lowest: float,
               preset: Preset, spp: int) -> dict:
    """The whole scene: mesh (PLY in the scene folder), lights, environment, ground, sensor.

    ``lowest``: the mesh's smallest coordinate along the preset's up axis (ground height).
    """
    scene: dict[str, Any] = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": int(preset.max_depth),
                       "hide_emitters": preset.background is not None},
        "sensor": sensor(camera, spp),
        # two-sided: open surfaces and neural reconstructions show their back faces, which a
        # one-sided diffuse BSDF renders black
        "mesh": {"type": "ply", "filename": mesh_file, "bsdf": {"type": "twosided", "material": material}},
    }
    if preset.environment > 0:
        scene["environment"] = {"type": "constant", "radiance": rgb(preset.environment)}
    az = camera_azimuth(camera, preset)
    for i, light in enumerate(preset.lights):
        scene[f"light_{i}"] = _area_light(light, az, sphere, preset)
    if preset.ground.enabled:
        scene["ground"] = _ground(sphere, lowest, preset)
    return scene


def to_mitsuba(d: Any, base_dir: str | Path, mi) -> Any:
    """Plain scene dict -> ``mi.load_dict`` input (transforms to Mitsuba types, files made absolute)."""
    if isinstance(d, dict):
        out = {}
        for k, v in d.items():
            if k == "filename":
                out[k] = str(Path(base_dir) / v)
            else:
                out[k] = to_mitsuba(v, base_dir, mi)
        return out
    if isinstance(d, np.ndarray):
        if d.shape == (4, 4):
            return mi.ScalarTransform4f(d.tolist())
        if d.shape == (3, 3):
            return mi.ScalarTransform3f(d.tolist())
        raise AssertionError(f"unexpected array of shape {d.shape} in a scene dict")
    return d


def _fmt(x: float) -> str:
    return repr(float(x))


def _xml_lines(name: str | None, d: Any, indent: int) -> list[str]:
    pad = "    " * indent
    attr = f" name={quoteattr(name)}" if name else ""
    if isinstance(d, dict) and d.get("type") == "rgb":
        return [f'{pad}<rgb{attr} value="{", ".join(_fmt(x) for x in d["value"])}"/>']
    if isinstance(d, dict):
        tag = PLUGIN_TAGS[d["type"]]
        # top-level objects get an id, nested ones their property name
        ident = f" id={quoteattr(name)}" if indent == 1 else attr
        lines = [f'{pad}<{tag} type="{d["type"]}"{ident}>']
        for k, v in d.items():
            if k != "type":
                lines += _xml_lines(k, v, indent + 1)
        return lines + [f"{pad}</{tag}>"]
    if isinstance(d, np.ndarray):
        m = d if d.shape == (4, 4) else np.array([[d[0, 0], d[0, 1], 0, d[0, 2]], [d[1, 0], d[1, 1], 0, d[1, 2]],
                                                  [0, 0, 1, 0], [d[2, 0], d[2, 1], 0, d[2, 2]]])
        values = " ".join(_fmt(x) for x in m.reshape(-1))
        return [f"{pad}<transform{attr}>", f'{pad}    <matrix value="{values}"/>', f"{pad}</transform>"]
    if isinstance(d, bool):
        return [f'{pad}<boolean{attr} value="{str(d).lower()}"/>']
    if isinstance(d, (int, np.integer)):
        return [f'{pad}<integer{attr} value="{int(d)}"/>']
    if isinstance(d, (float, np.floating)):
        return [f'{pad}<float{attr} value="{_fmt(d)}"/>']
    if isinstance(d, str):
        return [f"{pad}<string{attr} value={quoteattr(d)}/>"]
    raise AssertionError(f"cannot write {type(d).__name__} to Mitsuba XML")


def scene_xml(scene: dict) -> str:
    """Mitsuba 3 scene file text for a plain scene dict (files stay relative to the XML's folder)."""
    lines = ['<?xml version="1.0" encoding="utf-8"?>', "<!-- written by mna render -->",
             '<scene version="3.0.0">']
    for k, v in scene.items():
        if k != "type":
            lines += _xml_lines(k, v, 1)
    return "\n".join(lines + ["</scene>", ""])


def render_dict(scene: dict, base_dir: str | Path, variant: str, seed: int = 0) -> np.ndarray:
    """Render a plain scene dict with ``variant``: linear RGBA ``(H, W, 4)`` float32."""
    from render.backend import use_variant

    mi = use_variant(variant)
    loaded = mi.load_dict(to_mitsuba(scene, base_dir, mi))
    return np.array(mi.render(loaded, seed=seed), dtype=np.float32)


def render_xml(path: str | Path, variant: str, seed: int = 0) -> np.ndarray:
    """Render a Mitsuba scene file with ``variant``: linear RGBA ``(H, W, 4)`` float32."""
    from render.backend import use_variant

    mi = use_variant(variant)
    return np.array(mi.render(mi.load_file(str(path)), seed=seed), dtype=np.float32)
