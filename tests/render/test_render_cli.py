"""``mna render``, ``mna render-mesh``, ``mna figure`` and the report: outputs, comparability, bad input."""
from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from mna.cli import main
from render.images import read_image

FAST = ["--spp", "2", "--res", "24", "--no-progress"]


def _sensor_matrix(xml_path) -> np.ndarray:
    root = ET.parse(xml_path).getroot()
    return np.array([float(x) for x in root.find("sensor/transform/matrix").get("value").split()])


@pytest.fixture(scope="module")
def rendered_run(uv_run, fast_variant):
    code = main(["render", str(uv_run), "--views", "front,three_quarter", "--heatmap", "metric,charts",
                 "--variant", fast_variant, *FAST])
    assert code == 0
    return uv_run


def test_render_run_writes_both_methods_comparably(rendered_run):
    out = rendered_run / "renders"
    summary = json.loads((out / "render.json").read_text())
    recs = {m: json.loads((out / m / "render.json").read_text()) for m in ("mna", "xatlas")}
    assert summary["variant"] in ("scalar_rgb", "llvm_ad_rgb", "cuda_ad_rgb")
    for m, rec in recs.items():
        assert rec["variant"] == summary["variant"]
        for view in ("front", "three_quarter"):
            for key in (view, f"heat_metric_{view}", f"heat_charts_{view}"):
                png, exr = read_image(out / m / f"{key}.png"), read_image(out / m / f"{key}.exr")
                assert png.shape == (24, 24, 3) and exr.shape == (24, 24, 4)
    # identical cameras, checker square size in 3D and heat scale for both methods
    for view in ("front", "three_quarter"):
        np.testing.assert_array_equal(_sensor_matrix(out / "mna" / "scene" / f"{view}.xml"),
                                      _sensor_matrix(out / "xatlas" / "scene" / f"{view}.xml"))
    assert recs["mna"]["checker_square_size"] == recs["xatlas"]["checker_square_size"]
    assert recs["mna"]["heat_ranges"] == recs["xatlas"]["heat_ranges"] == summary["heat_ranges"]
    assert summary["heat_ranges"]["metric"]["vmax"] > 0
    # xatlas and the torus' own UVs differ in UV scale, so the texture frequencies differ
    assert recs["mna"]["checker_squares_per_uv_unit"] != recs["xatlas"]["checker_squares_per_uv_unit"]
    assert (out / "figure.png").is_file() and (out / "figure_heat_metric.png").is_file()
    assert not list(out.rglob(".*"))  # no atomic-write temporaries left


def test_figure_grid_and_pdf(rendered_run, tmp_path, capsys):
    # the layout `mna compare` writes: a list of rows under "methods"
    (rendered_run / "compare.json").write_text(json.dumps(
        {"methods": [{"method": "mna", "charts": 1, "seam_length": 2.5, "distortion_metric": 0.4},
                     {"method": "xatlas", "charts": 7, "seam_length": 4.0, "distortion_metric": 0.02}]}))
    from render.figure import caption

    assert caption(rendered_run, "xatlas") == "islands 7 · seam 4.00 · dist. 0.020"
    out = tmp_path / "fig.png"
    assert main(["figure", str(rendered_run), "-o", str(out), "--pdf", "--image", "heat_metric"]) == 0
    assert "(2 x 2 cells)" in capsys.readouterr().out  # rows mna, xatlas x views front, three_quarter
    img = read_image(out)
    assert min(img.shape[:2]) > 400 and img.shape[0] > img.shape[1]  # 2 x 2 square cells + colour bar below
    assert out.with_suffix(".pdf").read_bytes()[:4] == b"%PDF"
    # several runs: one column per run
    assert main(["figure", str(rendered_run), str(rendered_run), "-o", str(tmp_path / "two.png")]) == 0
    assert "(2 x 2 cells)" in capsys.readouterr().out


def test_report_is_self_contained(rendered_run):
    from render.report import write_report

    (rendered_run / "compare.json").write_text(json.dumps({"methods": [
        {"method": "mna", "mesh": "reconstruction", "faces": 10, "charts": 1, "seam_length": 2.5},
        {"method": "xatlas", "mesh": "reconstruction", "faces": 10, "charts": 7, "seam_length": 4.0}]}))
    (rendered_run / "mesh.glb").write_bytes(b"glTF")
    rep = write_report(rendered_run)
    md, page = rep.markdown.read_text(), rep.html.read_text()
    assert "renders/figure.png" in md and "| xatlas | reconstruction | 10 | 7 | 4.00 |" in md
    assert "[mesh.glb](mesh.glb)" in md
    assert page.count("data:image/png;base64,") == md.count("![")
    assert "<td>xatlas</td>" in page and 'href="mesh.glb"' in page
    assert "src=\"renders/" not in page  # images are inlined, not linked


def test_report_reads_as_a_document_and_escapes_paths(rendered_run, tmp_path):
    """One h1, sections as h2 (compare.md's own h1 is not pasted in), no internal names, and a
    run folder named like a Markdown link to javascript: stays text."""
    import shutil

    from render.report import write_report

    (rendered_run / "compare.md").write_text("# compare: x\n\nsee DESIGN\n")
    evil = tmp_path / "[x](javascript:alert(1))"
    shutil.copytree(rendered_run, evil, ignore=shutil.ignore_patterns("scene"))
    page = write_report(evil).html.read_text()
    assert page.count("<h1>") == 1 and "<h2>" in page
    assert 'href="javascript' not in page.lower() and "javascript:alert(1)" in page  # shown, not live
    for internal in ("DESIGN", "texture.harness", "tr g"):
        assert internal not in page


