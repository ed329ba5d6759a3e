"""Render UV-mapped meshes and run folders: textures, heat maps, previews, scene files, metrics.

``render_mesh`` renders one mesh into a folder; ``render_run`` renders a run folder's
``mesh.obj`` (ours) and ``xatlas/mesh.obj`` with one framing (bounding sphere of the
first mesh), one 3D checker square size and one heat-map scale, so the two are
directly comparable. Layout of a render folder ``OUT/``::

    {view}.png / .exr               textured render (8-bit sRGB / linear RGBA radiance)
    heat_{kind}_{view}.png / .exr   heat map (metric, conformal, area distortion, or charts)
    preview_{view}.png              pyrender preview (--preview)
    colorbar_{kind}.png             colour bar of a distortion heat map (shared scale)
    scene/                          Mitsuba scene files: {view}.xml, heat_{kind}_{view}.xml,
                                    mesh.ply, heat_{kind}.ply, texture.png
    render.json                     what was rendered how: variant, spp, timings, scales

Every input is validated before the first file is written, and every file is written
atomically, so bad input leaves nothing behind and an interrupt nothing half-written.
"""
from __future__ import annotations

import dataclasses
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mnacore.atomic import atomic_path, write_json
from mnacore.frame import far_from_origin
from render import heatmap as H
from render.backend import VariantChoice, choose_variant, import_mitsuba
from render.images import read_image, to_display, write_exr, write_png
from render.meshes import (
    UVMesh,
    double_sided_render_mesh,
    load_uv_mesh,
    reversed_twins,
    unshare,
    vertex_normals,
    write_ply,
)
from render.mitsuba_scene import (
    material_bitmap,
    material_plain,
    material_procedural_checker,
    material_vertex_colors,
    render_dict,
    scene_dict,
    scene_xml,
)
from scenes.cameras import BoundingSphere, Camera, bounding_sphere, camera_rig, world_frame
from scenes.presets import Preset, load_preset, preset_to_dict
from texture.textures import checker_image, squares_per_uv_unit, uv_grid_image

TEXTURES = ("checker", "uvgrid", "bake", "procedural", "none")
DEFAULT_VIEWS = ("front", "side", "top", "three_quarter")
#: (label, path relative to RUN/) of the meshes ``render_run`` renders, in order
RUN_MESHES = (("mna", "mesh.obj"), ("xatlas", "xatlas/mesh.obj"))


@dataclass(frozen=True)
class RenderOptions:
    """What to render and how (the ``mna render`` options)."""

    views: tuple[str, ...] | None = None
    """preset view names; None = ``DEFAULT_VIEWS`` (those the preset has)."""
    turntable: int | None = None
    """N views around the up axis instead of ``views``."""
    spp: int = 128
    """Mitsuba samples per pixel."""
    res: int = 1024
    """image side in pixels (square images)."""
    texture: str = "checker"
    """checker | uvgrid | bake (the mesh's own texture) | procedural (Mitsuba checkerboard) | none."""
    heatmaps: tuple[str, ...] = ()
    """extra heat-map renders: metric, conformal, area, charts."""
    preview: bool = False
    """also write pyrender previews with the same cameras."""
    variant: str | None = None
    """Mitsuba variant; None = best available (cuda, llvm, scalar)."""
    preset: str | Preset | None = None
    """built-in preset name, a YAML/JSON file, or a ``Preset``; None = studio."""
    seed: int = 0
    heat_max: float | None = None
    """fix the top of the distortion colour scale (to share it across runs)."""
    progress: bool = True

    def validate(self) -> None:
        if isinstance(self.spp, bool) or not isinstance(self.spp, int) or self.spp < 1:
            raise ValueError(f"--spp: expected a positive integer, got {self.spp!r}")
        if isinstance(self.res, bool) or not isinstance(self.res, int) or not 8 <= self.res <= 16384:
            raise ValueError(f"--res: expected an integer in [8, 16384], got {self.res!r}")
        if self.texture not in TEXTURES:
            raise ValueError(f"--texture: unknown texture {self.texture!r}; choose from {', '.join(TEXTURES)}")
        for k in self.heatmaps:
            if k not in H.HEATMAP_KINDS:
                raise ValueError(f"--heatmap: unknown kind {k!r}; choose from {', '.join(H.HEATMAP_KINDS)}")
        if self.turntable is not None and self.views:
            raise ValueError("--views and --turntable cannot be used together")
        if self.turntable is not None and not 1 <= self.turntable <= 720:
            raise ValueError(f"--turntable: expected 1..720 views, got {self.turntable}")
        if self.heat_max is not None and not self.heat_max > 0:
            raise ValueError(f"--heat-max: expected > 0, got {self.heat_max}")


