"""Exported assets as viewers read them: material, normals, precision, winding, slivers, the validator."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh
from texture_helpers import assert_glb_validates, glb_attribute, glb_json

from mnacore.grid import grid_faces
from mnacore.uvmesh import make_uv_mesh, weld_ids
from texture.clip import SNAP_FRACTION, clip_mesh
from texture.export import ATLAS_SAMPLER, ROUGHNESS, export_textured, read_back
from texture.harness import measure
from texture.layouts import prepare, unmirrored
from texture.normals import shading_normals
from texture.textures import checker_image
from texture.trim import Piece
from texture.xatlas_uv import XatlasOptions, unwrap


def _xatlas(mesh: trimesh.Trimesh):
    return unwrap(mesh.vertices, mesh.faces, XatlasOptions(resolution=256, padding=4)).mesh


@pytest.fixture(scope="module")
def sphere_export(tmp_path_factory, icosphere):
    folder = tmp_path_factory.mktemp("sphere_export")
    mesh = _xatlas(icosphere)
    return mesh, export_textured(folder, mesh, checker_image(8.0, 256))


def test_glb_material_is_matte_plastic_and_single_sided_when_closed(sphere_export):
    _, paths = sphere_export
    (mat,) = glb_json(paths["glb"])["materials"]
    pbr = mat["pbrMetallicRoughness"]
    assert pbr["metallicFactor"] == 0.0  # glTF's default is 1 (a metal)
    assert pbr["roughnessFactor"] == pytest.approx(ROUGHNESS)
    assert "baseColorTexture" in pbr
    assert mat.get("doubleSided", False) is False  # closed: back faces are never seen
    mtl = open(paths["mtl"]).read()
    assert "Pm 0.0" in mtl and "Ks 0.0 0.0 0.0" in mtl


def test_glb_atlas_is_clamped_at_its_edge_and_views_declare_their_targets(sphere_export):
    """The texture is sampled clamped to the edge (glTF's default, REPEAT, would blend the
    atlas's opposite border into islands that lie against this one) and mip-mapped; every
    vertex attribute's view is an ARRAY_BUFFER, the indices' an ELEMENT_ARRAY_BUFFER."""
    _, paths = sphere_export
    doc = glb_json(paths["glb"])
    (tex,) = doc["textures"]
    sampler = doc["samplers"][tex["sampler"]]
    assert sampler["wrapS"] == sampler["wrapT"] == 33071  # CLAMP_TO_EDGE
    assert sampler["magFilter"] == 9729 and sampler["minFilter"] == 9987  # LINEAR, LINEAR_MIPMAP_LINEAR
    assert sampler == ATLAS_SAMPLER
    (prim,) = doc["meshes"][0]["primitives"]
    views = doc["bufferViews"]
    for name, acc in prim["attributes"].items():
        assert views[doc["accessors"][acc]["bufferView"]]["target"] == 34962, name
    assert views[doc["accessors"][prim["indices"]]["bufferView"]]["target"] == 34963
    image_view = views[doc["images"][0]["bufferView"]]
    assert "target" not in image_view  # an image is not vertex data


def test_open_surface_is_double_sided(tmp_path):
    grid = trimesh.creation.box()  # cut the box open: drop its two top triangles
    top = np.flatnonzero(grid.face_normals[:, 2] > 0.9)
    opened = trimesh.Trimesh(grid.vertices, np.delete(grid.faces, top, 0), process=False)
    paths = export_textured(tmp_path, _xatlas(opened), checker_image(8.0, 256))
    (mat,) = glb_json(paths["glb"])["materials"]
    assert mat["doubleSided"] is True


def test_smooth_normals_on_a_sphere_shared_across_seams(sphere_export, icosphere):
    mesh, paths = sphere_export
    glb = trimesh.load(paths["glb"], force="mesh", process=False)
    n = glb_attribute(paths["glb"], "NORMAL")  # as stored (trimesh recomputes its own on access)
    np.testing.assert_allclose(glb_attribute(paths["glb"], "POSITION"), glb.vertices)
    radial = glb.vertices / np.linalg.norm(glb.vertices, axis=1, keepdims=True)
    # an icosphere's vertex normal is its radial direction (by symmetry), to the facet error
    assert np.degrees(np.arccos(np.clip((n * radial).sum(1), -1, 1))).max() < 2.0
    assert len(glb.vertices) == len(mesh.vertices)  # no crease: no vertex added
    ids = weld_ids(glb.vertices)  # seam copies (same point, other UVs) share one normal
    for i in np.flatnonzero(np.bincount(ids) > 1)[:50]:
        same = n[ids == i]
        assert np.abs(same - same[0]).max() < 1e-6
    obj = open(paths["obj"]).read()
    assert obj.count("\nvn ") == len(mesh.vertices) and "/" in obj.split("\nf ")[1]


def test_cube_keeps_its_edges_sharp():
    box = trimesh.creation.box(extents=(2.0, 3.0, 5.0))
    weld = weld_ids(box.vertices)
    s = shading_normals(box.vertices, box.faces, weld)
    assert len(s.source) == 24  # 8 corners x 3 faces meeting at 90 degrees
    face_n = box.face_normals[:, None, :]
    np.testing.assert_allclose(s.normals[s.faces], np.repeat(face_n, 3, 1), atol=1e-12)


@pytest.mark.parametrize("scale", [1e-30, 1e-9, 1.0, 1e200])
def test_obj_and_glb_keep_coordinates_at_any_scale(tmp_path, scale):
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    mesh = _xatlas(box)
    mesh = make_uv_mesh(mesh.vertices * scale, mesh.faces, mesh.uv)
    if scale > 1e38:  # float32 (the GLB) cannot hold it: the writer must refuse, not write inf
        with pytest.raises(ValueError, match="float32"):
            export_textured(tmp_path, mesh, checker_image(8.0, 256))
        return
    paths = export_textured(tmp_path, mesh, checker_image(8.0, 256))
    for kind in ("obj", "glb"):
        back = read_back(paths[kind])
        order = np.lexsort(back.vertices.T)
        want = mesh.vertices[np.lexsort(mesh.vertices.T)]
        np.testing.assert_allclose(back.vertices[order], want, rtol=1e-7, atol=0)


def test_obj_and_glb_measure_the_same(sphere_export):
    _, paths = sphere_export
    a = measure(read_back(paths["obj"])).summary
    b = measure(read_back(paths["glb"])).summary
    for key in ("charts", "flipped_faces", "mirrored_islands", "degenerate_uv_faces"):
        assert a[key] == b[key], key
    # the same float32 numbers: the OBJ's 9 digits parse to within 1e-9 of them
    for key in ("seam_length", "distortion_metric", "distortion_conformal", "mirrored_area_percent",
                "uv_overlap_percent", "utilization", "surface_area"):
        assert a[key] == pytest.approx(b[key], rel=1e-6, abs=1e-9), key


def test_glb_passes_the_khronos_validator(sphere_export):
    _, paths = sphere_export
    assert_glb_validates(paths["glb"])


def test_glb_accessors_with_equal_data_keep_their_own_views(tmp_path):
    # an icosahedron's vertices lie on the unit sphere and its normals equal them to the bit;
    # a view shared by POSITION and NORMAL would need a byteStride (a validator error)
    ico = trimesh.creation.icosahedron()
    paths = export_textured(tmp_path, _xatlas(ico), checker_image(8.0, 256))
    np.testing.assert_array_equal(glb_attribute(paths["glb"], "NORMAL"), glb_attribute(paths["glb"], "POSITION"))
    accessors = glb_json(paths["glb"])["accessors"]
    views = [a["bufferView"] for a in accessors]
    assert len(set(views)) == len(views) == 4  # positions, normals, UVs, indices
    assert_glb_validates(paths["glb"])


def test_a_mesh_in_map_coordinates_keeps_its_shape(tmp_path, icosphere):
    # a unit sphere at UTM-like coordinates: float32 there steps by 0.5 (at 5.3e6), so the
    # positions are stored relative to the centre and the centre as the node's translation
    offset = np.array([412345.678, 5312345.432, 250.0])
    far = _xatlas(icosphere)
    far = make_uv_mesh(far.vertices + offset, far.faces, far.uv)
    paths = export_textured(tmp_path, far, checker_image(8.0, 256))
    for kind in ("glb", "obj"):
        back = read_back(paths[kind])
        assert back.faces.shape == far.faces.shape
        err = np.abs(back.vertices[back.faces] - far.vertices[far.faces]).max()
        assert err < 1e-6, (kind, err)  # float32 of a unit-size shape: ~6e-8; at the offset: 0.25
    glb, obj = read_back(paths["glb"]), read_back(paths["obj"])
    np.testing.assert_array_equal(glb.vertices[glb.faces], obj.vertices[obj.faces])
    (node,) = [n for n in glb_json(paths["glb"])["nodes"] if "mesh" in n]
    np.testing.assert_allclose(np.reshape(node["matrix"], (4, 4))[3, :3], far.vertices.min(0) / 2 + far.vertices.max(0) / 2)
    assert np.abs(glb_attribute(paths["glb"], "POSITION")).max() <= 1.0 + 1e-6
    assert_glb_validates(paths["glb"])


def test_asset_origin_only_for_a_mesh_far_from_the_origin_for_its_size():
    from mnacore.frame import FAR_FROM_ORIGIN as FAR
    from texture.export import asset_origin

    box = trimesh.creation.box(extents=[2.0, 1.0, 1.0]).vertices  # extent 2
    np.testing.assert_array_equal(asset_origin(box + [FAR * 2 - 1, 0, 0]), np.zeros(3))  # |v| up to 2 FAR: kept
    np.testing.assert_allclose(asset_origin(box + [FAR * 2, 5, 0]), [FAR * 2, 5, 0])  # beyond: its centre
    np.testing.assert_array_equal(asset_origin(box * 1e-6), np.zeros(3))  # small but centred: kept


def _two_islands(mirror_second: bool):
    """Two unit squares side by side in 3D (z up, wound counter-clockwise from +z), separate in UV."""
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [1, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0.0]])
    F = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    uv = V[:, :2] * 0.4 + [0.05, 0.05]
    uv[4:] += [0.1, 0.0]
    if mirror_second:
        uv[4:, 0] = 1.0 - uv[4:, 0]
    return V, F, uv


def test_harness_reports_mirrored_area():
    V, F, uv = _two_islands(mirror_second=True)
    s = measure(make_uv_mesh(V, F, uv)).summary
    assert s["mirrored_area_percent"] == pytest.approx(50.0)
    assert s["mirrored_islands"] == 1 and s["flipped_faces"] == 0  # consistent within each island
    V, F, uv = _two_islands(mirror_second=False)
    assert measure(make_uv_mesh(V, F, uv)).summary["mirrored_area_percent"] == 0.0


def test_atlas_reflects_mirrored_islands():
    V, F, uv = _two_islands(mirror_second=True)
    out = unmirrored(prepare(Piece(0, V.astype(float), uv, F)))
    t = out.uv[out.faces]
    signed = (t[:, 1, 0] - t[:, 0, 0]) * (t[:, 2, 1] - t[:, 0, 1]) - (t[:, 1, 1] - t[:, 0, 1]) * (t[:, 2, 0] - t[:, 0, 0])
    assert (signed > 0).all()
    np.testing.assert_allclose(out.xyz[out.faces], V[F])  # 3D and winding untouched
    # lengths in UV unchanged (a reflection): still an isometry up to the 0.4 scale
    e = np.linalg.norm(t[:, 1] - t[:, 0], axis=1)
    np.testing.assert_allclose(e, 0.4 * np.linalg.norm(V[F][:, 1] - V[F][:, 0], axis=1))


def test_clip_near_vertices_leaves_no_slivers():
    """An iso-line passing 0.1 % of a cell from grid vertices: plain marching triangles leave
    triangles of ~1e-3 of a face; snapping keeps every triangle at >= SNAP_FRACTION^2 / 4 of one
    and the kept region exact (the field is linear, so the snapped vertices lie on its line)."""
    G = 11
    lin = np.linspace(0, 1, G)
    x, y = np.meshgrid(lin, lin, indexing="xy")
    P = np.column_stack([x.ravel(), y.ravel()])
    h = 1.0 / (G - 1)
    field = (0.5 + 0.001 * h) - P[:, 0]  # kept: x < 0.5 + 0.001 h, just past a column of vertices
    face = 0.5 * h * h
    plain = clip_mesh(P, grid_faces(G), field)
    t = plain.attrs[plain.faces]
    a_plain = 0.5 * np.abs((t[:, 1, 0] - t[:, 0, 0]) * (t[:, 2, 1] - t[:, 0, 1])
                           - (t[:, 1, 1] - t[:, 0, 1]) * (t[:, 2, 0] - t[:, 0, 0]))
    assert a_plain.min() < 0.01 * face  # the slivers this guards against
    snapped = clip_mesh(P, grid_faces(G), field, plane=(0, 1))
    t = snapped.attrs[snapped.faces]
    a = 0.5 * ((t[:, 1, 0] - t[:, 0, 0]) * (t[:, 2, 1] - t[:, 0, 1]) - (t[:, 1, 1] - t[:, 0, 1]) * (t[:, 2, 0] - t[:, 0, 0]))
    assert (a > 0).all() and a.min() >= SNAP_FRACTION ** 2 / 4 * face
    assert a.sum() == pytest.approx(0.5 + 0.001 * h, abs=1e-12)
    on_line = snapped.attrs[snapped.field == 0]
    np.testing.assert_allclose(on_line[:, 0], 0.5 + 0.001 * h, atol=1e-12)
    # clipping the other side with the same rule gives the same border: the halves tile the square
    other = clip_mesh(P, grid_faces(G), -field, plane=(0, 1))
    t = other.attrs[other.faces]
    b = 0.5 * ((t[:, 1, 0] - t[:, 0, 0]) * (t[:, 2, 1] - t[:, 0, 1]) - (t[:, 1, 1] - t[:, 0, 1]) * (t[:, 2, 0] - t[:, 0, 0]))
    assert a.sum() + b.sum() == pytest.approx(1.0, abs=1e-12)
