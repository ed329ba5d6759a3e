"""``mna unwrap`` end to end: files, the input's faces read back, compare on the same mesh, bad input."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from texture_helpers import assert_glb_validates, glb_attribute, glb_json, write_sphere_run

from mna import shapes
from mna.cli import main
from mnacore.machine import cpu_summary
from texture.export import read_back
from texture.harness import measure
from texture.textures import read_image, same_triangles, sample_bilinear

SMALL = ["--size", "256", "--padding", "2"]


@pytest.fixture(scope="module")
def unwrapped(tmp_path_factory):
    """(run with synthetic sphere charts, OUT of `mna unwrap --run`, input mesh)."""
    run = write_sphere_run(tmp_path_factory.mktemp("sphere_run"), G=48)
    out = tmp_path_factory.mktemp("unwrap") / "out"
    assert main(["unwrap", str(run / "input.ply"), "-o", str(out), "--run", str(run), *SMALL]) == 0
    return run, out, trimesh.load(run / "input.ply", process=False)


def test_unwrap_writes_the_input_faces_with_uvs(unwrapped):
    run, out, mesh = unwrapped
    for name in ("mesh.obj", "mesh.mtl", "mesh_texture.png", "mesh.glb", "unwrap.json"):
        assert (out / name).is_file()
    info = json.loads((out / "unwrap.json").read_text())
    assert info["fit"] == "reused" and info["input_uv_replaced"] is False
    assert info["machine"] == cpu_summary()  # which machine the timings are of
    for stage in ("prepare", "assign", "clean", "flatten", "relax", "slits", "pack"):
        assert info["timings"][f"unwrap_{stage}"] >= 0
    for fmt in ("mesh.obj", "mesh.glb"):
        back = read_back(out / fmt)
        assert back.faces.shape == mesh.faces.shape
        np.testing.assert_allclose(back.vertices[back.faces], np.asarray(mesh.vertices)[mesh.faces], atol=1e-6)
    m = info["uv_metrics"]
    assert m["charts"] == info["islands"] and m["flipped_faces"] == 0 and m["uv_overlap_percent"] == 0.0
    assert m["distortion_metric"] < 0.15
    # OBJ and GLB of the same export measure identically (GLB stores float32)
    a, b = (measure(read_back(out / f), reference=mesh).summary for f in ("mesh.obj", "mesh.glb"))
    for key in ("charts", "flipped_faces", "uv_overlap_percent"):
        assert a[key] == b[key]
    for key in ("seam_length", "distortion_metric", "utilization"):
        assert a[key] == pytest.approx(b[key], rel=1e-3, abs=1e-4)


def test_unwrapped_glb_is_an_asset_viewers_accept(unwrapped):
    """The Khronos glTF validator: no errors, no warnings; material metallic 0 and normals present."""
    _, out, mesh = unwrapped
    (mat,) = glb_json(out / "mesh.glb")["materials"]
    assert mat["pbrMetallicRoughness"]["metallicFactor"] == 0.0
    normals = glb_attribute(out / "mesh.glb", "NORMAL")
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-6)
    # a sphere: every normal points away from the centre (no face wound inward)
    positions = glb_attribute(out / "mesh.glb", "POSITION")
    centre = np.asarray(mesh.vertices).mean(0)
    assert ((positions - centre) * normals).sum(1).min() > 0
    assert_glb_validates(out / "mesh.glb")


def test_compare_uses_the_same_input_mesh_for_xatlas(unwrapped):
    _, out, mesh = unwrapped
    assert main(["compare", str(out), "--no-sweep", *SMALL]) == 0
    rows = {r["method"]: r for r in json.loads((out / "compare.json").read_text())["methods"]}
    assert set(rows) == {"mna", "xatlas"}
    assert rows["mna"]["faces"] == rows["xatlas"]["faces"] == len(mesh.faces)
    assert rows["mna"]["mesh"] == rows["xatlas"]["mesh"] == "input"
    assert (out / "xatlas" / "mesh.obj").is_file() and (out / "compare.md").is_file()
    # the time column counts the unwrap after the fit, said once (not the reconstruction's stages)
    md = (out / "compare.md").read_text()
    assert md.count("Time: the UV method alone (ours: the unwrap after the fit).") == 1 and "trim, orient" not in md
    # uv-metrics on the folder's files: the same reference and frame, so the same numbers
    for method, path in (("mna", out / "mesh.glb"), ("xatlas", out / "xatlas" / "mesh.obj")):
        summary = out.parent / f"{method}_metrics.json"
        assert main(["uv-metrics", str(path), "-o", str(summary)]) == 0
        alone = json.loads(summary.read_text())
        for key in ("charts", "seam_length", "surface_area", "distortion_metric", "mirrored_area_percent"):
            assert alone[key] == pytest.approx(rows[method][key], rel=1e-5, abs=1e-9), (method, key)


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


@pytest.mark.parametrize("case", ["no_faces", "point_cloud", "nan", "run_missing", "run_garbage"])
def test_bad_input_is_one_line_exit_2_and_writes_nothing(tmp_path, capsys, case):
    good = tmp_path / "good.obj"
    shapes.sphere(subdivisions=1).export(good)
    mesh, extra = good, []
    if case == "no_faces":
        mesh = _write(tmp_path / "nofaces.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    elif case == "point_cloud":
        mesh = tmp_path / "cloud.ply"
        trimesh.PointCloud(np.random.default_rng(0).normal(size=(40, 3))).export(mesh)
    elif case == "nan":
        mesh = _write(tmp_path / "nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\n")
    elif case == "run_missing":
        extra = ["--run", str(tmp_path / "no_such_run")]
    else:
        run = tmp_path / "garbage_run"
        run.mkdir()
        _write(run / "charts.npz", "not a zip file")
        extra = ["--run", str(run)]
    out = tmp_path / "out"
    assert main(["unwrap", str(mesh), "-o", str(out), *extra, *SMALL]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("mna unwrap: error:") and len(err.splitlines()) == 1
    if case == "point_cloud":
        assert "no triangle faces (a point cloud of 40 points: `mna fit` reconstructs it)" in err
    assert not out.exists()


def test_unwrap_fits_when_no_run_is_given(tmp_path):
    """The fit path: a tiny fit of a sphere into OUT (same run-folder contract as `mna fit`)."""
    mesh = tmp_path / "sphere.obj"
    shapes.sphere(subdivisions=2).export(mesh)
    out = tmp_path / "out"
    rc = main(["unwrap", str(mesh), "-o", str(out), "--preset", "tiny", "--steps", "30", "--charts", "2",
               "--no-progress", *SMALL])
    assert rc == 0
    for name in ("config.yaml", "checkpoint.pt", "charts.npz", "metrics.json", "mesh.obj", "mesh.glb", "unwrap.json"):
        assert (out / name).is_file(), name
    info = json.loads((out / "unwrap.json").read_text())
    assert info["fit"] == "fitted" and info["fit_steps"] == 30 and info["charts"] == 2
    back = read_back(out / "mesh.obj")
    loaded = trimesh.load(mesh, process=False, maintain_order=True)
    np.testing.assert_array_equal(back.faces.shape, loaded.faces.shape)
    np.testing.assert_allclose(back.vertices[back.faces], loaded.vertices[loaded.faces], atol=1e-6)
    assert info["uv_metrics"]["flipped_faces"] == 0 and info["uv_metrics"]["uv_overlap_percent"] == 0.0


def test_unwrap_fits_fewer_steps_than_a_reconstruction_unless_given_a_budget():
    """Without ``--steps`` or ``--time-budget`` the unwrap's fit runs ``UNWRAP_FIT_STEPS``
    steps (fewer than the ``fast`` preset's own), or the preset's own where those are fewer
    (``tiny``); a given budget is kept as given. It leaves out L_surf, which the ``fast`` preset's own
    fit has, and the charts' input encoding, which the ``detail`` preset's has, and exclusive labels."""
    import argparse

    from mna.commands.unwrap import UNWRAP_FIT_STEPS, fit_config, register
    from mna.config import preset

    parser = argparse.ArgumentParser()
    register(parser.add_subparsers())

    def config(*extra):
        return fit_config(parser.parse_args(["unwrap", "m.ply", "-o", "out", *extra]))

    assert UNWRAP_FIT_STEPS < preset("fast").steps
    fast = config()
    assert (fast.preset, fast.steps, fast.time_budget) == ("fast", UNWRAP_FIT_STEPS, None)
    assert fast.loss.w_surface == 0.0 < preset("fast").loss.w_surface
    assert config("--preset", "detail").model.chart_octaves == 0 < preset("detail").model.chart_octaves
    assert config("--preset", "detail").late_w_dist == 0.0 < preset("detail").late_w_dist
    assert not config("--preset", "detail").exclusive_labels and preset("detail").exclusive_labels
    assert fast.loss.w_orient == preset("fast").loss.w_orient > 0  # the rest of the preset is kept
    assert config("--preset", "tiny").steps == preset("tiny").steps < UNWRAP_FIT_STEPS
    assert config("--steps", "4321").steps == 4321
    assert config("--preset", "detail", "--steps", "4321").model.chart_octaves == 0  # however long the fit
    timed = config("--time-budget", "90")
    assert timed.time_budget == 90.0


def test_unwrap_refuses_a_non_empty_out_without_overwrite(tmp_path, capsys):
    """The fit path follows `mna fit`'s run-folder rule (refuse a non-empty OUT; --overwrite)."""
    mesh = tmp_path / "sphere.obj"
    shapes.sphere(subdivisions=1).export(mesh)
    out = tmp_path / "out"
    out.mkdir()
    (out / "config.yaml").write_text("input: elsewhere.obj\n")
    args = ["unwrap", str(mesh), "-o", str(out), "--preset", "tiny", "--steps", "10", "--no-progress", *SMALL]
    assert main(args) == 2
    assert "not empty" in capsys.readouterr().err
    assert main([*args, "--overwrite"]) == 0 and (out / "unwrap.json").is_file()


def test_unwrap_with_run_follows_the_run_folder_rule(tmp_path, capsys):
    """With --run, OUT is prepared like every run folder: an earlier unwrap there (and what
    `mna compare`/`render` added to it) is refused without --overwrite and removed with it;
    files mna does not write are never deleted; unwrapping into the fit's own folder keeps
    the fit."""
    run = write_sphere_run(tmp_path / "run", G=32)
    mesh = str(run / "input.ply")
    out = tmp_path / "out"
    args = ["unwrap", mesh, "-o", str(out), "--run", str(run), "--no-progress", *SMALL]
    assert main(args) == 0
    (out / "compare.md").write_text("an earlier comparison\n")
    (out / "renders").mkdir()
    capsys.readouterr()
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert "not empty" in err and "--overwrite" in err and len(err.splitlines()) == 1
    assert main([*args, "--overwrite"]) == 0
    assert (out / "unwrap.json").is_file() and not (out / "compare.md").exists() and not (out / "renders").exists()
    (out / "notes.txt").write_text("mine\n")
    assert main([*args, "--overwrite"]) == 2 and (out / "notes.txt").is_file()
    assert "does not write" in capsys.readouterr().err
    # into the fit's own folder: the fit's files are not counted, and stay
    fit_files = sorted(p.name for p in run.iterdir())
    assert main(["unwrap", mesh, "-o", str(run), "--run", str(run), "--no-progress", *SMALL]) == 0
    assert set(fit_files) <= {p.name for p in run.iterdir()} and (run / "unwrap.json").is_file()


def test_unwrap_a_low_poly_box(tmp_path):
    # 8 vertices and 12 faces, a game asset's block-out: the fit samples its faces
    box = trimesh.creation.box(extents=[1.0, 2.0, 3.0])
    box.export(tmp_path / "box.obj")
    out = tmp_path / "out"
    assert main(["unwrap", str(tmp_path / "box.obj"), "-o", str(out), "--steps", "60", "--no-progress", *SMALL]) == 0
    back = read_back(out / "mesh.glb")
    assert back.faces.shape == (12, 3)
    np.testing.assert_allclose(back.vertices[back.faces], box.vertices[box.faces], atol=1e-6)
    m = json.loads((out / "unwrap.json").read_text())["uv_metrics"]
    assert m["flipped_faces"] == 0 and m["uv_overlap_percent"] == 0.0
    assert m["distortion_metric"] < 0.15  # flat faces: each island folds out flat


def test_a_run_that_does_not_reach_the_mesh_is_reported(tmp_path, capsys):
    """--run with charts of the same sphere moved away (another place, as a run fitted in
    other units would be): every face takes the fallback, the unwrap still writes valid UVs,
    and one warning line says so; the run's own mesh gets no warning."""
    run = write_sphere_run(tmp_path / "run", G=32)
    mesh = trimesh.load(run / "input.ply", process=False)
    moved = mesh.copy()
    moved.apply_translation([40.0, 0.0, 0.0])  # 20 radii away (the sphere's radius is 2)
    moved.export(tmp_path / "moved.ply")
    args = ["--run", str(run), "--no-progress", *SMALL]
    assert main(["unwrap", str(run / "input.ply"), "-o", str(tmp_path / "own"), *args]) == 0
    own = capsys.readouterr()
    assert "warning" not in own.err
    assert "replaced" not in own.out  # an input without texture coordinates: nothing said of them
    assert main(["unwrap", str(tmp_path / "moved.ply"), "-o", str(tmp_path / "out"), *args]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "warning" in err[0] and "reach only 0 %" in err[0]
    doc = json.loads((tmp_path / "out" / "unwrap.json").read_text())
    assert doc["assignment"]["fallback_area_fraction"] == pytest.approx(1.0)
    assert doc["uv_metrics"]["flipped_faces"] == 0 and doc["uv_metrics"]["uv_overlap_percent"] == 0.0


@pytest.mark.parametrize("kind", ["obj", "glb_scene"])
def test_texture_coordinates_the_input_carried_are_replaced_and_said_so(tmp_path, capsys, kind):
    """An OBJ with ``vt`` lines, and a glTF scene where only one of two meshes carries UVs
    (read as one mesh, trimesh drops them): unwrap.json and the summary say they were replaced."""
    run = write_sphere_run(tmp_path / "run", G=32)
    sphere = trimesh.load(run / "input.ply", process=False)
    rng = np.random.default_rng(0)
    if kind == "obj":
        textured = trimesh.Trimesh(sphere.vertices, sphere.faces, process=False,
                                   visual=trimesh.visual.TextureVisuals(uv=rng.random((len(sphere.vertices), 2))))
        path = tmp_path / "textured.obj"
        textured.export(path)
    else:
        top = sphere.triangles_center[:, 2] > sphere.centroid[2]
        scene = trimesh.Scene()
        for keep, uv in ((top, True), (~top, False)):
            part = sphere.submesh([np.flatnonzero(keep)], append=True)
            if uv:
                part.visual = trimesh.visual.TextureVisuals(uv=rng.random((len(part.vertices), 2)))
            scene.add_geometry(part)
        path = tmp_path / "scene.glb"
        scene.export(path)
    assert main(["unwrap", str(path), "-o", str(tmp_path / "out"), "--run", str(run), "--no-progress", *SMALL]) == 0
    assert "were replaced" in capsys.readouterr().out
    doc = json.loads((tmp_path / "out" / "unwrap.json").read_text())
    assert doc["input_uv_replaced"] is True
    assert doc["uv_metrics"]["flipped_faces"] == 0 and doc["uv_metrics"]["uv_overlap_percent"] == 0.0
    back = read_back(tmp_path / "out" / "mesh.glb")
    assert len(back.faces) == len(sphere.faces)



def test_faces_wound_against_their_neighbours_are_written_wound_like_them_and_said_so(tmp_path, capsys):
    """The sphere with a fifth of its faces' winding reversed: the summary says how many, and
    mesh.obj and mesh.glb read back with every face wound like its neighbours (the GLB passes
    the validator), no face flipped or mirrored; an input wound consistently says nothing."""
    run = write_sphere_run(tmp_path / "run", G=32)
    sphere = trimesh.load(run / "input.ply", process=False)
    faces = np.asarray(sphere.faces).copy()
    flip = np.random.default_rng(1).random(len(faces)) < 0.2
    faces[flip] = faces[flip][:, ::-1]
    trimesh.Trimesh(sphere.vertices, faces, process=False).export(tmp_path / "scrambled.ply")
    args = ["--run", str(run), "--no-progress", *SMALL]
    assert main(["unwrap", str(tmp_path / "scrambled.ply"), "-o", str(tmp_path / "out"), *args]) == 0
    assert f"{flip.sum()} of scrambled.ply's faces were wound against their neighbours" in capsys.readouterr().out
    for name in ("mesh.obj", "mesh.glb"):
        back = read_back(tmp_path / "out" / name)
        assert trimesh.Trimesh(back.vertices, back.faces).is_winding_consistent
        m = measure(back).summary
        assert m["flipped_faces"] == 0 and m["mirrored_area_percent"] == 0.0
    assert_glb_validates(tmp_path / "out" / "mesh.glb")
    assert main(["unwrap", str(run / "input.ply"), "-o", str(tmp_path / "own"), *args]) == 0
    assert "wound against" not in capsys.readouterr().out


def test_bake_reads_each_face_its_own_colour_on_a_double_sided_input(tmp_path):
    """A double-sided sphere whose outside is red and whose inside is blue (each face beside
    a copy wound the other way, on vertex copies of their own): `--texture bake` writes each
    face the colour of its own side. The output's faces are the input's, so every texel reads
    its own face; the closest point on the input is a tie between the two sides."""
    run = write_sphere_run(tmp_path / "run", G=32, colored_input=False)
    sphere = trimesh.load(run / "input.ply", process=False)
    v, f = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    n = len(v)
    colours = np.repeat([[230, 20, 20, 255], [20, 20, 230, 255]], n, axis=0).astype(np.uint8)
    both = trimesh.Trimesh(np.vstack([v, v]), np.vstack([f, f[:, ::-1] + n]), vertex_colors=colours, process=False)
    both.export(tmp_path / "two_sided.ply")
    out = tmp_path / "out"
    assert main(["unwrap", str(tmp_path / "two_sided.ply"), "-o", str(out), "--run", str(run), "--texture", "bake",
                 "--no-progress", *SMALL]) == 0
    back = read_back(out / "mesh.obj")
    np.testing.assert_allclose(back.vertices[back.faces], both.vertices[both.faces], atol=1e-6)
    img = read_image(out / "mesh_texture.png")
    rgb = sample_bilinear(img, back.uv[back.faces].mean(1))
    want = np.repeat([[230, 20, 20], [20, 20, 230]], len(f), axis=0) / 255
    np.testing.assert_allclose(rgb, want, atol=2 / 255)


def test_same_triangles_finds_each_face_among_regrouped_and_turned_source_faces():
    """The bake's face match: the unwrap's faces against a source read in another order (a
    reader that regroups faces by material, its corners rotated), a face turned (corners 2
    and 3 swapped, as the unwrap writes a face wound against its neighbours), and a face the
    source does not hold (-1: the bake projects it)."""
    rng = np.random.default_rng(0)
    v = rng.random((60, 3)) * 40.0 - 7.0
    f = np.array([rng.choice(60, 3, replace=False) for _ in range(90)])
    order = rng.permutation(90)
    src_f = f[order].copy()
    src_f[::3] = np.roll(src_f[::3], 1, axis=1)
    out_f = f.copy()
    out_f[5] = out_f[5][[0, 2, 1]]
    out_v = np.vstack([v, [[100.0, 100.0, 100.0]]])
    out_f[7, 0] = 60  # a corner the source does not have
    match, perm = same_triangles(out_v, out_f, v, src_f)
    want = np.argsort(order)
    want[7] = -1
    np.testing.assert_array_equal(match, want)
    ok = match >= 0
    np.testing.assert_array_equal(src_f[match[ok]][np.arange(ok.sum())[:, None], perm[ok]], out_f[ok])


def test_faces_written_twice_share_their_originals_uvs_and_it_is_said(tmp_path, capsys):
    """The sphere with 30 of its faces written again (corners rotated): the summary says how
    many; mesh.obj and mesh.glb keep every face, each copy on its original's UV triangle, and
    measure alike (no overlap: an exact repeat counts once); the GLB passes the validator."""
    run = write_sphere_run(tmp_path / "run", G=32)
    sphere = trimesh.load(run / "input.ply", process=False)
    faces = np.asarray(sphere.faces)
    pick = np.random.default_rng(2).choice(len(faces), 30, replace=False)
    both = np.vstack([faces, np.roll(faces[pick], 1, axis=1)])
    trimesh.Trimesh(sphere.vertices, both, process=False).export(tmp_path / "twice.ply")
    args = ["--run", str(run), "--no-progress", *SMALL]
    assert main(["unwrap", str(tmp_path / "twice.ply"), "-o", str(tmp_path / "out"), *args]) == 0
    assert "30 of twice.ply's faces repeat an earlier face" in capsys.readouterr().out
    sums = []
    for name in ("mesh.obj", "mesh.glb"):
        back = read_back(tmp_path / "out" / name)
        assert len(back.faces) == len(both)
        for k, o in enumerate(pick):  # copy k: its original's UV at the corner on the same point
            at = {tuple(np.round(back.vertices[v], 6)): back.uv[v] for v in back.faces[o]}
            for v in back.faces[len(faces) + k]:
                np.testing.assert_allclose(back.uv[v], at[tuple(np.round(back.vertices[v], 6))], atol=1e-6)
        sums.append(measure(back).summary)
    assert sums[0]["uv_overlap_percent"] == 0.0 and sums[0]["charts"] == sums[1]["charts"]
    assert sums[0]["seam_length"] == pytest.approx(sums[1]["seam_length"], rel=1e-6)
    assert_glb_validates(tmp_path / "out" / "mesh.glb")


def test_an_obj_whose_faces_change_material_keeps_its_face_order(tmp_path, capsys):
    """The sphere as an OBJ whose faces switch between two materials every ten faces (no
    ``vt``): trimesh groups an OBJ's faces by material, so the unwrap's face ``i`` was another
    face of the file. Now mesh.obj and mesh.glb hold the file's faces in its order, and no
    texture coordinates are said to be replaced (the file has none)."""
    run = write_sphere_run(tmp_path / "run", G=32)
    sphere = trimesh.load(run / "input.ply", process=False)
    v, f = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    lines = ["mtllib two.mtl"] + [f"v {a:.9g} {b:.9g} {c:.9g}" for a, b, c in v]
    for i, t in enumerate(f):
        if i % 10 == 0:
            lines.append("usemtl " + ("red" if i // 10 % 2 == 0 else "blue"))
        lines.append("f " + " ".join(str(k + 1) for k in t))
    (tmp_path / "two.obj").write_text("\n".join(lines) + "\n")
    (tmp_path / "two.mtl").write_text("newmtl red\nKd 1 0 0\nnewmtl blue\nKd 0 0 1\n")
    args = ["--run", str(run), "--no-progress", *SMALL]
    assert main(["unwrap", str(tmp_path / "two.obj"), "-o", str(tmp_path / "out"), *args]) == 0
    assert "were replaced" not in capsys.readouterr().out
    for name in ("mesh.obj", "mesh.glb"):
        back = read_back(tmp_path / "out" / name)
        np.testing.assert_allclose(back.vertices[back.faces], v[f], atol=1e-6)
