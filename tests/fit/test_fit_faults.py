"""Faults and hostile input through the CLI (issue 15, items 9 and 11-17).

Every case asserts the outcome a user sees: the exit code, the one line on stderr (no
traceback), and what is (not) left on disk.
"""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import torch

from mna import config as C
from mna import shapes
from mna.cli import main
from mna.run import fit_run

REPO = Path(__file__).resolve().parents[2]


def _fails(capsys, argv, needle, code=2):
    got = main(argv)
    err = capsys.readouterr().err.strip()
    assert got == code, err
    assert "Traceback" not in err
    assert len(err.splitlines()) == (1 if code == 2 else 2), err
    assert needle.lower() in err.lower(), err
    return err


def _tiny(steps: int = 5) -> C.FitConfig:
    cfg = C.tiny()
    cfg.steps, cfg.device = steps, "cpu"
    return cfg


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory, torus_file) -> Path:
    """A finished 5-step fit; tests copy it before changing it."""
    run = tmp_path_factory.mktemp("faults") / "run"
    fit_run(torus_file, run, _tiny(), progress_bar=False, log=lambda s: None)
    return run


@pytest.fixture
def run_copy(tiny_run, tmp_path) -> Path:
    dst = tmp_path / "run"
    shutil.copytree(tiny_run, dst)
    return dst


def _write_obj(path: Path, vertices: np.ndarray, faces: np.ndarray) -> Path:
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in np.asarray(vertices, np.float64).tolist()]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in np.asarray(faces)]
    path.write_text("\n".join(lines) + "\n")
    return path


# -- item 9: a checkpoint never runs code ------------------------------------------------------
class _Payload:
    """Unpickling this calls ``os.system``: what a crafted checkpoint.pt would do."""

    def __init__(self, marker: Path):
        self.marker = marker

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


def _plant(run: Path, marker: Path) -> None:
    torch.save({"model": _Payload(marker), "step": 1, "normalization": {}}, run / "checkpoint.pt")


@pytest.mark.parametrize("command", ["extract", "resume", "reconstruct", "evaluate"])
def test_crafted_checkpoint_is_refused_without_running(capsys, run_copy, torus_file, tmp_path, command):
    marker = tmp_path / "marker"
    _plant(run_copy, marker)
    argv = {"extract": ["extract", str(run_copy)],
            "resume": ["fit", torus_file, "-o", str(run_copy), "--resume", "--no-progress"],
            "reconstruct": ["reconstruct", str(run_copy / "checkpoint.pt"), torus_file, "-o", str(tmp_path / "r")],
            "evaluate": ["evaluate", str(run_copy / "checkpoint.pt")]}[command]
    _fails(capsys, argv, "refusing to load")
    assert not marker.exists()
    assert not (tmp_path / "r").exists()


def test_checkpoints_hold_plain_data_and_load_weights_only(tiny_run):
    from mna.checkpoint import plain_data_problem

    state = torch.load(tiny_run / "checkpoint.pt", weights_only=True)
    assert plain_data_problem(state) is None
    assert isinstance(state["numpy_rng"]["state"]["state"], int)


# -- item 11: config values validated up front; any exception is one line ------------------
@pytest.mark.parametrize("argv, needle", [
    (["--time-budget", "inf"], "--time-budget must be positive, finite"),
    (["--time-budget", "nan"], "--time-budget must be positive, finite"),
])
def test_non_finite_time_budget(capsys, sphere_file, tmp_path, argv, needle):
    out = tmp_path / "run"
    _fails(capsys, ["fit", sphere_file, "-o", str(out), "--preset", "tiny", *argv], needle)
    assert not out.exists()