@dataclass(frozen=True)
class Framing:
    """What two renders must share to be comparable: cameras, ground height, checker size."""

    sphere: BoundingSphere
    lowest: float
    """smallest coordinate along the preset's up axis (ground plane height)."""
    square_size: float
    """3D side of one checker square."""


def framing_for(mesh: UVMesh, preset: Preset) -> Framing:
    sphere = bounding_sphere(mesh.vertices)
    _, up, _ = world_frame(preset.up, preset.front)
    return Framing(sphere, float((mesh.vertices @ up).min()),
                   2.0 * sphere.radius / preset.material.checker_squares)


def near_origin(mesh: UVMesh, framing: Framing, preset: Preset) -> tuple[UVMesh, Framing]:
    """``mesh`` and ``framing`` moved so that the framing's centre is the origin, where the
    framing is far from the origin for its size (:func:`mnacore.frame.far_from_origin`).

    Mitsuba and OpenGL hold positions in float32. At map coordinates (5e6) float32 steps by
    0.5, and a unit sphere rendered as stepped slabs. A translation of mesh, cameras, lights
    and ground together leaves every image the same. Elsewhere the mesh is kept as it is.
    """
    c, r = framing.sphere.center, framing.sphere.radius
    if not far_from_origin(float(np.abs(c).max()) + r, 2 * r):
        return mesh, framing
    _, up, _ = world_frame(preset.up, preset.front)
    return (dataclasses.replace(mesh, vertices=mesh.vertices - c),
            Framing(BoundingSphere(np.zeros(3), r), framing.lowest - float(c @ up), framing.square_size))


@dataclass
class MeshRender:
    """Result of ``render_mesh``: the images and scene files written, and how."""

    out_dir: Path
    label: str
    variant: str
    images: dict[str, Path] = field(default_factory=dict)
    """``{view}``, ``heat_{kind}_{view}``, ``preview_{view}`` -> PNG path."""
    scenes: dict[str, Path] = field(default_factory=dict)
    """same keys (Mitsuba renders only) -> scene XML path."""
    seconds: dict[str, float] = field(default_factory=dict)
    """Mitsuba render seconds per image key."""
    checker_frequency: float | None = None
    heat_ranges: dict[str, H.HeatRange] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)


def check_mesh(mesh: UVMesh, opts: RenderOptions) -> None:
    """Raise a clear ``ValueError`` if ``mesh`` cannot be rendered as asked."""
    needs_uv = opts.texture in ("checker", "uvgrid", "bake", "procedural") or opts.heatmaps
    if needs_uv and mesh.uv is None:
        what = f"--texture {opts.texture}" if opts.texture != "none" else f"--heatmap {opts.heatmaps[0]}"
        raise ValueError(f"mesh {mesh.name!r} has no UVs but {what} needs a UV-mapped mesh "
                         "(UV-map it with `mna export`, or use --texture none)")
    if opts.texture == "bake":
        if mesh.texture is None:
            raise ValueError(f"mesh {mesh.name!r} names no texture image (no map_Kd in its .mtl); "
                             "--texture bake needs one")
        if not mesh.texture.is_file():
            raise ValueError(f"texture file not found: {mesh.texture}")


