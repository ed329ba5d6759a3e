"""Scene presets and camera rigs: closed forms, framing, strict preset parsing (no renderer needed)."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from scenes.cameras import BoundingSphere, bounding_sphere, camera_rig, direction, frame_camera, project, view_specs
from scenes.presets import BUILTIN_PRESETS, ViewSpec, load_preset, preset_from_dict


@pytest.mark.parametrize("name", BUILTIN_PRESETS)
def test_builtin_presets_load(name):
    p = load_preset(name)
    assert p.name == name
    assert {"front", "side", "top", "three_quarter"} <= set(p.views)


def test_direction_closed_form():
    # up = +y, front = +z: right = up x front = +x
    np.testing.assert_allclose(direction(0, 0), [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(direction(90, 0), [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(direction(0, 90), [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(direction(45, 0), [math.sqrt(0.5), 0, math.sqrt(0.5)], atol=1e-12)
    # z-up world, front = -y
    np.testing.assert_allclose(direction(0, 90, up=(0, 0, 1), front=(0, -1, 0)), [0, 0, 1], atol=1e-12)


def test_bounding_sphere_matches_design_normalisation():
    v = np.array([[0, 0, 0], [2, 0, 0], [0, 4, 0], [0, 0, 6.0]])
    s = bounding_sphere(v)
    np.testing.assert_allclose(s.center, [1, 2, 3])
    assert s.radius == pytest.approx(np.linalg.norm(v - [1, 2, 3], axis=1).max())


def test_camera_distance_makes_sphere_tangent_to_view_cone():
    p = load_preset("studio")
    sphere = BoundingSphere(np.array([0.5, -1.0, 2.0]), 3.0)
    cam = frame_camera("front", sphere, ViewSpec(0, 0), p, 64, 64)
    d = np.linalg.norm(cam.origin - sphere.center)
    # sin(half fov) = margin * r / d
    assert p.camera.margin * sphere.radius / d == pytest.approx(math.sin(math.radians(p.camera.fov / 2)))
    px = project(sphere.center[None], cam).pixels[0]
    np.testing.assert_allclose(px, [32, 32], atol=1e-9)


def test_projection_of_camera_axes():
    p = load_preset("studio")
    cam = frame_camera("front", BoundingSphere(np.zeros(3), 1.0), ViewSpec(0, 0), p, 100, 50)
    # front camera on +z looking at -z: world +x is image right, +y image up
    right = project(np.array([[0.1, 0, 0]]), cam).pixels[0]
    up = project(np.array([[0, 0.1, 0]]), cam).pixels[0]
    assert right[0] > 50 and right[1] == pytest.approx(25)
    assert up[1] < 25 and up[0] == pytest.approx(50)


def test_look_at_matches_mitsuba():
    from render.backend import use_variant
    from render.mitsuba_scene import look_at

    mi = use_variant("scalar_rgb")
    o, t, u = [1.0, 2.0, 3.0], [0.5, -1.0, 0.0], [0.0, 1.0, 0.0]
    ref = np.array(mi.ScalarTransform4f().look_at(origin=o, target=t, up=u).matrix)
    np.testing.assert_allclose(look_at(o, t, u), ref, atol=1e-6)


@pytest.mark.parametrize("views,turntable", [(None, None), (None, 8), (["top"], None)])
def test_framing_keeps_every_vertex_inside(views, turntable, meshes):
    p = load_preset("studio")
    v, _, _ = meshes.torus()
    v = v * [1.0, 2.5, 0.7] + [3.0, -2.0, 10.0]  # off-centre, anisotropic
    for w, h in ((64, 64), (96, 48), (40, 80)):
        for cam in camera_rig(v, p, w, h, views, turntable):
            proj = project(v, cam)
            assert (proj.depth > 0).all()
            assert proj.pixels[:, 0].min() >= 0 and proj.pixels[:, 0].max() <= w, cam.name
            assert proj.pixels[:, 1].min() >= 0 and proj.pixels[:, 1].max() <= h, cam.name
            # and the mesh fills a good part of the frame (not framed absurdly loose)
            extent = np.ptp(proj.pixels, axis=0) / np.array([w, h])
            assert extent.max() > 0.5 * min(w, h) / max(w, h)


def test_top_view_up_vector_is_not_degenerate():
    p = load_preset("studio")
    (cam,) = camera_rig(np.eye(3), p, 32, 32, ["top"])
    left, up, fwd = cam.axes()
    assert np.isfinite(cam.to_world()).all()
    np.testing.assert_allclose(fwd, [0, -1, 0], atol=1e-12)
    np.testing.assert_allclose(up, [0, 0, -1], atol=1e-12)  # image up = the mesh's back


def test_turntable_azimuths():
    specs = view_specs(load_preset("studio"), turntable=8)
    assert [round(s.azimuth) for _, s in specs] == [0, 45, 90, 135, 180, 225, 270, 315]
    assert len({n for n, _ in specs}) == 8


def test_unknown_view_is_a_clear_error():
    with pytest.raises(ValueError, match="unknown view 'diagonal'"):
        view_specs(load_preset("studio"), ["diagonal"])


@pytest.mark.parametrize("data,match", [
    ({"lights": [{"azimuth": 0, "brightness": 3}]}, r"lights\[0\]\.brightness: unknown key"),
    ({"camera": {"fov": "wide"}}, r"camera\.fov: expected a number"),
    ({"camera": {"fov": 200}}, r"camera\.fov: 200"),
    ({"colour": [1, 1, 1]}, r"colour: unknown key"),
    ({"ground": {"enabled": "yes"}}, r"ground\.enabled: expected true or false"),
    ({"up": [0, 1, 0], "front": [0, 2, 0]}, "must not be parallel"),
    ({"views": {}}, "views"),
])
def test_bad_preset_is_a_clear_error(data, match):
    data = {"views": {"front": {"azimuth": 0, "elevation": 0}}, **data}
    with pytest.raises(ValueError, match=match):
        preset_from_dict(data, "test.yaml")


def test_user_preset_file_json_and_yaml(tmp_path):
    data = {"views": {"left": {"azimuth": -90, "elevation": 10}}, "environment": 0.5,
            "lights": [{"azimuth": 10, "elevation": 40, "intensity": 2}], "ground": {"enabled": False}}
    (tmp_path / "mine.json").write_text(json.dumps(data))
    p = load_preset(tmp_path / "mine.json")
    assert p.name == "mine" and p.environment == 0.5 and not p.ground.enabled
    assert p.lights[0].intensity == 2.0 and p.views["left"].azimuth == -90
    (tmp_path / "bad.yaml").write_text("views: {front: {azimuth: 0}}\nshadows: true\n")
    with pytest.raises(ValueError, match="shadows: unknown key"):
        load_preset(tmp_path / "bad.yaml")
    with pytest.raises(ValueError, match="not found"):
        load_preset(tmp_path / "missing.yaml")