@pytest.mark.parametrize("yaml_text, needle", [
    ("checkpoint_every: 0\n", "checkpoint_every must be at least 1"),
    ("log_every: -1\n", "log_every must be at least 1"),
    ("lr: .nan\n", "lr must be a finite number"),
    ("tau: 7\n", "tau must be in (0, 1)"),
    ("threads: -4\n", "--threads must be between 0"),
    ("model:\n  charts: 1000\n", "--charts must be between 1 and 64"),
    ("loss:\n  w_dist: .inf\n", "loss.w_dist must be a finite number"),
    ("- a\n- b\n", "must hold a mapping"),
])
def test_bad_config_values_leave_nothing(capsys, sphere_file, tmp_path, yaml_text, needle):
    cfg, out = tmp_path / "c.yaml", tmp_path / "run"
    cfg.write_text("preset: tiny\n" + yaml_text if not yaml_text.startswith("-") else yaml_text)
    _fails(capsys, ["fit", sphere_file, "-o", str(out), "--config", str(cfg)], needle)
    assert not out.exists()


def test_unexpected_exception_is_two_lines_exit_1(capsys, monkeypatch, sphere_file, tmp_path):
    import mna.commands.fit as fit_cmd

    def broken(args):
        return 1 // 0

    monkeypatch.setattr(fit_cmd, "run_fit", broken)
    argv = ["fit", sphere_file, "-o", str(tmp_path / "run")]
    from mna.cli import BUG_LINE

    err = _fails(capsys, argv, "ZeroDivisionError", code=1)
    assert err.splitlines()[1] == BUG_LINE
    monkeypatch.setenv("MNA_DEBUG", "1")
    with pytest.raises(ZeroDivisionError):
        main(argv)


# -- item 12: one run per folder ---------------------------------------------------------------
def _old_outputs(run: Path) -> None:
    (run / "mesh.obj").write_text("old\n")
    (run / "renders").mkdir()
    (run / "renders" / "front.png").write_bytes(b"old")
    (run / "report.html").write_text("old")


def test_fit_into_a_non_empty_run_is_refused(capsys, run_copy, torus_file):
    _old_outputs(run_copy)
    before = sorted(p.name for p in run_copy.iterdir())
    mtime = (run_copy / "checkpoint.pt").stat().st_mtime_ns
    _fails(capsys, ["fit", torus_file, "-o", str(run_copy), "--preset", "tiny", "--steps", "3"],
           "not empty")
    assert sorted(p.name for p in run_copy.iterdir()) == before
    assert (run_copy / "checkpoint.pt").stat().st_mtime_ns == mtime


def test_overwrite_removes_what_the_new_run_does_not_write(capsys, run_copy, torus_file):
    _old_outputs(run_copy)
    code = main(["fit", torus_file, "-o", str(run_copy), "--preset", "tiny", "--steps", "3", "--no-progress",
                 "--overwrite"])
    assert code == 0, capsys.readouterr().err
    assert sorted(p.name for p in run_copy.iterdir()) == [
        "charts.npz", "charts.ply", "checkpoint.pt", "config.yaml", "metrics.json", "points.ply"]


def test_overwrite_never_deletes_foreign_files(capsys, run_copy, torus_file):
    (run_copy / "notes.txt").write_text("mine")
    _fails(capsys, ["fit", torus_file, "-o", str(run_copy), "--preset", "tiny", "--overwrite"],
           "files mna does not write (notes.txt)")
    assert (run_copy / "notes.txt").read_text() == "mine" and (run_copy / "checkpoint.pt").is_file()


def test_input_inside_the_run_folder_is_not_content(tmp_path):
    from mna.runfolder import prepare_run_folder

    run = tmp_path / "run"
    run.mkdir()
    src = run / "input_torus.ply"
    src.write_text("x")
    assert prepare_run_folder(run, keep=[src]) == run and src.is_file()
    (run / "mesh.obj").write_text("old")
    prepare_run_folder(run, overwrite=True, keep=[src])
    assert sorted(p.name for p in run.iterdir()) == ["input_torus.ply"]


# -- item 13: scale ------------------------------------------------------------------------------
@pytest.mark.parametrize("scale", [1e-30, 1e200])
def test_tiny_and_huge_meshes_fit(tmp_path, scale):
    mesh = shapes.torus(sections=24, ring=12)
    src = _write_obj(tmp_path / "t.obj", mesh.vertices * scale, mesh.faces)
    res = fit_run(str(src), tmp_path / "run", _tiny(3), progress_bar=False, log=lambda s: None)
    assert res.metrics["normalization"]["scale"] == pytest.approx(1.4 * scale, rel=0.02)
    z = np.load(tmp_path / "run" / "charts.npz")
    assert np.isfinite(z["vertices"]).all()
    extent = np.abs(z["vertices"]).max()
    assert 0.01 * scale < extent < 3 * scale  # the input's frame, not flushed to 0 or inf
    import trimesh

    pts = trimesh.load(tmp_path / "run" / "points.ply").vertices
    assert np.isfinite(pts).all() and 0.01 * scale < np.abs(pts).max() < 3 * scale