def _texture_files(mesh: UVMesh, geometry: tuple[UVMesh, np.ndarray], opts: RenderOptions, preset: Preset,
                   framing: Framing, scene_dir: Path) -> tuple[dict, float | None]:
    """Write the mesh PLY (``geometry``: :func:`_render_geometry`) + texture PNG into
    ``scene_dir``; return (material, checker frequency)."""
    render, normals = geometry
    write_ply(scene_dir / "mesh.ply", render.vertices, render.faces, render.uv, normals)
    mat = preset.material
    if opts.texture == "none":
        return material_plain(mat.base_color), None
    freq = squares_per_uv_unit(mesh.vertices, mesh.faces, mesh.uv, framing.square_size)
    if opts.texture == "procedural":
        return material_procedural_checker(freq, mat.checker_colors), freq
    if opts.texture == "bake":
        image = read_image(mesh.texture)
        image = np.repeat(image, 3, axis=2) if image.shape[2] == 1 else image[..., :3]
        freq = None
    elif opts.texture == "checker":
        image = checker_image(freq, mat.texture_size, mat.checker_colors)
    else:
        image = uv_grid_image(freq, mat.texture_size)
    write_png(scene_dir / "texture.png", image)
    return material_bitmap("texture.png"), freq


#: how far each side of a double-sided surface is moved out along its own normal for the
#: render, in bounding-sphere radii: a twentieth of a pixel at 1024 pixels across the sphere
#: (:func:`render.meshes.double_sided_render_mesh`)
TWIN_GAP = 1e-4


def _render_geometry(mesh: UVMesh, framing: Framing) -> tuple[UVMesh, np.ndarray]:
    """(the mesh to write, its normals per vertex): as it is with smooth vertex normals, or,
    where faces lie on reversed copies of themselves, the sides moved apart and each corner
    normal of its own side (:func:`render.meshes.double_sided_render_mesh`). Either way face
    ``i`` of the result is face ``i`` of the mesh."""
    twins = reversed_twins(mesh.vertices, mesh.faces)
    if not twins.any():
        return mesh, vertex_normals(mesh.vertices, mesh.faces)
    return double_sided_render_mesh(mesh, twins, TWIN_GAP * framing.sphere.radius)


def _heat_files(geometry: tuple[UVMesh, np.ndarray], kind: str, values: np.ndarray, scale: H.HeatRange | None,
                preset: Preset, scene_dir: Path) -> None:
    from render.images import srgb_to_linear

    colors = (H.island_colors(values, preset.heatmap.chart_cmap) if kind == "charts"
              else H.distortion_colors(values, scale))
    render, normals = geometry
    flat = unshare(render)
    write_ply(scene_dir / f"heat_{kind}.ply", flat.vertices, flat.faces, None, normals[render.faces.reshape(-1)],
              srgb_to_linear(np.repeat(colors, 3, axis=0)))


def _progress(items, enabled: bool, desc: str):
    if not enabled:
        return items
    from tqdm import tqdm

    return tqdm(items, desc=desc, unit="view", file=sys.stderr, leave=False)


