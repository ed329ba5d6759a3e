"""``mna export``, ``mna uv``, ``mna uv-metrics``, ``mna compare``: outputs and every bad input."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from texture_helpers import CENTER, color_function

from mna import shapes
from mna.cli import main
from texture.export import read_back
from texture.textures import read_image, sample_bilinear


def _one_error_line(capsys, code):
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and "error" in err[0]
    return err[0]


def _files(folder: Path) -> set[str]:
    return {p.name for p in folder.iterdir()}


@pytest.mark.parametrize("max_islands", [0, 6])
def test_export_writes_textured_assets(fresh_sphere_run, capsys, max_islands):
    run = fresh_sphere_run
    before = _files(run)
    assert main(["export", str(run), "--size", "256", "--padding", "2", "--max-islands", str(max_islands)]) == 0
    assert _files(run) - before == {"mesh.obj", "mesh.mtl", "mesh_texture.png", "mesh.glb", "atlas.json"}
    info = json.loads((run / "atlas.json").read_text())
    a, m = info["atlas"], info["uv_metrics"]
    # two caps trimmed at the equator; by default the packing search halves them to pack
    # tighter (two discs leave a square's corners empty), each halving one more island
    islands = 2 + a["split_islands"]
    assert (a["split_islands"] == 0) if max_islands == 0 else (a["split_islands"] >= 1)
    assert a["islands"] == islands and m["charts"] == islands
    assert a["doubly_covered_percent"] <= 1.0 and a["fscore_drop"] <= 0.5
    assert m["flipped_faces"] == 0 and m["uv_overlap_percent"] == 0.0
    assert m["distortion_metric"] < 0.5
    # seam = the equator (length 2 pi on the unit sphere) + the halvings' cuts (unit frame) / sqrt(4 pi)
    seam = 2 * np.pi + sum(h["cut_length"] for h in a["halvings"])
    assert m["seam_length"] == pytest.approx(seam / np.sqrt(4 * np.pi), rel=0.03)
    back = read_back(run / "mesh.obj")
    assert back.uv.min() >= 0 and back.uv.max() <= 1
    assert np.linalg.norm(back.vertices - CENTER, axis=1).mean() == pytest.approx(2.0, rel=1e-3)  # input frame
    assert f"atlas: {islands} islands" in capsys.readouterr().out


def test_export_bake_reproduces_input_colours(fresh_sphere_run):
    run = fresh_sphere_run
    assert main(["export", str(run), "--texture", "bake", "--size", "256", "--padding", "4"]) == 0
    mesh = read_back(run / "mesh.obj")
    img = read_image(run / "mesh_texture.png")
    centre = mesh.vertices[mesh.faces].mean(1)
    want = color_function((centre - CENTER) / 2.0)[:, :3] / 255
    err = np.abs(sample_bilinear(img, mesh.uv[mesh.faces].mean(1)) - want)
    assert err.mean() < 0.01 and np.percentile(err, 99) < 0.05


def test_uv_and_uv_metrics(tmp_path, capsys):
    src = tmp_path / "sphere.obj"
    shapes.sphere(subdivisions=3).export(src)
    out = tmp_path / "out"
    assert main(["uv", str(src), "-o", str(out), "--resolution", "256", "--padding", "2", "--max-cost", "4"]) == 0
    assert _files(out) == {"mesh.obj", "mesh.mtl", "mesh_texture.png", "mesh.glb", "metrics.json"}
    m = json.loads((out / "metrics.json").read_text())
    assert m["uv_metrics"]["flipped_faces"] == 0 and m["options"]["max_cost"] == 4.0
    assert m["uv_metrics"]["charts"] == m["xatlas_charts"]
    capsys.readouterr()
    assert main(["uv-metrics", str(out / "mesh.obj"), "--reference", str(src), "-o", str(tmp_path / "m.json")]) == 0
    again = json.loads((tmp_path / "m.json").read_text())
    assert again["charts"] == m["uv_metrics"]["charts"]
    # the run-folder rule: a second run into OUT is refused, --overwrite replaces what mna wrote
    (out / "renders").mkdir()
    args = ["uv", str(src), "-o", str(out), "--resolution", "256", "--padding", "2"]
    assert main(args) == 2 and "not empty" in capsys.readouterr().err
    assert main([*args, "--overwrite"]) == 0
    assert _files(out) == {"mesh.obj", "mesh.mtl", "mesh_texture.png", "mesh.glb", "metrics.json"}
    assert json.loads((out / "metrics.json").read_text())["options"]["max_cost"] == 2.0
    assert again["distortion_metric"] == pytest.approx(m["uv_metrics"]["distortion_metric"], abs=1e-5)


def test_compare_tabulates_every_method(tmp_path, monkeypatch):
    from texture_helpers import write_sphere_run

    import texture.compare as C

    monkeypatch.setattr(C, "SWEEP_MAX_COST", (1.0, 8.0))
    monkeypatch.setattr(C, "SWEEP_MAX_ITERATIONS", (1,))
    run = write_sphere_run(tmp_path / "run", G=40)
    assert main(["compare", str(run), "--size", "256", "--padding", "2"]) == 0
    res = json.loads((run / "compare.json").read_text())
    names = [r["method"] for r in res["methods"]]
    assert names == ["mna", "xatlas", "xatlas_input"]
    assert len(res["sweep"]) == 2
    for sub in ("xatlas", "xatlas_input"):
        assert {"mesh.obj", "mesh.glb", "mesh_texture.png", "metrics.json"} <= _files(run / sub)
    ours, xa = res["methods"][0], res["methods"][1]
    assert ours["faces"] == xa["faces"]  # the same reconstructed mesh
    atlas = json.loads((run / "atlas.json").read_text())["atlas"]
    # the two caps, halved by the packing search to pack tighter
    assert ours["charts"] == 2 + atlas["split_islands"] > 2 and xa["charts"] >= 2
    assert ours["seam_length"] <= xa["seam_length"] + 1e-9  # xatlas cannot join our separate islands
    md = (run / "compare.md").read_text()
    assert "| mna | reconstruction |" in md and "xatlas sweep" in md
    assert md.count("Time: the UV method alone (ours: trim, orient, relax, pack).") == 1
    # uv-metrics on the run's own files reports what compare reports (one reference, one frame)
    for method, path in (("mna", run / "mesh.obj"), ("xatlas", run / "xatlas" / "mesh.glb")):
        assert main(["uv-metrics", str(path), "-o", str(tmp_path / f"{method}.json")]) == 0
        alone = json.loads((tmp_path / f"{method}.json").read_text())
        row = next(r for r in res["methods"] if r["method"] == method)
        for key in ("charts", "seam_length", "surface_area", "distortion_metric", "folded_area_percent"):
            assert alone[key] == pytest.approx(row[key], rel=1e-6, abs=1e-9), (method, key)


def test_uv_metrics_writes_strict_json(tmp_path, capsys):
    """UVs beyond [0, 1]^2 have no utilisation (NaN); JSON has no NaN: null, which strict parsers read."""
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.0]])
    F = np.array([[0, 1, 2], [1, 3, 2]])
    uv = np.array([[0, 0], [1, 0], [0, 1], [2, 2.0]])
    path = tmp_path / "m.obj"
    from mnacore.uvmesh import make_uv_mesh
    from texture.export import export_textured
    from texture.textures import checker_image

    export_textured(tmp_path, make_uv_mesh(V, F, uv), checker_image(4.0, 64), stem="m")
    assert main(["uv-metrics", str(path), "-o", str(tmp_path / "out.json")]) == 0
    text = (tmp_path / "out.json").read_text()
    assert "NaN" not in text and "Infinity" not in text and json.loads(text)["utilization"] is None
    json.loads(text, parse_constant=lambda c: pytest.fail(f"non-standard JSON constant {c}"))
    assert main(["uv-metrics", str(path), "-o", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is a folder" in err and "/." not in err


# ---- bad input: one line, exit 2, nothing written --------------------------------------------


@pytest.mark.parametrize("size", ["0", "-4", "abc", "1.5"])
def test_export_bad_size(fresh_sphere_run, capsys, size):
    before = _files(fresh_sphere_run)
    code = main(["export", str(fresh_sphere_run), f"--size={size}"])
    assert "positive integer" in _one_error_line(capsys, code)
    assert _files(fresh_sphere_run) == before


@pytest.mark.parametrize("relax", ["-1", "abc", "2.5"])
def test_export_bad_relax(fresh_sphere_run, capsys, relax):
    before = _files(fresh_sphere_run)
    code = main(["export", str(fresh_sphere_run), f"--relax={relax}"])
    assert "--relax must be an integer >= 0" in _one_error_line(capsys, code)
    assert _files(fresh_sphere_run) == before


def test_export_without_relax_keeps_chart_uvs(fresh_sphere_run):
    """--relax 0: the packed UVs are the charts' own up to one scale; the default relaxes them."""
    run = fresh_sphere_run
    assert main(["export", str(run), "--size", "256", "--padding", "2", "--max-islands", "0", "--relax", "0"]) == 0
    raw = json.loads((run / "atlas.json").read_text())
    assert raw["relax"] == 0 and "relax_energy_before" not in raw["atlas"]
    assert main(["export", str(run), "--size", "256", "--padding", "2", "--max-islands", "0"]) == 0
    relaxed = json.loads((run / "atlas.json").read_text())
    assert relaxed["relax"] == 8 and relaxed["atlas"]["relax_iterations_max"] >= 1
    assert relaxed["uv_metrics"]["distortion_metric"] < raw["uv_metrics"]["distortion_metric"]
    assert relaxed["uv_metrics"]["flipped_faces"] == 0 and relaxed["uv_metrics"]["uv_overlap_percent"] == 0.0