def test_a_mesh_in_map_coordinates_keeps_its_shape_in_the_run(tmp_path):
    # a 1.4-unit torus at UTM-like coordinates: float32 steps by 0.5 at 5.3e6
    mesh = shapes.torus(sections=24, ring=12)
    offset = np.array([412345.678, 5312345.432, 250.0])
    src = _write_obj(tmp_path / "t.obj", mesh.vertices + offset, mesh.faces)
    fit_run(str(src), tmp_path / "run", _tiny(3), progress_bar=False, log=lambda s: None)
    z = np.load(tmp_path / "run" / "charts.npz")
    v = z["vertices"] - offset  # the input's frame, to the torus's own precision
    assert z["vertices"].dtype == np.float64
    # the charts' points sit on the grid: distinct in the shape's frame, not snapped to 0.5 steps
    assert np.abs(v).max() < 3 and len(np.unique(np.round(v[:, 0], 6))) > len(v) // 4


def test_export_reference_points_of_a_huge_mesh():
    """`mna export` samples the input surface: in a 1e200 mesh's own units its areas overflow."""
    import trimesh

    from mnacore.frame import Normalization
    from texture.pipeline import reference_points

    mesh = shapes.sphere(subdivisions=1)
    for scale in (1e-200, 1e200):
        big = trimesh.Trimesh(mesh.vertices * scale, mesh.faces, process=False)
        pts = reference_points(big, None, Normalization.fit(big.vertices), count=200)
        assert np.isfinite(pts).all()
        np.testing.assert_allclose(np.linalg.norm(pts, axis=1).max(), 1.0, atol=0.05)


def test_unit_ball_is_overflow_safe_and_relative():
    from mnacore.errors import InputError
    from mnacore.frame import Normalization, unit_ball, unit_ball_normalization

    pts = np.array([[0.0, 0, 0], [2, 0, 0], [0, 1, 0]])
    for s in (1e-300, 1e-30, 1.0, 1e200, 1e300):
        c, r = unit_ball(pts * s)
        np.testing.assert_allclose(c, [s, s / 2, 0], rtol=1e-12)
        assert r == pytest.approx(np.sqrt(1.25) * s, rel=1e-12)
        np.testing.assert_allclose(unit_ball_normalization(pts * s).center, c)
    with pytest.raises(InputError, match="zero extent"):
        unit_ball(np.ones((5, 3)) * 1e200 + np.arange(5)[:, None] * 1e180)  # 1e-20 relative
    with pytest.raises(InputError, match="coordinates overflow"):
        unit_ball(np.array([[-1.7e308, -1.7e308, 0], [1.7e308, 1.7e308, 0]]))  # radius 2.4e308
    assert Normalization.fit(pts).to_json() == Normalization.fit(pts).to_dict()


def test_infinite_coordinates_say_overflow(capsys, tmp_path):
    mesh = shapes.sphere(subdivisions=1)
    vertices = mesh.vertices.copy()
    vertices[0, 0] = np.inf
    src = _write_obj(tmp_path / "s.obj", vertices, mesh.faces)
    src.write_text(src.read_text().replace("inf", "1e400", 1))  # a number float64 cannot hold
    out = tmp_path / "run"
    _fails(capsys, ["fit", str(src), "-o", str(out)], "coordinates overflow")
    assert not out.exists()


# -- item 14: messages name the right thing ----------------------------------------------------
def test_text_file_named_ply(capsys, tmp_path):
    src = tmp_path / "notes.ply"
    src.write_text("hello, not a mesh\n" * 5)
    _fails(capsys, ["fit", str(src), "-o", str(tmp_path / "run")], "cannot read notes.ply: not a PLY file")
    _fails(capsys, ["uv-metrics", str(src)], "cannot read notes.ply: not a PLY file")
    assert not (tmp_path / "run").exists()


