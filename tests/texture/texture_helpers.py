"""Synthetic neural-atlas outputs with closed forms, for the texture tests.

``sphere_charts`` covers the unit sphere with azimuthal-equidistant caps: chart ``k`` maps
``(u, v)`` with ``r = |(u, v)|`` to the point at polar angle ``theta = r * theta_max``
around axis ``a_k``. Its occupancy ``occ = 1.5 - r`` puts the domain boundary
(``occ = 0.5``) exactly on the circle ``r = 1``, i.e. the cap ``theta < theta_max``.
Two caps of 105 degrees around +z and -z overlap in the band 75..105 degrees.

Analytic metric: radial stretch ``theta_max``, tangential ``theta_max sin(theta) / theta``.
"""
from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import pytest
import trimesh

from mna import shapes
from mnacore.charts import save_charts
from mnacore.frame import Normalization

CENTER = np.array([0.5, -1.0, 2.0])
SCALE = 2.0


def _frame(axis: np.ndarray) -> np.ndarray:
    """3x3 rotation whose third column is ``axis``."""
    a = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    helper = np.array([1.0, 0, 0]) if abs(a[0]) < 0.9 else np.array([0, 1.0, 0])
    e1 = np.cross(helper, a)
    e1 /= np.linalg.norm(e1)
    return np.stack([e1, np.cross(a, e1), a], 1)


def cap_chart(G: int, theta_max: float, axis) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(uv (G,G,2), xyz unit frame (G,G,3), occ (G,G)) of one azimuthal-equidistant cap."""
    lin = np.linspace(-1.0, 1.0, G)
    u, v = np.meshgrid(lin, lin, indexing="xy")  # u varies along columns j, v along rows i
    uv = np.stack([u, v], -1)
    r = np.hypot(u, v)
    theta = r * theta_max
    safe = np.where(r > 0, r, 1.0)
    local = np.stack([np.sin(theta) * u / safe, np.sin(theta) * v / safe, np.cos(theta)], -1)
    xyz = local @ _frame(np.asarray(axis, float)).T
    return uv, xyz, 1.5 - r


def sphere_charts(G: int = 96, theta_max: float = np.radians(105), axes=((0, 0, 1), (0, 0, -1))):
    parts = [cap_chart(G, theta_max, a) for a in axes]
    uv = np.stack([p[0] for p in parts])
    xyz = np.stack([p[1] for p in parts]) * SCALE + CENTER  # input frame
    occ = np.stack([p[2] for p in parts])
    return uv, xyz, occ


def write_sphere_run(run: Path, G: int = 96, colored_input: bool = True, **kw) -> Path:
    """A run folder with charts.npz of ``sphere_charts`` and config.yaml naming an input mesh."""
    run.mkdir(parents=True, exist_ok=True)
    uv, xyz, occ = sphere_charts(G, **kw)
    save_charts(run / "charts.npz", uv, xyz, occ, 0.5, Normalization(CENTER, SCALE))
    mesh = shapes.sphere(radius=1.0, subdivisions=4)
    if colored_input:
        mesh.visual.vertex_colors = color_function(mesh.vertices)
    mesh.apply_scale(SCALE)
    mesh.apply_translation(CENTER)
    mesh.export(run / "input.ply")
    (run / "config.yaml").write_text(f"input: {run / 'input.ply'}\nseed: 0\n")
    return run


def color_function(unit_xyz: np.ndarray) -> np.ndarray:
    """RGBA uint8 colour of a unit-frame point: linear in position (so exact under interpolation)."""
    rgb = np.clip((np.asarray(unit_xyz) + 1.0) * 0.5, 0, 1) * 255
    return np.column_stack([np.round(rgb), np.full(len(rgb), 255)]).astype(np.uint8)


@pytest.fixture(scope="session")
def sphere_run(tmp_path_factory) -> Path:
    """Read-only synthetic run (copy it before writing into it)."""
    return write_sphere_run(tmp_path_factory.mktemp("sphere_run"))


@pytest.fixture
def fresh_sphere_run(tmp_path) -> Path:
    """A writable synthetic run (coarser grid than ``sphere_run``: CLI tests are end to end)."""
    return write_sphere_run(tmp_path / "run", G=64)


@pytest.fixture(scope="session")
def icosphere() -> trimesh.Trimesh:
    return shapes.sphere(radius=1.0, subdivisions=3)


def assert_glb_validates(path) -> None:
    """The Khronos glTF validator reports no errors, no warnings and no hints (skips where it
    is absent)."""
    from texture import gltf_validator

    reason = gltf_validator.available()
    if reason:
        pytest.skip(reason)
    report = gltf_validator.validate(path)
    assert report["numErrors"] == 0 and report["numWarnings"] == 0, report["messages"][:5]
    assert report["numHints"] == 0, report["messages"][:5]


def glb_json(path) -> dict:
    """The JSON chunk of a GLB file (glTF 2.0 binary container)."""
    data = open(path, "rb").read()
    length, kind = struct.unpack_from("<I4s", data, 12)
    assert kind == b"JSON"
    return json.loads(data[20:20 + length])


def glb_attribute(path, name: str) -> np.ndarray:
    """The raw ``name`` attribute (e.g. NORMAL) of the GLB's first primitive, as stored."""
    data = open(path, "rb").read()
    length = struct.unpack_from("<I", data, 12)[0]
    doc, base = json.loads(data[20:20 + length]), 20 + length + 8
    a = doc["accessors"][doc["meshes"][0]["primitives"][0]["attributes"][name]]
    view = doc["bufferViews"][a["bufferView"]]
    width = {"VEC3": 3, "VEC2": 2}[a["type"]]
    offset = base + view.get("byteOffset", 0) + a.get("byteOffset", 0)
    return np.frombuffer(data, np.float32, a["count"] * width, offset).reshape(-1, width).astype(np.float64)
