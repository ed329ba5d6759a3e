"""Fast rasterised previews with pyrender (headless through EGL), with the same cameras as Mitsuba.

Lights approximate the preset: each area light becomes a directional light from the
same position with irradiance ``intensity * size^2 / distance^2``; the constant
environment becomes ambient light. Good for a quick look, not for figures.

``PYOPENGL_PLATFORM`` must be set before PyOpenGL is first imported; ``_pyrender`` sets
it to ``egl`` when unset. With no working EGL the preview raises ``PreviewUnavailable``
with a one-line reason, and callers skip the preview instead of failing the render.
"""
from __future__ import annotations

import os

import numpy as np

from render.meshes import UVMesh, vertex_normals
from scenes.cameras import BoundingSphere, Camera, direction, world_frame
from scenes.presets import Preset


class PreviewUnavailable(RuntimeError):
    """pyrender or its EGL context cannot be used on this machine."""


def _pyrender():
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    try:
        import pyrender
    except Exception as exc:  # ImportError, or OpenGL's own errors when no GL library loads
        raise PreviewUnavailable(f"pyrender preview unavailable: {type(exc).__name__}: {exc}") from None
    return pyrender


def _material(pyrender, base_color=(1.0, 1.0, 1.0), texture: np.ndarray | None = None):
    kw = {}
    if texture is not None:
        img = np.round(np.clip(texture[..., :3], 0, 1) * 255).astype(np.uint8)
        kw["baseColorTexture"] = pyrender.Texture(source=img, source_channels="RGB")
    return pyrender.MetallicRoughnessMaterial(baseColorFactor=(*base_color, 1.0), metallicFactor=0.0,
                                              roughnessFactor=1.0, doubleSided=True, **kw)


def mesh_node(pyrender, mesh: UVMesh, texture: np.ndarray | None = None,
              face_colors: np.ndarray | None = None, base_color=(0.7, 0.7, 0.7)):
    """pyrender mesh: textured (sRGB ``texture`` (H, W, 3)), per-face colours (F, 3), or plain."""
    if face_colors is not None:
        idx = mesh.faces.reshape(-1)
        prim = pyrender.Primitive(
            positions=mesh.vertices[idx].astype(np.float32),
            normals=vertex_normals(mesh.vertices, mesh.faces)[idx].astype(np.float32),
            color_0=np.repeat(np.asarray(face_colors, np.float32), 3, axis=0),
            indices=np.arange(len(idx), dtype=np.uint32).reshape(-1, 3), material=_material(pyrender))
        return pyrender.Mesh([prim])
    # pyrender flips images on upload, so OBJ-convention UVs (v up) are used as they are
    uv = mesh.uv.astype(np.float32) if texture is not None else None
    prim = pyrender.Primitive(
        positions=mesh.vertices.astype(np.float32),
        normals=vertex_normals(mesh.vertices, mesh.faces).astype(np.float32),
        texcoord_0=uv, indices=mesh.faces.astype(np.uint32),
        material=_material(pyrender, (1.0, 1.0, 1.0) if texture is not None else base_color, texture))
    return pyrender.Mesh([prim])


def _ground_node(pyrender, sphere: BoundingSphere, lowest: float, preset: Preset):
    right, up, front = world_frame(preset.up, preset.front)
    half = preset.ground.size * sphere.radius / 2
    c = sphere.center + ((lowest - sphere.center @ up) - preset.ground.offset * sphere.radius) * up
    quad = np.array([c - half * right - half * front, c + half * right - half * front,
                     c + half * right + half * front, c - half * right + half * front], np.float32)
    prim = pyrender.Primitive(positions=quad, normals=np.tile(up.astype(np.float32), (4, 1)),
                              indices=np.array([[0, 2, 1], [0, 3, 2]], np.uint32),
                              material=_material(pyrender, preset.ground.color))
    return pyrender.Mesh([prim])


class PreviewRenderer:
    """One offscreen EGL context reused over views: ``render(camera) -> (H, W, 3)`` sRGB floats."""

    def __init__(self, node_mesh, sphere: BoundingSphere, lowest: float, preset: Preset,
                 width: int, height: int):
        self.pyrender = pr = _pyrender()
        self.preset, self.sphere = preset, sphere
        bg = preset.background if preset.background is not None else (preset.environment,) * 3
        self.scene = pr.Scene(bg_color=(*bg, 1.0), ambient_light=(preset.environment,) * 3)
        self.scene.add(node_mesh)
        if preset.ground.enabled:
            self.scene.add(_ground_node(pr, sphere, lowest, preset))
        try:
            self.renderer = pr.OffscreenRenderer(width, height)
        except Exception as exc:
            raise PreviewUnavailable(f"pyrender preview unavailable (no EGL context: {type(exc).__name__}: "
                                     f"{str(exc).strip().splitlines()[0] if str(exc).strip() else ''})") from None
        self._light_nodes = []
        self._camera_node = None

    def _set_lights(self, camera: Camera) -> None:
        from render.mitsuba_scene import camera_azimuth, look_at

        for n in self._light_nodes:
            self.scene.remove_node(n)
        self._light_nodes = []
        cam_az = camera_azimuth(camera, self.preset)
        for light in self.preset.lights:
            az = light.azimuth + (cam_az if self.preset.lights_follow_camera else 0.0)
            d = direction(az, light.elevation, self.preset.up, self.preset.front)
            pos = self.sphere.center + light.distance * self.sphere.radius * d
            _, up, front = world_frame(self.preset.up, self.preset.front)
            pose = look_at(pos, self.sphere.center, front if abs(d @ up) > 0.999 else up)
            pose[:3, 2] *= -1  # directional lights shine along their local -z
            pose[:3, 0] *= -1
            irradiance = light.intensity * light.size**2 / light.distance**2
            node = self.scene.add(self.pyrender.DirectionalLight(color=light.color, intensity=irradiance),
                                  pose=pose)
            self._light_nodes.append(node)

    def render(self, camera: Camera) -> np.ndarray:
        pr = self.pyrender
        if self._camera_node is not None:
            self.scene.remove_node(self._camera_node)
        dist = float(np.linalg.norm(camera.origin - camera.target))
        cam = pr.PerspectiveCamera(yfov=camera.yfov(), aspectRatio=camera.width / camera.height,
                                   znear=0.01 * dist, zfar=100.0 * dist)
        self._camera_node = self.scene.add(cam, pose=camera.gl_pose())
        self._set_lights(camera)
        color, _ = self.renderer.render(self.scene)
        return color.astype(np.float32) / 255.0

    def close(self) -> None:
        self.renderer.delete()
