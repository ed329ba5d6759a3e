"""Fixtures for render tests: per-variant Mitsuba, pyrender/EGL, reference images, small UV meshes.

* ``variant`` is parametrised over ``scalar_rgb`` and ``llvm_ad_rgb`` (and ``cuda_ad_rgb``
  where a GPU works); a variant whose backend is missing skips with the reason.
* On CI (``CI=true``) a skipped test in this folder is turned into a failure, so a CI run
  proves that both renderers really ran.
* ``compare_image`` checks a render against ``references/{name}.exr`` (relative error with
  a floor; a mean and a max bound). On failure it writes the rendered, reference and
  error images under ``tests/_artifacts/render/`` and names them in the message.
  ``MNA_REGEN_REFS=1`` rewrites the references instead (render them at high spp).
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parent
REFERENCES = HERE / "references"
ARTIFACTS = HERE.parents[1] / "tests" / "_artifacts" / "render"
ON_CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")
REGEN = os.environ.get("MNA_REGEN_REFS", "") not in ("", "0")

MITSUBA_VARIANTS = ["scalar_rgb", "llvm_ad_rgb"]


def _extra_variants() -> list[str]:
    try:
        from render.backend import available_variants

        return [v for v in available_variants() if v not in MITSUBA_VARIANTS]
    except Exception:  # collection must never fail on a missing backend
        return []


def pytest_collection_modifyitems(config, items):
    for item in items:
        if HERE in Path(str(item.fspath)).parents:
            item.add_marker(pytest.mark.render)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if ON_CI and report.skipped and HERE in Path(str(item.fspath)).parents:
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        report.outcome = "failed"
        report.longrepr = f"render test skipped on CI (CI=true), which counts as a failure: {reason}"


@pytest.fixture(params=MITSUBA_VARIANTS + _extra_variants())
def variant(request) -> str:
    """A Mitsuba RGB variant whose backend works here (skips with the reason otherwise)."""
    from render.backend import _missing_reason, available_variants, import_mitsuba

    mi = import_mitsuba()
    name = request.param
    if name not in mi.variants():
        pytest.skip(f"Mitsuba variant {name} is not compiled into this Mitsuba build")
    if name not in available_variants():
        pytest.skip(f"Mitsuba variant {name} unavailable: {_missing_reason(name)}")
    return name


@pytest.fixture(scope="session")
def fast_variant() -> str:
    """The variant for tests that need *a* Mitsuba: scalar (no JIT warm-up at tiny sizes)."""
    from render.backend import available_variants

    avail = available_variants()
    if not avail:
        pytest.skip("no Mitsuba variant works here")
    return "scalar_rgb" if "scalar_rgb" in avail else avail[0]


@pytest.fixture(scope="session")
def pyrender_ok():
    """Skip unless pyrender can open an EGL context here."""
    from render.preview import PreviewUnavailable, _pyrender

    try:
        pr = _pyrender()
        r = pr.OffscreenRenderer(8, 8)
        r.delete()
    except PreviewUnavailable as exc:
        pytest.skip(str(exc))
    except Exception as exc:
        pytest.skip(f"pyrender preview unavailable (no EGL context): {type(exc).__name__}: {exc}")
    return True


def _write_artifacts(name: str, image: np.ndarray, reference: np.ndarray | None, error: np.ndarray | None):
    from render.images import linear_to_srgb, write_exr, write_png

    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    paths = [ARTIFACTS / f"{name}_rendered.exr", ARTIFACTS / f"{name}_rendered.png"]
    write_exr(paths[0], image)
    write_png(paths[1], linear_to_srgb(image[..., :3]))
    if reference is not None:
        paths.append(ARTIFACTS / f"{name}_reference.png")
        write_png(paths[-1], linear_to_srgb(reference[..., :3]))
    if error is not None:
        paths.append(ARTIFACTS / f"{name}_error.png")
        write_png(paths[-1], np.clip(error / max(float(error.max()), 1e-6), 0, 1))
    return paths


@pytest.fixture
def compare_image():
    """``compare_image(name, image, reference_fn, mean=, max=, floor=)``: assert against a stored reference.

    ``reference_fn()`` renders the reference (high spp); it is called only to regenerate.
    """
    from render.images import read_image, relative_error, write_exr

    def check(name: str, image: np.ndarray, reference_fn, mean: float, max: float, floor: float = 0.05,
              block: int = 4):
        path = REFERENCES / f"{name}.exr"
        if REGEN:
            REFERENCES.mkdir(parents=True, exist_ok=True)
            write_exr(path, reference_fn())
            print(f"regenerated reference {path}", file=sys.stderr)
        if not path.is_file():
            paths = _write_artifacts(name, image, None, None)
            pytest.fail(f"reference {path} missing; run with MNA_REGEN_REFS=1. Rendered: {paths[1]}")
        ref = read_image(path)
        err = relative_error(image, ref, floor=floor, block=block)
        if not (err.mean <= mean and err.max <= max):
            paths = _write_artifacts(name, image, ref, err.error)
            pytest.fail(f"{name}: relative error mean {err.mean:.4f} (bound {mean}), block max {err.max:.4f} "
                        f"(bound {max}); wrote {', '.join(str(p) for p in paths)}")
        return err

    return check


# ---------------------------------------------------------------- small meshes

def torus_with_uv(major: float = 1.0, minor: float = 0.4, n: int = 32, m: int = 16):
    """Parametric torus: vertices (V, 3), faces (F, 3), uv (V, 2) = (theta / 2pi, phi / 2pi), seams split."""
    i, j = np.meshgrid(np.arange(n + 1), np.arange(m + 1), indexing="ij")
    u, v = i / n, j / m
    th, ph = 2 * np.pi * u, 2 * np.pi * v
    verts = np.stack([(major + minor * np.cos(ph)) * np.cos(th), minor * np.sin(ph),
                      (major + minor * np.cos(ph)) * np.sin(th)], -1).reshape(-1, 3)
    a = (i[:-1, :-1] * (m + 1) + j[:-1, :-1]).ravel()
    b, c, d = a + (m + 1), a + (m + 1) + 1, a + 1
    faces = np.concatenate([np.stack([a, d, c], 1), np.stack([a, c, b], 1)])
    return verts, faces, np.stack([u, v], -1).reshape(-1, 2)


def flat_square(side: float = 2.0, n: int = 4):
    """Square in the z = 0 plane facing +z, isometric UVs ``uv = (x, y) / side + 1/2``."""
    lin = np.linspace(-side / 2, side / 2, n + 1)
    x, y = np.meshgrid(lin, lin, indexing="xy")
    verts = np.stack([x, y, np.zeros_like(x)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = (i * (n + 1) + j).ravel()
    b, c, d = a + 1, a + n + 2, a + n + 1
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return verts, faces, verts[:, :2] / side + 0.5


def write_obj(path: Path, verts, faces, uv=None) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in verts]
    if uv is not None:
        lines += [f"vt {s:.9g} {t:.9g}" for s, t in uv]
        lines += [f"f {a + 1}/{a + 1} {b + 1}/{b + 1} {c + 1}/{c + 1}" for a, b, c in faces]
    else:
        lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="session")
def uv_run(tmp_path_factory) -> Path:
    """A run folder: RUN/mesh.obj (parametric torus UVs) and RUN/xatlas/mesh.obj (xatlas UVs)."""
    import trimesh
    import xatlas

    run = tmp_path_factory.mktemp("run") / "torus"
    v, f, uv = torus_with_uv(n=24, m=12)
    write_obj(run / "mesh.obj", v, f, uv)
    welded = trimesh.Trimesh(v, f, process=True)
    vmap, idx, xuv = xatlas.parametrize(np.asarray(welded.vertices), np.asarray(welded.faces))
    write_obj(run / "xatlas" / "mesh.obj", np.asarray(welded.vertices)[vmap], idx, xuv)
    return run


class MeshFactory:
    """Builders of small UV meshes, handed to tests as the ``meshes`` fixture."""

    torus = staticmethod(torus_with_uv)
    flat_square = staticmethod(flat_square)
    write_obj = staticmethod(write_obj)


@pytest.fixture(scope="session")
def meshes() -> MeshFactory:
    return MeshFactory()
