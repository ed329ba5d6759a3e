"""Bad input through the CLI: one clear line on stderr, exit code 2, nothing half-written."""
from __future__ import annotations

import numpy as np
import pytest

from mna.cli import main


def _fails(capsys, argv, needle):
    code = main(argv)
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert len(err.splitlines()) == 1, err
    assert needle.lower() in err.lower(), err
    return err


@pytest.fixture
def out(tmp_path):
    return tmp_path / "run"


def _assert_untouched(out):
    assert not out.exists() or not any(out.iterdir())


def test_missing_file(capsys, tmp_path, out):
    _fails(capsys, ["fit", str(tmp_path / "nope.obj"), "-o", str(out)], "not found")
    _assert_untouched(out)


def test_unknown_extension(capsys, tmp_path, out):
    f = tmp_path / "shape.abc"
    f.write_text("1 2 3\n")
    _fails(capsys, ["fit", str(f), "-o", str(out)], "unknown input extension")
    _assert_untouched(out)


def test_empty_file(capsys, tmp_path, out):
    f = tmp_path / "empty.obj"
    f.write_text("")
    _fails(capsys, ["fit", str(f), "-o", str(out)], "empty")
    _assert_untouched(out)


def test_unreadable_file(capsys, tmp_path, out):
    f = tmp_path / "junk.npy"
    f.write_bytes(b"\x00\x01garbage" * 10)
    _fails(capsys, ["fit", str(f), "-o", str(out)], "cannot read")
    _assert_untouched(out)


@pytest.mark.parametrize("bad, needle", [(np.nan, "NaN coordinates"), (np.inf, "coordinates overflow")])
def test_nan_or_inf_coordinates(capsys, tmp_path, out, bad, needle):
    pts = np.random.default_rng(0).normal(size=(100, 3))
    pts[5, 1] = bad
    np.save(tmp_path / "cloud.npy", pts)
    _fails(capsys, ["fit", str(tmp_path / "cloud.npy"), "-o", str(out)], needle)
    _assert_untouched(out)


def test_mesh_without_faces(capsys, tmp_path, out):
    f = tmp_path / "nofaces.obj"
    f.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in np.random.default_rng(0).normal(size=(30, 3))))
    _fails(capsys, ["fit", str(f), "-o", str(out)], "no faces")
    _assert_untouched(out)


def test_too_few_points(capsys, tmp_path, out):
    np.save(tmp_path / "few.npy", np.random.default_rng(0).normal(size=(5, 3)))
    _fails(capsys, ["fit", str(tmp_path / "few.npy"), "-o", str(out)], "at least")
    _assert_untouched(out)


def test_zero_extent(capsys, tmp_path, out):
    np.save(tmp_path / "point.npy", np.ones((100, 3)))
    _fails(capsys, ["fit", str(tmp_path / "point.npy"), "-o", str(out)], "zero extent")
    _assert_untouched(out)


def test_zero_charts(capsys, sphere_file, out):
    _fails(capsys, ["fit", sphere_file, "-o", str(out), "--charts", "0"], "--charts must be between 1 and 64")
    _assert_untouched(out)


def test_unwritable_output(capsys, sphere_file, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("a file, not a folder")
    _fails(capsys, ["fit", sphere_file, "-o", str(blocker / "run")], "not writable")
    _fails(capsys, ["fit", sphere_file, "-o", str(blocker)], "not a folder")


def test_resume_without_checkpoint(capsys, sphere_file, out):
    out.mkdir()
    _fails(capsys, ["fit", sphere_file, "-o", str(out), "--resume"], "config.yaml")


def test_unknown_preset_and_bad_budget(capsys, sphere_file, out):
    _fails(capsys, ["fit", sphere_file, "-o", str(out), "--preset", "huge"], "unknown preset")
    _fails(capsys, ["fit", sphere_file, "-o", str(out), "--time-budget", "-3"], "--time-budget must be positive")
    _assert_untouched(out)


def test_extract_missing_run(capsys, tmp_path):
    _fails(capsys, ["extract", str(tmp_path / "none")], "not found")


def test_config_with_unknown_key(capsys, sphere_file, tmp_path, out):
    cfg = tmp_path / "c.yaml"
    cfg.write_text("lr: 0.001\nwarp_drive: 9\n")
    _fails(capsys, ["fit", sphere_file, "-o", str(out), "--config", str(cfg)], "unknown key")
    cfg.write_text("lr: fast\n")
    _fails(capsys, ["fit", sphere_file, "-o", str(out), "--config", str(cfg)], "config.lr must be float")


def test_fit_cli_end_to_end_with_grid(capsys, torus_file, out):
    code = main(["fit", torus_file, "-o", str(out), "--preset", "tiny", "--steps", "5", "--grid", "20",
                 "--no-progress", "--device", "cpu"])
    assert code == 0, capsys.readouterr().err
    z = np.load(out / "charts.npz")
    assert z["xyz"].shape == (3, 20, 20, 3)
    assert "fscore_mesh" in capsys.readouterr().out


def test_config_float_written_without_dot(tmp_path):
    """YAML 1.1 reads ``1e-3`` as a string; a float key still takes it (and a word still fails)."""
    from mna import config as C

    cfg = C.from_dict({"lr": "1e-3", "loss": {"w_orient": "2e-3"}})
    assert cfg.lr == 0.001 and cfg.loss.w_orient == 0.002
    with pytest.raises(C.MnaError, match="config.lr must be float"):
        C.from_dict({"lr": "fast"})


def test_a_low_poly_mesh_is_sampled_on_its_faces(tmp_path):
    # 8 vertices are too few for a cloud, not for a mesh: its faces are the shape
    import trimesh

    from mna.data import MIN_POINTS, load_surface
    from mnacore.errors import InputError

    box = trimesh.creation.box(extents=[2.0, 4.0, 6.0])
    assert len(box.vertices) < MIN_POINTS
    box.export(tmp_path / "box.obj")
    s = load_surface(tmp_path / "box.obj")
    corner = np.abs(s.normalization.apply(np.array([[1.0, 2.0, 3.0]]))[0])
    np.testing.assert_allclose(corner, np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0), rtol=1e-12)  # unit-ball frame
    p = s.sample(2000, np.random.default_rng(0))
    # every sample lies on a face: on the box, with one coordinate at its half-extent
    assert np.all(np.abs(p) <= corner + 1e-12)
    assert np.all(np.min(np.abs(np.abs(p) - corner), axis=1) < 1e-12)
    np.save(tmp_path / "box_points.npy", box.vertices)
    with pytest.raises(InputError, match="at least"):
        load_surface(tmp_path / "box_points.npy")