def render_mesh(mesh: UVMesh | str | Path, out_dir: str | Path, opts: RenderOptions,
                framing: Framing | None = None, heat_values: dict[str, np.ndarray] | None = None,
                heat_ranges: dict[str, H.HeatRange] | None = None, label: str | None = None,
                variant: VariantChoice | None = None) -> MeshRender:
    """Render one UV-mapped mesh into ``out_dir`` (see the module docs for the layout).

    ``framing`` / ``heat_ranges`` come from ``render_run`` to share cameras, checker size
    and colour scales across meshes; by default they are this mesh's own.
    """
    opts.validate()
    preset = load_preset(opts.preset)
    mesh = load_uv_mesh(mesh) if not isinstance(mesh, UVMesh) else mesh
    check_mesh(mesh, opts)
    framing = framing or framing_for(mesh, preset)
    recorded = framing  # render.json says where the mesh is, not where it was rendered
    mesh, framing = near_origin(mesh, framing, preset)
    views = list(opts.views) if opts.views else [v for v in DEFAULT_VIEWS if v in preset.views] or None
    cameras = camera_rig(framing.sphere, preset, opts.res, opts.res,
                         None if opts.turntable else views, opts.turntable)
    if heat_values is None:
        heat_values = {k: H.face_values(mesh, k) for k in opts.heatmaps}
    heat_ranges = dict(heat_ranges or {})
    for k in opts.heatmaps:
        if k != "charts" and k not in heat_ranges:
            heat_ranges[k] = _heat_range([heat_values[k]], preset, opts)
    choice = variant or choose_variant(opts.variant)
    variant, warnings = choice.variant, [choice.warning] if choice.warning else []

    out_dir, label = Path(out_dir), label or mesh.name
    scene_dir = out_dir / "scene"
    result = MeshRender(out_dir, label, variant, warnings=warnings, heat_ranges=heat_ranges)
    geometry = _render_geometry(mesh, framing)  # once: the textured PLY and every heat map's
    material, result.checker_frequency = _texture_files(mesh, geometry, opts, preset, framing, scene_dir)
    jobs = [("", "mesh.ply", material)]
    for k in opts.heatmaps:
        _heat_files(geometry, k, heat_values[k], heat_ranges.get(k), preset, scene_dir)
        jobs.append((f"heat_{k}_", f"heat_{k}.ply", material_vertex_colors()))
        if k != "charts":
            H.colorbar_png(out_dir / f"colorbar_{k}.png", heat_ranges[k], f"{k} distortion (per face)")

    for cam in _progress(cameras, opts.progress, f"render {label}"):
        for prefix, ply, mat in jobs:
            key = f"{prefix}{cam.name}"
            scene = scene_dict(ply, mat, cam, framing.sphere, framing.lowest, preset, opts.spp)
            xml = scene_dir / f"{key}.xml"
            with atomic_path(xml) as tmp:
                tmp.write_text(scene_xml(scene))
            t0 = time.perf_counter()
            rgba = render_dict(scene, scene_dir, variant, opts.seed)
            result.seconds[key] = time.perf_counter() - t0
            write_exr(out_dir / f"{key}.exr", rgba)
            write_png(out_dir / f"{key}.png", to_display(rgba, preset.background))
            result.images[key], result.scenes[key] = out_dir / f"{key}.png", xml
    if opts.preview:
        _previews(mesh, cameras, opts, preset, framing, scene_dir, result)
    write_json(out_dir / "render.json", render_record(result, opts, preset, recorded))
    return result


def _heat_range(values: list[np.ndarray], preset: Preset, opts: RenderOptions) -> H.HeatRange:
    scale = H.shared_range(values, preset.heatmap.percentile, preset.heatmap.cmap)
    return dataclasses.replace(scale, vmax=opts.heat_max) if opts.heat_max else scale


def _previews(mesh: UVMesh, cameras: list[Camera], opts: RenderOptions, preset: Preset,
              framing: Framing, scene_dir: Path, result: MeshRender) -> None:
    from render.preview import PreviewRenderer, PreviewUnavailable, _pyrender, mesh_node

    texture = read_image(scene_dir / "texture.png") if (scene_dir / "texture.png").is_file() and \
        opts.texture in ("checker", "uvgrid", "bake") else None
    try:
        node = mesh_node(_pyrender(), mesh, texture, base_color=preset.material.base_color)
        renderer = PreviewRenderer(node, framing.sphere, framing.lowest, preset, opts.res, opts.res)
    except PreviewUnavailable as exc:
        msg = f"{exc}; skipping the preview (set PYOPENGL_PLATFORM=egl and install libegl1)"
        print(f"mna render: warning: {msg}", file=sys.stderr)
        result.warnings.append(msg)
        return
    try:
        for cam in cameras:
            key = f"preview_{cam.name}"
            t0 = time.perf_counter()
            image = renderer.render(cam)
            result.seconds[key] = time.perf_counter() - t0
            write_png(result.out_dir / f"{key}.png", image)
            result.images[key] = result.out_dir / f"{key}.png"
    finally:
        renderer.close()