def test_broken_gltf_and_its_missing_buffer(capsys, tmp_path):
    import trimesh

    # trimesh reports both as a FileNotFoundError naming another file ("model.gltf")
    (tmp_path / "cut.gltf").write_text('{"asset":')
    (tmp_path / "list.gltf").write_text("[1, 2]")
    files = trimesh.Scene(shapes.torus(sections=24, ring=12)).export(file_type="gltf")
    (tmp_path / "model.gltf").write_bytes(files["model.gltf"])  # without its .bin buffers
    for cmd in (["fit"], ["unwrap"]):
        out = tmp_path / "run"
        _fails(capsys, [*cmd, str(tmp_path / "cut.gltf"), "-o", str(out)], "cannot read cut.gltf: not glTF JSON")
        _fails(capsys, [*cmd, str(tmp_path / "list.gltf"), "-o", str(out)], 'cannot read list.gltf: not glTF (no "asset"')
        missing = next(k for k in files if k.endswith(".bin"))
        _fails(capsys, [*cmd, str(tmp_path / "model.gltf"), "-o", str(out)],
               f"cannot read model.gltf: a file it refers to is missing: {missing}")
        assert not out.exists()


def test_negative_seed_names_the_option(capsys, sphere_file, tmp_path):
    out = tmp_path / "run"
    _fails(capsys, ["fit", sphere_file, "-o", str(out), "--seed", "-5"], "--seed must be between 0 and")
    assert not out.exists()


def test_corrupt_metrics_json_fails_before_any_work(capsys, run_copy):
    (run_copy / "metrics.json").write_text("{corrupt")
    stamp = {p.name: p.stat().st_mtime_ns for p in run_copy.iterdir()}
    _fails(capsys, ["extract", str(run_copy)], f"{run_copy / 'metrics.json'} is not valid JSON")
    assert {p.name: p.stat().st_mtime_ns for p in run_copy.iterdir()} == stamp


def test_corrupt_metrics_json_fails_before_resuming(capsys, run_copy, torus_file):
    (run_copy / "metrics.json").write_text("[1, 2")
    mtime = (run_copy / "checkpoint.pt").stat().st_mtime_ns
    _fails(capsys, ["fit", torus_file, "-o", str(run_copy), "--resume", "--steps", "8", "--no-progress"],
           "metrics.json is not valid JSON")
    assert (run_copy / "checkpoint.pt").stat().st_mtime_ns == mtime


def _nan_obj(path: Path, nan_uv: bool) -> Path:
    mesh = shapes.sphere(subdivisions=1)
    v = mesh.vertices.copy()
    uv = np.random.default_rng(0).random((len(v), 2))
    (uv if nan_uv else v)[3, 0] = np.nan
    lines = [f"v {x} {y} {z}" for x, y, z in v] + [f"vt {a} {b}" for a, b in uv]
    lines += [f"f {a + 1}/{a + 1} {b + 1}/{b + 1} {c + 1}/{c + 1}" for a, b, c in mesh.faces]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_render_mesh_nan_uvs_writes_nothing(capsys, tmp_path):
    out = tmp_path / "out"
    _fails(capsys, ["render-mesh", str(_nan_obj(tmp_path / "m.obj", True)), "-o", str(out), "--res", "16",
                    "--spp", "1", "--no-progress"], "m.obj: UVs contain NaN")
    assert not out.exists()


def test_uv_nan_coordinates(capsys, tmp_path):
    out = tmp_path / "out"
    _fails(capsys, ["uv", str(_nan_obj(tmp_path / "m.obj", False)), "-o", str(out)], "m.obj has NaN coordinates")
    assert not out.exists()