def test_report_fits_a_1280_px_window(rendered_run, tmp_path):
    """Laid out by headless Chromium at 1280 px: nothing overflows the page sideways."""
    import re
    import shutil
    import subprocess

    from render.report import write_report

    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        pytest.skip("chromium is not installed (make setup installs it where apt-get works)")
    (rendered_run / "compare.json").write_text(json.dumps({"methods": [
        {"method": name, "mesh": "reconstruction", "faces": 123456, "charts": 4592, "seam_length": 1234.5,
         "distortion_metric": 0.1, "distortion_conformal": 0.1, "distortion_area": 0.1,
         "flipped_area_percent": 0.0, "mirrored_area_percent": 28.0, "folded_area_percent": 0.0,
         "orientation_undecided_area_percent": 0.0, "uv_overlap_percent": 0.0, "utilization": 0.6,
         "seconds": 123.4} for name in ("mna", "xatlas", "xatlas_input")]}))
    page = write_report(rendered_run).html.read_text()
    probe = tmp_path / "probe.html"
    # the page's width, the window's, and how far the widest table scrolls inside its box
    probe.write_text(page.replace("</body>", "<script>const t = [...document.querySelectorAll('div.table')]"
                                  ".map(d => d.scrollWidth - d.clientWidth); document.body.setAttribute('data-w', "
                                  "document.documentElement.scrollWidth + 'x' + "
                                  "document.documentElement.clientWidth + 'x' + Math.max(0, ...t))</script></body>"))
    out = subprocess.run([chromium, "--headless", "--no-sandbox", "--disable-gpu", "--window-size=1280,900",
                          "--dump-dom", probe.as_uri()], capture_output=True, text=True, timeout=120).stdout
    scroll, client, table = map(int, re.search(r'data-w="(\d+)x(\d+)x(\d+)"', out).groups())
    assert scroll <= client <= 1280 and table == 0


def test_report_from_a_relative_run_folder(rendered_run, monkeypatch):
    """`mna demo -o demo_run` passes a relative folder: figure paths must not be doubled."""
    from render.report import write_report

    monkeypatch.chdir(rendered_run.parent)
    rep = write_report(rendered_run.name)
    assert "renders/figure.png" in rep.markdown.read_text()
    assert rep.html.read_text().count("data:image/png;base64,") >= 1


def test_render_mesh_cli(uv_run, tmp_path, fast_variant, capsys):
    out = tmp_path / "out"
    code = main(["render-mesh", str(uv_run / "xatlas" / "mesh.obj"), "-o", str(out), "--turntable", "2",
                 "--texture", "uvgrid", "--variant", fast_variant, *FAST])
    assert code == 0
    assert f"Mitsuba variant {fast_variant}" in capsys.readouterr().err
    assert sorted(p.name for p in out.glob("*.png")) == ["turntable_000.png", "turntable_001.png"]
    assert (out / "scene" / "turntable_000.xml").is_file() and (out / "scene" / "texture.png").is_file()


@pytest.mark.parametrize("argv,match", [
    (["--spp", "0"], "--spp"),
    (["--texture", "bake"], "no texture image"),
    (["--preset", "BADPRESET"], "unknown key"),
    (["--views", "diagonal"], "unknown view"),
    (["--variant", "nope_rgb"], "unknown Mitsuba variant"),
])
def test_bad_input_is_one_line_exit_2_nothing_written(uv_run, tmp_path, capsys, argv, match):
    if "BADPRESET" in argv:
        bad = tmp_path / "bad.yaml"
        bad.write_text("views: {front: {azimuth: 0}}\nlights: [{azimuth: 0, wattage: 100}]\n")
        argv = [str(bad) if a == "BADPRESET" else a for a in argv]
    out = tmp_path / "out"
    code = None
    try:
        code = main(["render-mesh", str(uv_run / "mesh.obj"), "-o", str(out), *FAST, *argv])
    except SystemExit as exc:  # argparse's own errors exit from inside parse_args
        code = exc.code
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert match in err and len(err.splitlines()) == 1, err
    assert not out.exists()


def test_mesh_without_uvs_is_a_clear_error(tmp_path, meshes, capsys):
    v, f, _ = meshes.flat_square(n=2)
    mesh = meshes.write_obj(tmp_path / "nouv.obj", v, f)
    assert main(["render-mesh", str(mesh), "-o", str(tmp_path / "out"), *FAST]) == 2
    err = capsys.readouterr().err
    assert "has no UVs" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_missing_inputs(tmp_path, capsys):
    assert main(["render", str(tmp_path / "nope"), *FAST]) == 2
    assert "run folder not found" in capsys.readouterr().err
    (tmp_path / "empty").mkdir()
    assert main(["render", str(tmp_path / "empty"), *FAST]) == 2
    assert "mna export" in capsys.readouterr().err
    assert main(["render-mesh", str(tmp_path / "missing.obj"), "-o", str(tmp_path / "o"), *FAST]) == 2
    assert "mesh not found" in capsys.readouterr().err
    assert main(["figure", str(tmp_path / "empty"), "-o", str(tmp_path / "f.png")]) == 2
    assert "no renders" in capsys.readouterr().err