def test_export_missing_charts(tmp_path, capsys):
    (tmp_path / "run").mkdir()
    code = main(["export", str(tmp_path / "run")])
    assert "charts file not found" in _one_error_line(capsys, code)
    assert _files(tmp_path / "run") == set()


def test_export_nan_charts(fresh_sphere_run, capsys):
    run = fresh_sphere_run
    with np.load(run / "charts.npz") as z:
        data = dict(z)
    data["xyz"][0, 3, 3, 0] = np.nan
    np.savez(run / "charts.npz", **data)
    before = _files(run)
    code = main(["export", str(run)])
    assert "NaN" in _one_error_line(capsys, code)
    assert _files(run) == before


def test_export_bake_without_colours(fresh_sphere_run, capsys):
    run = fresh_sphere_run
    shapes.sphere(subdivisions=2).export(run / "input.ply")  # no colours
    before = _files(run)
    code = main(["export", str(run), "--texture", "bake", "--size", "64"])
    assert "neither vertex colours nor a texture" in _one_error_line(capsys, code)
    assert _files(run) == before


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


QUAD = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"


def test_uv_metrics_mesh_without_uvs(tmp_path, capsys):
    mesh = _write(tmp_path / "plain.obj", QUAD + "f 1 2 3\nf 1 3 4\n")
    code = main(["uv-metrics", str(mesh)])
    assert "has no UVs" in _one_error_line(capsys, code)


