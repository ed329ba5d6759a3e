"""Textures, image I/O, PLY and scene-file writing: closed forms and round trips (no rendering)."""
from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest

from render.heatmap import distortion_colors, island_colors, shared_range
from render.images import (box_downsample, linear_to_srgb, read_image, relative_error, srgb_to_linear,
                           to_display, write_exr, write_png)
from render.meshes import load_uv_mesh, unshare, vertex_normals, write_ply
from render.mitsuba_scene import material_bitmap, material_procedural_checker, scene_dict, scene_xml
from texture.textures import checker_image, squares_per_uv_unit, uv_grid_image, uv_length_scale
from scenes.cameras import bounding_sphere, camera_rig
from scenes.presets import load_preset


def test_checker_texture_convention():
    img = checker_image(2.0, 8, colors=((1, 1, 1), (0, 0, 0)))
    # 2 squares per UV unit on 8 px: 4 px squares; the square at UV (0,0) is the bottom-left, colour 0
    assert img.shape == (8, 8, 3)
    assert (img[4:, :4] == 1).all() and (img[:4, 4:] == 1).all()
    assert (img[:4, :4] == 0).all() and (img[4:, 4:] == 0).all()


def test_checker_refuses_squares_below_four_texels():
    with pytest.raises(ValueError, match="texels"):
        checker_image(300.0, 1024)


def test_uv_grid_texture_shape_and_lines():
    img = uv_grid_image(4.0, 64)
    assert img.shape == (64, 64, 3) and img.min() >= 0 and img.max() <= 1
    assert np.allclose(img[:, 0], 0.1)  # the cell edge at u = 0 is a dark line


def test_uv_length_scale_closed_form(meshes):
    v, f, uv = meshes.flat_square(side=2.0)
    # 3D area 4, UV area 1 -> s = 2 (3D length per UV unit)
    assert uv_length_scale(v, f, uv) == pytest.approx(2.0)
    assert squares_per_uv_unit(v, f, uv, square_size=0.25) == pytest.approx(8.0)
    # scaling the mesh by 3 scales s by 3: same 3D square size -> 3x the frequency
    assert squares_per_uv_unit(3 * v, f, uv, 0.25) == pytest.approx(24.0)


def test_srgb_round_trip():
    x = np.linspace(0, 1, 101, dtype=np.float32)
    np.testing.assert_allclose(srgb_to_linear(linear_to_srgb(x)), x, atol=1e-5)
    assert linear_to_srgb(np.float32(0.5)) == pytest.approx(0.7354, abs=1e-3)


def test_to_display_composites_premultiplied_alpha():
    rgba = np.array([[[0.0, 0.0, 0.0, 0.0], [0.25, 0.25, 0.25, 0.5]]], np.float32)
    out = to_display(rgba, (1.0, 1.0, 1.0))
    np.testing.assert_allclose(out[0, 0], 1.0, atol=1e-6)  # empty pixel = background
    np.testing.assert_allclose(out[0, 1], linear_to_srgb(np.float32(0.75)), atol=1e-6)


def test_png_and_exr_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    img = rng.random((5, 7, 3)).astype(np.float32)
    write_png(tmp_path / "a.png", img)
    np.testing.assert_allclose(read_image(tmp_path / "a.png"), img, atol=0.5 / 255 + 1e-6)
    write_exr(tmp_path / "a.exr", img * 10)
    np.testing.assert_allclose(read_image(tmp_path / "a.exr"), img * 10, rtol=1e-3)
    assert not list(tmp_path.glob(".*"))  # no temporaries left behind


def test_relative_error_bounds():
    ref = np.full((8, 8, 3), 0.5, np.float32)
    img = ref.copy()
    img[0, 0] = 1.0  # one bad pixel
    err = relative_error(img, ref, floor=0.05, block=4)
    assert err.mean == pytest.approx(0.5 / 0.55 / 64)
    assert err.max == pytest.approx(0.5 / 16 / 0.55)
    assert box_downsample(img, 4).shape == (2, 2, 3)
    with pytest.raises(ValueError, match="shape"):
        relative_error(img[:4], ref)