def test_uv_metrics_into_a_folder_names_the_folder(capsys, tmp_path):
    from mnacore.atomic import TEMP_MARK

    mesh = shapes.sphere(subdivisions=1)
    src = tmp_path / "m.obj"
    uv = np.random.default_rng(0).random((len(mesh.vertices), 2))
    lines = [f"v {x} {y} {z}" for x, y, z in mesh.vertices] + [f"vt {a} {b}" for a, b in uv]
    lines += [f"f {a + 1}/{a + 1} {b + 1}/{b + 1} {c + 1}/{c + 1}" for a, b, c in mesh.faces]
    src.write_text("\n".join(lines) + "\n")
    folder = tmp_path / "dir"
    folder.mkdir()
    err = _fails(capsys, ["uv-metrics", str(src), "-o", str(folder)], f"{folder} is a folder")
    assert TEMP_MARK not in err and not any(folder.iterdir())
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir", "m.obj"]


# -- item 15: values accepted without a word -----------------------------------------------------
def test_extract_points_zero(capsys, run_copy):
    _fails(capsys, ["extract", str(run_copy), "--points", "0"], "--points must be positive")


def test_export_square_size_zero(capsys, run_copy):
    for bad in ("0", "-1", "nan"):
        _fails(capsys, ["export", str(run_copy), "--square-size", bad], "--square-size must be a positive")
    assert not (run_copy / "mesh.obj").exists()


def test_empty_output_path(capsys, sphere_file, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _fails(capsys, ["fit", sphere_file, "-o", ""], "-o/--out must not be empty")
    _fails(capsys, ["uv", sphere_file, "-o", ""], "-o/--out must not be empty")
    _fails(capsys, ["extract", ""], "RUN must not be empty")
    assert not any(tmp_path.iterdir())


def test_charts_upper_limit(capsys, sphere_file, tmp_path):
    _fails(capsys, ["fit", sphere_file, "-o", str(tmp_path / "run"), "--charts", "1000"],
           "--charts must be between 1 and 64, got 1000")
    assert not (tmp_path / "run").exists()


@pytest.mark.skipif(torch.cuda.is_available(), reason="needs a machine without CUDA")
def test_cuda_without_cuda_leaves_no_folder(capsys, sphere_file, tmp_path):
    _fails(capsys, ["fit", sphere_file, "-o", str(tmp_path / "run"), "--device", "cuda"], "no CUDA device")
    assert not (tmp_path / "run").exists()


def test_negative_threads_leaves_no_folder(capsys, sphere_file, tmp_path):
    _fails(capsys, ["fit", sphere_file, "-o", str(tmp_path / "run"), "--threads", "-4"], "--threads must be")
    assert not (tmp_path / "run").exists()


# -- item 16: SIGTERM and stale temporaries ------------------------------------------------------
def _env() -> dict:
    return {**os.environ, "PYTHONUNBUFFERED": "1", "PYTHONPATH": str(REPO)}


def test_sigterm_saves_a_checkpoint_and_exits_143(torus_file, tmp_path):
    run = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, "-m", "mna.cli", "fit", torus_file, "-o", str(run), "--preset", "tiny",
                             "--steps", "100000", "--no-progress", "--device", "cpu"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env())
    deadline = time.time() + 60
    while not (run / "checkpoint.pt").exists() and time.time() < deadline:
        time.sleep(0.2)
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err
    assert "checkpoint saved" in out and "Traceback" not in err
    assert torch.load(run / "checkpoint.pt", weights_only=True)["step"] >= 50


def test_stale_temporaries_are_cleaned_on_the_next_start(run_copy, torus_file):
    from mnacore.atomic import PROCESS_START, atomic_path

    # a killed earlier process left them: older than this process's start (the rule), which
    # may be minutes ago in a long test session
    old = PROCESS_START - 60
    stale = [run_copy / ".checkpoint.pt.mna-tmp.ab12cd_9.pt",  # this version's name
             run_copy / ".checkpoint.k2j9x0ab.pt"]  # the name before
    for p in stale:
        p.write_bytes(b"half a checkpoint")
        os.utime(p, (old, old))
    fresh = run_copy / ".metrics.json.mna-tmp.zz12cd_9.json"  # another process, writing now
    fresh.write_text("{")
    os.utime(fresh, (time.time() + 5, time.time() + 5))
    mine = [run_copy / ".checkpoint.notes.pt", run_copy / ".hidden"]  # not our names
    for p in mine:
        p.write_text("user")
        os.utime(p, (old, old))
    res = fit_run(torus_file, run_copy, _tiny(8), resume=True, progress_bar=False, log=lambda s: None)
    assert res.steps == 8
    assert not any(p.exists() for p in stale)
    assert fresh.exists() and all(p.exists() for p in mine)
    with atomic_path(run_copy / "x.json") as tmp:
        assert tmp.name.startswith(".x.json.mna-tmp.") and tmp.suffix == ".json"