def test_uv_metrics_nan_uvs(tmp_path, capsys):
    mesh = _write(tmp_path / "nan.obj", QUAD + "vt 0 0\nvt 1 0\nvt nan 1\nvt 0 1\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    code = main(["uv-metrics", str(mesh), "-o", str(tmp_path / "m.json")])
    assert "NaN" in _one_error_line(capsys, code)
    assert not (tmp_path / "m.json").exists()


@pytest.mark.parametrize("faces, message", [
    ("f 1 2 3\nf 2 1 4\nf 1 2 5\n", "non-manifold"),  # edge 1-2 has three faces
    ("f 1 2 3\nf 1 3 4\nf 1 2 2\n", "degenerate"),
    ("f 1 2 3\nf 1 3 4\nv 2 0 0\nf 2 5 2\n", "degenerate"),
])
def test_uv_rejects_bad_meshes(tmp_path, capsys, faces, message):
    mesh = _write(tmp_path / "bad.obj", QUAD + "v 0.5 0.5 1\n" + faces)
    out = tmp_path / "out"
    code = main(["uv", str(mesh), "-o", str(out)])
    assert message in _one_error_line(capsys, code)
    assert not out.exists() or _files(out) == set()


def test_uv_bake_with_unreadable_texture(tmp_path, capsys):
    (tmp_path / "tex.png").write_bytes(b"garbage, not an image")
    _write(tmp_path / "m.mtl", "newmtl a\nmap_Kd tex.png\n")
    mesh = _write(tmp_path / "m.obj", "mtllib m.mtl\n" + QUAD + "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl a\n"
                  "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    out = tmp_path / "out"
    code = main(["uv", str(mesh), "-o", str(out), "--texture", "bake", "--resolution", "64"])
    _one_error_line(capsys, code)
    assert not out.exists() or _files(out) == set()


def test_uv_missing_and_bad_options(tmp_path, capsys):
    code = main(["uv", str(tmp_path / "nope.obj"), "-o", str(tmp_path / "o")])
    assert "not found" in _one_error_line(capsys, code)
    src = tmp_path / "s.obj"
    shapes.sphere(subdivisions=1).export(src)
    code = main(["uv", str(src), "-o", str(tmp_path / "o"), "--max-cost", "-1"])
    assert "--max-cost" in _one_error_line(capsys, code)
    code = main(["uv", str(src), "-o", str(tmp_path / "o"), "--size", "0"])
    assert "positive integer" in _one_error_line(capsys, code)
    assert not (tmp_path / "o").exists()


def test_export_bad_max_islands(fresh_sphere_run, capsys):
    before = _files(fresh_sphere_run)
    code = main(["export", str(fresh_sphere_run), "--max-islands", "-1"])
    assert "--max-islands" in _one_error_line(capsys, code)
    assert _files(fresh_sphere_run) == before


def test_atlas_json_holds_the_config_that_reproduces_the_export(fresh_sphere_run, tmp_path):
    import shutil

    from mnacore.configs import from_dict
    from texture.atlas import AtlasConfig
    from texture.pipeline import export_run
    from texture.relax import RelaxConfig

    assert main(["export", str(fresh_sphere_run), "--size", "256", "--padding", "3", "--max-islands", "3",
                 "--relax", "2"]) == 0
    cfg = json.loads((fresh_sphere_run / "atlas.json").read_text())["config"]
    atlas_cfg = from_dict(cfg["atlas"], AtlasConfig, "atlas.json config.atlas")
    assert atlas_cfg == AtlasConfig(resolution=256, padding=3, max_islands=3, relax=RelaxConfig(iterations=2))
    again = tmp_path / "again"
    shutil.copytree(fresh_sphere_run, again)
    for name in ("mesh.obj", "mesh.glb", "atlas.json"):
        (again / name).unlink()
    export_run(again, texture=cfg["texture"], size=cfg["size"], padding=cfg["padding"],
               square_size=cfg["square_size"], max_islands=atlas_cfg.max_islands, relax=atlas_cfg.relax.iterations)
    assert (again / "mesh.obj").read_bytes() == (fresh_sphere_run / "mesh.obj").read_bytes()


def test_export_config_repeats_an_export(fresh_sphere_run, tmp_path, capsys):
    """`mna export RUN --config atlas.json` repeats the export that wrote it, options included;
    a config beside other options, or with an unknown key or a bad value, is refused in one
    line and nothing is written."""
    import shutil

    assert main(["export", str(fresh_sphere_run), "--size", "256", "--padding", "3", "--max-islands", "3",
                 "--relax", "2", "--square-size", "0.2", "--texture", "uvgrid"]) == 0
    saved = tmp_path / "first_atlas.json"
    shutil.copy(fresh_sphere_run / "atlas.json", saved)
    again = tmp_path / "again"
    shutil.copytree(fresh_sphere_run, again)
    for name in ("mesh.obj", "mesh.glb", "mesh_texture.png", "atlas.json"):
        (again / name).unlink()
    assert main(["export", str(again), "--config", str(saved)]) == 0
    for name in ("mesh.obj", "mesh_texture.png"):
        assert (again / name).read_bytes() == (fresh_sphere_run / name).read_bytes(), name
    first, second = (json.loads(p.read_text()) for p in (saved, again / "atlas.json"))
    assert second["config"] == first["config"] and second["size"] == 256 and second["padding"] == 3
    capsys.readouterr()
    before = _files(again)
    assert main(["export", str(again), "--config", str(saved), "--size", "512"]) == 2
    assert "drop --size" in _one_error_line(capsys, 2)
    atlas_bytes = (again / "atlas.json").read_bytes()
    bad = dict(first["config"], atlas=dict(first["config"]["atlas"], max_islandz=3))
    (tmp_path / "bad.json").write_text(json.dumps(bad))
    assert main(["export", str(again), "--config", str(tmp_path / "bad.json")]) == 2
    assert "max_islandz" in capsys.readouterr().err
    (tmp_path / "neg.yaml").write_text("padding: -1\n")
    assert main(["export", str(again), "--config", str(tmp_path / "neg.yaml")]) == 2
    assert "--padding must be a non-negative integer" in capsys.readouterr().err
    assert _files(again) == before and (again / "atlas.json").read_bytes() == atlas_bytes