def test_ply_round_trip_flips_v(tmp_path, meshes):
    import trimesh

    v, f, uv = meshes.torus(n=6, m=4)
    write_ply(tmp_path / "m.ply", v, f, uv, vertex_normals(v, f))
    m = trimesh.load(tmp_path / "m.ply", process=False)
    np.testing.assert_allclose(m.vertices, v, atol=1e-6)
    np.testing.assert_array_equal(m.faces, f)
    text = (tmp_path / "m.ply").read_bytes()
    header, body = text.split(b"end_header\n")
    assert b"property float u" in header and b"property float nx" in header
    rows = np.frombuffer(body[: len(v) * 8 * 4], "<f4").reshape(len(v), 8)
    np.testing.assert_allclose(rows[:, 6], uv[:, 0], atol=1e-6)
    np.testing.assert_allclose(rows[:, 7], 1 - uv[:, 1], atol=1e-6)


def test_vertex_normals_are_seam_free(meshes):
    v, f, _ = meshes.torus(n=8, m=6)
    n = vertex_normals(v, f)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1, atol=1e-9)
    # seam copies (same position) get the same normal
    _, inv = np.unique(np.round(v, 9), axis=0, return_inverse=True)
    for k in np.unique(inv.reshape(-1)):
        group = n[inv.reshape(-1) == k]
        np.testing.assert_allclose(group, np.broadcast_to(group[0], group.shape), atol=1e-12)
    # outward: the torus normal at (R + r, 0, 0) points along +x
    i = np.argmax(v[:, 0])
    np.testing.assert_allclose(n[i], [1, 0, 0], atol=1e-6)


def test_unshare_gives_three_vertices_per_face(meshes):
    from render.meshes import UVMesh

    v, f, uv = meshes.flat_square(n=2)
    flat = unshare(UVMesh(v, f, uv))
    assert flat.vertices.shape == (3 * len(f), 3)
    np.testing.assert_array_equal(flat.faces.reshape(-1), np.arange(3 * len(f)))
    np.testing.assert_allclose(flat.vertices[flat.faces], v[f])


def test_load_uv_mesh_obj_with_and_without_uv(tmp_path, meshes):
    v, f, uv = meshes.flat_square(n=2)
    m = load_uv_mesh(meshes.write_obj(tmp_path / "uv.obj", v, f, uv))
    assert m.uv is not None and m.uv.shape == (len(m.vertices), 2)
    assert load_uv_mesh(meshes.write_obj(tmp_path / "plain.obj", v, f)).uv is None
    with pytest.raises(ValueError, match="not found"):
        load_uv_mesh(tmp_path / "nope.obj")


def test_shared_heat_scale_and_colours():
    a, b = np.linspace(0, 1, 101), np.linspace(0, 3, 101)
    s = shared_range([a, b], percentile=100)
    assert (s.vmin, s.vmax) == (0.0, 3.0)
    cols = distortion_colors(np.array([0.0, 3.0, 10.0, np.nan]), s)
    np.testing.assert_allclose(cols[1], cols[2])  # clipped at vmax
    np.testing.assert_allclose(cols[3], 0.5)  # NaN -> grey
    assert not np.allclose(cols[0], cols[1])
    ids = island_colors(np.array([0, 1, 1, 2]))
    np.testing.assert_allclose(ids[1], ids[2])
    assert not np.allclose(ids[0], ids[1])
    assert island_colors(np.arange(50)).shape == (50, 3)  # many charts: golden-ratio hues


def test_scene_xml_structure(meshes):
    p = load_preset("studio")
    v, f, uv = meshes.torus(n=6, m=4)
    (cam,) = camera_rig(v, p, 32, 24, ["front"])
    for mat in (material_bitmap("texture.png"), material_procedural_checker(8.0, p.material.checker_colors)):
        root = ET.fromstring(scene_xml(scene_dict("mesh.ply", mat, cam, bounding_sphere(v), v[:, 1].min(), p, 7)))
        assert root.tag == "scene" and root.get("version", "").startswith("3.")
        sensor = root.find("sensor")
        assert sensor.find("film/integer[@name='width']").get("value") == "32"
        assert sensor.find("sampler/integer[@name='sample_count']").get("value") == "7"
        m = np.array([float(x) for x in sensor.find("transform/matrix").get("value").split()]).reshape(4, 4)
        np.testing.assert_allclose(m, cam.to_world())
        assert root.find("shape[@id='mesh']/string[@name='filename']").get("value") == "mesh.ply"
        assert len(root.findall("shape/emitter[@type='area']")) == len(p.lights)
        assert root.find("shape[@id='ground']") is not None
        assert root.find("shape[@id='mesh']/bsdf[@type='twosided']/bsdf/texture").get("name") == "reflectance"