# -- item 17: a shared machine -------------------------------------------------------------------
def test_mna_sets_passive_omp_before_torch():
    env = {k: v for k, v in _env().items() if k != "OMP_WAIT_POLICY"}
    code = "import mna.cli, os, sys; print(os.environ['OMP_WAIT_POLICY'], 'torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True).stdout
    assert out.split() == ["PASSIVE", "False"]
    env["OMP_WAIT_POLICY"] = "ACTIVE"  # the user's choice wins
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True).stdout
    assert out.split()[0] == "ACTIVE"


def test_demo_budgets_its_fit_in_steps(monkeypatch, tmp_path, capsys):
    import mna.cli
    from mna.commands.demo import DEMO_STEPS

    calls = []

    def fake_main(argv):
        calls.append(argv)
        return 1  # stop after the fit stage

    monkeypatch.setattr(mna.cli, "main", fake_main)
    from mna.commands import demo

    args = mna.cli.build_parser().parse_args(["demo", "-o", str(tmp_path / "d")])
    with pytest.raises(Exception, match="stage 'fit' failed"):
        demo.run_demo(args)
    fit_argv = calls[0]
    assert "--time-budget" not in fit_argv
    assert fit_argv[fit_argv.index("--steps") + 1] == str(DEMO_STEPS)
    # a second demo into the same folder needs --overwrite; the demo's own input is no obstacle,
    # nor the unwrap folder an earlier demo wrote (a second `make demo` once failed on it)
    (tmp_path / "d" / "mesh.obj").write_text("old")
    (tmp_path / "d" / "unwrap").mkdir()
    (tmp_path / "d" / "unwrap" / "unwrap.json").write_text("{}")
    monkeypatch.setattr(mna.cli, "main", main)
    _fails(capsys, ["demo", "-o", str(tmp_path / "d")], "not empty")
    args = mna.cli.build_parser().parse_args(["demo", "-o", str(tmp_path / "d"), "--overwrite"])
    monkeypatch.setattr(mna.cli, "main", fake_main)
    with pytest.raises(Exception, match="stage 'fit' failed"):
        demo.run_demo(args)
    assert sorted(p.name for p in (tmp_path / "d").iterdir()) == ["input_torus.ply"]


def test_resume_removes_what_was_made_from_the_earlier_charts(run_copy, torus_file):
    """An export, comparison or renders of the charts before a resume would sit beside the new
    fit's charts as if they were made from them: --resume removes them (and says so), and
    keeps the fit's own files, the input and files mna does not write."""
    from mna.runfolder import DERIVED, FIT_FILES

    assert "mesh.obj" in DERIVED and "renders" in DERIVED and not set(FIT_FILES) & set(DERIVED)
    for name in ("mesh.obj", "mesh.glb", "compare.md", "unwrap.json"):
        (run_copy / name).write_text("made from the earlier charts")
    (run_copy / "renders").mkdir()
    (run_copy / "renders" / "figure.png").write_bytes(b"png")
    (run_copy / "notes.txt").write_text("mine")
    said = []
    res = fit_run(torus_file, run_copy, _tiny(8), resume=True, progress_bar=False, log=said.append)
    assert res.steps == 8
    for name in ("mesh.obj", "mesh.glb", "compare.md", "unwrap.json", "renders"):
        assert not (run_copy / name).exists(), name
    assert (run_copy / "notes.txt").read_text() == "mine"
    assert all((run_copy / n).is_file() for n in ("config.yaml", "checkpoint.pt", "metrics.json", "charts.npz"))
    (line,) = [s for s in said if s.startswith("removed")]
    assert "mesh.obj" in line and "renders/" in line
