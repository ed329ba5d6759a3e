"""``mna unwrap`` after the fit: the input mesh file + a run's charts -> ``OUT/mesh.*`` + ``OUT/unwrap.json``.

``load_unwrap_input`` reads the user's mesh with its own vertex list (an OBJ's ``v``
lines in file order, not split by its texture coordinates; its faces in file order, not
grouped by material: :func:`mnacore.uvmesh.read_mesh`) and validates it before
anything is written. ``unwrap_to_folder`` unwraps it with the charts of ``RUN/charts.npz``
(:func:`texture.unwrap.unwrap_mesh`), writes the textured OBJ/MTL/PNG/GLB through
:func:`texture.export.export_textured`, measures the result with the one harness
(:func:`texture.harness.measure`, reference = the input mesh, unit-ball frame of the
fit) and writes ``OUT/unwrap.json`` last (atomically).
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mnacore.atomic import write_json
from mnacore.charts import load_charts
from mnacore.errors import InputError
from mnacore.machine import cpu_summary
from mnacore.uvmesh import read_mesh, validate_mesh

from .export import export_textured
from .harness import measure
from .pipeline import TEXTURES, make_texture
from .textures import check_size, source_colors
from .unwrap import UnwrapConfig, unwrap_mesh

UNWRAP_JSON = "unwrap.json"


@dataclass
class UnwrapInput:
    """The user's mesh: ``mesh`` (trimesh, as read), ``vertices (V,3)``, ``faces (F,3)``,
    ``had_uv``: the file carried texture coordinates (they are replaced)."""

    mesh: object
    vertices: np.ndarray
    faces: np.ndarray
    had_uv: bool
    path: str


def load_unwrap_input(path: str | os.PathLike) -> UnwrapInput:
    """Read and validate a mesh file; ``InputError`` (one line) on anything unusable."""
    path = Path(path)
    mesh = read_mesh(path, keep_vertex_order=True)
    vertices, faces = validate_mesh(mesh.vertices, mesh.faces, path.name)
    return UnwrapInput(mesh, vertices, faces, _carries_uv(path, mesh), str(path))


def _has_uv(mesh) -> bool:
    uv = getattr(getattr(mesh, "visual", None), "uv", None)
    return uv is not None and len(uv) > 0


def _carries_uv(path: Path, mesh) -> bool:
    """Whether the file holds texture coordinates anywhere. A glTF scene is read as one mesh
    (its nodes' geometry in the scene frame), and where some of its meshes carry UVs and some
    do not, trimesh drops them all in that one mesh: each of the scene's own meshes is asked."""
    import trimesh

    if _has_uv(mesh):
        return True
    if path.suffix.lower() not in (".glb", ".gltf"):
        return False
    scene = trimesh.load(path, process=False)  # read once already: it loads
    return any(_has_uv(g) for g in (scene.geometry.values() if isinstance(scene, trimesh.Scene) else [scene]))


def read_unwrap_json(out: str | os.PathLike) -> dict:
    """``OUT/unwrap.json``, or ``InputError`` naming the file."""
    import json

    path = Path(out) / UNWRAP_JSON
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read {path}: {exc}") from None


def unwrap_harness_context(out: str | os.PathLike, info: dict | None = None,
                           inp: UnwrapInput | None = None) -> dict:
    """The harness's keyword arguments for an unwrap folder: the input mesh as the reference
    (its own vertex list, so its open borders are its real boundary) in the fit's unit ball.
    ``info`` / ``inp``: the folder's unwrap.json and input, when the caller already read them."""
    import trimesh

    from mnacore.frame import Normalization

    info = info if info is not None else read_unwrap_json(out)
    inp = inp if inp is not None else load_unwrap_input(info["input"])
    norm = Normalization(np.asarray(info["normalization"]["center"], np.float64),
                         float(info["normalization"]["scale"]))
    return {"reference": trimesh.Trimesh(inp.vertices, inp.faces, process=False), "normalization": norm,
            "reference_is_closed": False}


def _bake_source(inp: UnwrapInput):
    """The input as trimesh reads it by default, with its colours or texture (an OBJ read with
    its own vertex order, as unwrapping needs, loses its texture visuals)."""
    import trimesh

    try:
        mesh = trimesh.load(inp.path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types on unreadable files
        raise InputError(f"cannot read {inp.path} for --texture bake: {exc}") from None
    return mesh


def check_options(texture: str, size, padding) -> tuple[int, int]:
    """Validated ``(size, padding)``; raises ``InputError`` naming the option."""
    if texture not in TEXTURES:
        raise InputError(f"unknown texture {texture!r}; choose from {', '.join(TEXTURES)}")
    size = check_size(size)
    try:
        pad = int(str(padding).strip())
    except ValueError:
        raise InputError(f"--padding must be a non-negative integer, got {padding!r}") from None
    if pad < 0:
        raise InputError(f"--padding must be a non-negative integer, got {padding!r}")
    return size, pad


def _stage_bar(enabled: bool):
    """A callable: each call names the stage that starts (None: all done); a tqdm bar on stderr
    advancing a step per stage, or nothing when not ``enabled``."""
    import sys

    from tqdm.auto import tqdm

    from .unwrap import STAGES

    bar = tqdm(total=len(STAGES) + 3, desc="unwrap", unit="stage", file=sys.stderr, leave=False,
               disable=not enabled, dynamic_ncols=True)
    state = {"started": False, "closed": False}

    def step(name: str | None) -> None:
        if state["closed"]:
            return
        if state["started"]:
            bar.update(1)
        state["started"] = True
        if name is None:
            state["closed"] = True
            bar.close()
        else:
            bar.set_postfix_str(name)

    def note(text: str) -> None:  # a stage's own progress (the merge's rounds, the packing search's steps): same step, new text
        if not state["closed"]:
            bar.set_postfix_str(text)

    step.note = note
    return step


def unwrap_to_folder(inp: UnwrapInput, run: str | os.PathLike, out: str | os.PathLike, texture: str = "checker",
                     size: int | str = 2048, padding: int | str = 8, square_size: float | None = None,
                     cfg: UnwrapConfig | None = None, extra: dict | None = None, progress: bool = False) -> dict:
    """Unwrap ``inp`` with ``RUN``'s charts into ``OUT``; returns the ``unwrap.json`` content.
    ``progress``: a bar on stderr that advances stage by stage (:data:`texture.unwrap.STAGES`,
    then texture, write, measure), naming the stage running."""
    size, pad = check_options(texture, size, padding)
    charts = load_charts(Path(run) / "charts.npz")
    bake_source = None
    if texture == "bake":
        bake_source = _bake_source(inp)
        source_colors(bake_source)  # fail before the slow part when there is nothing to bake
    cfg = cfg or UnwrapConfig()
    cfg.resolution, cfg.padding = size, pad
    bar = _stage_bar(progress)
    try:
        t0 = time.perf_counter()
        result = unwrap_mesh(inp.vertices, inp.faces, charts, cfg, progress=bar)
        t1 = time.perf_counter()
        bar("texture")
        norm = charts.normalization
        source = None
        if texture == "bake":
            source = bake_source.copy()
            source.vertices = norm.apply(bake_source.vertices)
        image = make_texture(texture, result.mesh.transformed(norm), size, pad, source, square_size)
        t2 = time.perf_counter()
        out = Path(out)
        bar("write")
        paths = export_textured(out, result.mesh, image)
        t3 = time.perf_counter()
        bar("measure")
        metrics = measure(result.mesh, reference=inp.mesh, normalization=norm)
        timings = {**{f"unwrap_{k}": v for k, v in result.stats.pop("timings").items()},
                   "unwrap_total": t1 - t0, "texture": t2 - t1, "write": t3 - t2, "harness": time.perf_counter() - t3}
        doc = {"input": str(Path(inp.path).resolve()), "run": str(Path(run).resolve()),
               "input_uv_replaced": inp.had_uv, "texture": texture, "size": size, "padding": pad,
               "normalization": norm.to_json(), "charts": charts.n_charts,
               **result.stats, "uv_metrics": metrics.summary, "timings": timings, "machine": cpu_summary(),
               "files": paths,
               **(extra or {})}
    finally:
        bar(None)  # closes the bar, also when a stage fails (the error line then stands alone)
    write_json(out / UNWRAP_JSON, doc)
    return doc