def render_record(result: MeshRender, opts: RenderOptions, preset: Preset, framing: Framing) -> dict:
    """The ``render.json`` content: enough to reproduce and to caption the images."""
    mi = import_mitsuba()
    return {
        "label": result.label, "renderer": f"mitsuba {mi.__version__}", "variant": result.variant,
        "warnings": result.warnings, "options": {**dataclasses.asdict(opts), "preset": preset.name}, "preset": preset_to_dict(preset),
        "bounding_sphere": {"center": framing.sphere.center.tolist(), "radius": framing.sphere.radius},
        "checker_square_size": framing.square_size, "checker_squares_per_uv_unit": result.checker_frequency,
        "heat_ranges": {k: dataclasses.asdict(v) for k, v in result.heat_ranges.items()},
        "images": {k: p.name for k, p in result.images.items()},
        "scenes": {k: str(p.relative_to(result.out_dir)) for k, p in result.scenes.items()},
        "seconds": {k: round(v, 4) for k, v in result.seconds.items()},
    }


@dataclass
class RunRender:
    run_dir: Path
    variant: str
    meshes: dict[str, MeshRender]
    """label (``mna``, ``xatlas``) -> its render."""


def run_meshes(run_dir: str | Path) -> dict[str, Path]:
    """The UV meshes of a run folder that exist: ``{"mna": RUN/mesh.obj, "xatlas": RUN/xatlas/mesh.obj}``."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise ValueError(f"run folder not found: {run_dir}")
    found = {label: run_dir / rel for label, rel in RUN_MESHES if (run_dir / rel).is_file()}
    if not found:
        raise ValueError(f"{run_dir} has no mesh.obj nor xatlas/mesh.obj; run `mna export {run_dir}` first")
    return found


def render_run(run_dir: str | Path, opts: RenderOptions) -> RunRender:
    """Render ``RUN/mesh.obj`` and ``RUN/xatlas/mesh.obj`` comparably into ``RUN/renders/{label}/``.

    Shared: the framing (cameras, ground) and checker square size, from the first mesh
    found; the heat-map colour scale, from the per-face values of all meshes together.
    """
    opts.validate()
    preset = load_preset(opts.preset)
    meshes = {label: load_uv_mesh(path) for label, path in run_meshes(run_dir).items()}
    for mesh in meshes.values():
        check_mesh(mesh, opts)
    framing = framing_for(next(iter(meshes.values())), preset)
    values = {label: {k: H.face_values(m, k) for k in opts.heatmaps} for label, m in meshes.items()}
    ranges = {k: _heat_range([v[k] for v in values.values()], preset, opts)
              for k in opts.heatmaps if k != "charts"}
    choice = choose_variant(opts.variant)
    out = Path(run_dir) / "renders"
    results = {}
    for label, mesh in meshes.items():
        results[label] = render_mesh(mesh, out / label, opts, framing, values[label], ranges, label, choice)
    summary = {
        "variant": choice.variant, "warnings": [choice.warning] if choice.warning else [],
        "methods": {label: f"{label}/render.json" for label in results},
        "checker_square_size": framing.square_size,
        "heat_ranges": {k: dataclasses.asdict(v) for k, v in ranges.items()},
        "seconds_total": round(sum(sum(r.seconds.values()) for r in results.values()), 3),
    }
    write_json(out / "render.json", summary)
    return RunRender(Path(run_dir), choice.variant, results)
