"""Textures (checker, UV grid, bake, dilation), image I/O and OBJ/GLB export round trips."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh
from texture_helpers import color_function

from mnacore.errors import InputError
from mnacore.uvmesh import make_uv_mesh
from texture.export import export_textured, read_back
from texture.textures import (
    bake,
    check_size,
    checker_image,
    dilate,
    read_image,
    sample_bilinear,
    squares_per_uv_unit,
    texel_centers,
    uv_grid_image,
    uv_length_scale,
    write_image,
)
from texture.xatlas_uv import XatlasOptions, unwrap


@pytest.fixture(scope="module")
def sphere_atlas(icosphere):
    res = unwrap(icosphere.vertices, icosphere.faces, XatlasOptions(resolution=256, padding=4))
    return res.mesh


def test_texel_centres_convention():
    u, v = texel_centers(2, 4)
    assert u[0].tolist() == [0.125, 0.375, 0.625, 0.875]
    assert v[:, 0].tolist() == [0.75, 0.25]  # row 0 is the top of the texture (v near 1)


def test_checker_frequency_matches_3d_square_size():
    V = np.array([[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0.0]])
    m = make_uv_mesh(V, [[0, 1, 2], [0, 2, 3]], V[:, :2] / 8)  # 1 UV unit = 8 units of length
    assert uv_length_scale(m.vertices, m.faces, m.uv) == pytest.approx(8.0)
    # squares of side 0.05 on the surface: 8 / 0.05 = 160 per UV unit (not (1/8) / 0.05 = 2.5)
    assert squares_per_uv_unit(m.vertices, m.faces, m.uv, square_size=0.05) == pytest.approx(160.0)
    img = checker_image(4.0, 64)  # 16 texels per square
    assert img.shape == (64, 64, 3)
    assert (img[0, 0] == img[0, 15]).all() and not (img[0, 0] == img[0, 16]).all()
    assert (img[0, 0] == img[16, 16]).all()
    g = uv_grid_image(4.0, 64)
    assert g[:, :, 0].std() > 0.1 and g.min() >= 0 and g.max() <= 1


def _square_runs(row: np.ndarray) -> np.ndarray:
    """Lengths (texels) of the runs of equal colour along an image row, ends excluded."""
    change = np.flatnonzero(np.abs(np.diff(row, axis=0)).sum(1) > 0.1)
    return np.diff(change)


def test_exported_checker_squares_have_the_promised_3d_size(tmp_path):
    """The texture written by an export, read back from the PNG: a square spans ``square_size``
    of surface. The plane's UV scale is not 1 (1 UV unit = 2.8 units of length), so a units
    inversion (squares per UV unit = (1/s) / L instead of s / L) shows as 2.8^2 = 7.8x squares."""
    from texture.export import export_textured
    from texture.pipeline import make_texture

    side = 1.4  # a square plane inside the unit ball
    V = np.array([[0, 0, 0], [side, 0, 0], [side, side, 0], [0, side, 0.0]]) - [side / 2, side / 2, 0]
    uv = (V[:, :2] + side / 2) / side * 0.5 + 0.25  # occupies [0.25, 0.75]^2 of the texture
    mesh = make_uv_mesh(V, [[0, 1, 2], [0, 2, 3]], uv)
    size, square = 1024, 0.1
    paths = export_textured(tmp_path, mesh, make_texture("checker", mesh, size, 8, square_size=square))
    img = read_image(paths["texture"])
    rows = img[int(0.3 * size):int(0.7 * size):37]
    runs = np.concatenate([_square_runs(r) for r in rows])
    texels_per_length = size * 0.5 / side  # the plane spans 0.5 UV = 512 texels over 1.4 units
    square_texels = square * texels_per_length
    assert np.median(runs) == pytest.approx(square_texels, abs=1.0)


def test_checker_too_fine_for_the_texture_is_refused():
    with pytest.raises(InputError, match="texels"):
        checker_image(300.0, 1024)


def test_dilate_fills_gutter_rings():
    mask = np.zeros((9, 9), bool)
    mask[4, 4] = True
    img = np.zeros((9, 9, 3))
    img[4, 4] = [0.2, 0.4, 0.6]
    out, grown = dilate(img, mask, 2)
    assert grown.sum() == 25  # a 5x5 block after two 8-neighbour rings
    np.testing.assert_allclose(out[grown], np.tile([0.2, 0.4, 0.6], (25, 1)))
    assert (out[~grown] == 0).all()


def test_bake_round_trip_vertex_colours(icosphere, sphere_atlas):
    source = icosphere.copy()
    source.visual.vertex_colors = color_function(source.vertices)
    img = bake(sphere_atlas, source, 256, padding=4)
    # face centres: barycentric blend of vertex colours, which the linear colour function reproduces
    centre_uv = sphere_atlas.uv[sphere_atlas.faces].mean(1)
    centre_xyz = sphere_atlas.vertices[sphere_atlas.faces].mean(1)
    got = sample_bilinear(img, centre_uv)
    want = color_function(centre_xyz)[:, :3] / 255.0
    # tolerance: vertex colours rounded to 8 bit (0.5/255) + bilinear blend over one texel of
    # a field whose gradient is 0.5 per unit over texels of ~0.02 units
    assert np.abs(got - want).max() < 0.03
    assert np.abs(got - want).mean() < 0.006


def test_bake_without_colours_is_rejected(icosphere, sphere_atlas):
    with pytest.raises(InputError, match="neither vertex colours nor a texture"):
        bake(sphere_atlas, trimesh.Trimesh(icosphere.vertices, icosphere.faces), 64)


def test_bake_refuses_a_missing_texture(tmp_path):
    """An OBJ with UVs whose .mtl is missing: trimesh makes a 2 x 2 placeholder image, which
    would bake as flat grey; the user is told the material file is missing instead."""
    obj = tmp_path / "m.obj"
    obj.write_text("mtllib missing.mtl\nusemtl x\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n")
    source = trimesh.load(obj, force="mesh", process=False)
    from texture.textures import source_colors

    with pytest.raises(InputError, match="placeholder.*missing"):
        source_colors(source)


def test_bake_from_textured_source(icosphere, sphere_atlas):
    # the source: the same sphere with its own (xatlas) UVs and a texture = colour of its 3D point
    src_img = np.zeros((256, 256, 3))
    face, bary = __import__("texture.raster", fromlist=["face_id_image"]).face_id_image(
        sphere_atlas.uv[sphere_atlas.faces], 256, 256)
    hit = face >= 0
    pts = (bary[hit][:, :, None] * sphere_atlas.vertices[sphere_atlas.faces[face[hit]]]).sum(1)
    src_img[hit] = color_function(pts)[:, :3] / 255.0
    src_img, _ = dilate(src_img, hit, 4)
    import PIL.Image

    source = trimesh.Trimesh(sphere_atlas.vertices, sphere_atlas.faces, process=False)
    source.visual = trimesh.visual.TextureVisuals(
        uv=sphere_atlas.uv, image=PIL.Image.fromarray((src_img * 255).round().astype(np.uint8)))
    target = make_uv_mesh(sphere_atlas.vertices, sphere_atlas.faces, sphere_atlas.uv)
    img = bake(target, source, 256, padding=4)
    centre_uv = target.uv[target.faces].mean(1)
    want = color_function(target.vertices[target.faces].mean(1))[:, :3] / 255.0
    assert np.abs(sample_bilinear(img, centre_uv) - want).mean() < 0.01


@pytest.mark.parametrize("ext, tol", [(".png", 0.5 / 255 + 1e-9), (".exr", 1e-7)])
def test_image_round_trip(tmp_path, ext, tol):
    rng = np.random.default_rng(1)
    img = rng.random((7, 5, 3))
    write_image(tmp_path / f"a{ext}", img)
    back = read_image(tmp_path / f"a{ext}")
    assert back.shape == (7, 5, 3)
    assert np.abs(back - img).max() <= tol
    assert [p.name for p in tmp_path.iterdir()] == [f"a{ext}"]  # no temporary left


def test_unreadable_image(tmp_path):
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"not a png at all")
    with pytest.raises(InputError, match="cannot read image"):
        read_image(bad)


@pytest.mark.parametrize("size", [0, -3, "abc", "1.5", 2.0, True, None])
def test_check_size_rejects(size):
    with pytest.raises(InputError, match="positive integer"):
        check_size(size)


def test_check_size_accepts():
    assert check_size("512") == 512 and check_size(64) == 64


@pytest.mark.parametrize("kind", ["obj", "glb"])
def test_export_round_trip(tmp_path, sphere_atlas, kind):
    mesh = make_uv_mesh(sphere_atlas.vertices * 3 + [1, 2, 3], sphere_atlas.faces, sphere_atlas.uv)
    paths = export_textured(tmp_path, mesh, checker_image(4.0, 32))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mesh.glb", "mesh.mtl", "mesh.obj", "mesh_texture.png"]
    back = read_back(paths[kind])
    assert back.faces.shape == mesh.faces.shape
    # same corners in the same order: compare UV and position per face corner
    np.testing.assert_allclose(back.uv[back.faces], mesh.uv[mesh.faces], atol=1e-6)
    np.testing.assert_allclose(back.vertices[back.faces], mesh.vertices[mesh.faces], atol=1e-5)
    assert read_image(paths["texture"]).shape == (32, 32, 3)
    if kind == "obj":
        assert "map_Kd mesh_texture.png" in (tmp_path / "mesh.mtl").read_text()
        tm = trimesh.load(paths["obj"], process=False)
        assert tm.visual.material.image.size == (32, 32)  # the MTL finds the texture
    else:
        tm = trimesh.load(paths["glb"], force="mesh", process=False)
        img = np.asarray(tm.visual.material.baseColorTexture)
        assert img.shape[:2] == (32, 32)  # embedded
