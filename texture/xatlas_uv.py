"""UV-map any triangle mesh with xatlas (segmentation + parametrisation + packing).

The mesh is handed to xatlas in the unit-ball frame (so ``max_chart_area`` and
``max_boundary_length`` are in that frame); the result uses the input positions.
xatlas normalises its UVs by the atlas's width and height, which stretches them when
the atlas is not square; we undo that (``uv * (w, h) / max(w, h)``), so the UVs are
isotropic in texels and fit a square texture of ``max(w, h)`` texels.

**Held to the resolution asked for.** With a ``resolution`` and no ``texels_per_unit``,
xatlas picks the scale itself and only approximates the resolution (its estimate leaves the
gutters out): on the benchmark meshes its atlas came out 2256-3090 texels wide for 2048
asked, 2932 on 2,000 small cards, 1275 on 300 of them. The texture is ``resolution`` texels,
so there every gutter shrinks or widens by that ratio (8 texels became 5.6 on the 2,000
cards: seams bleed once the texture is filtered) and the layout's utilisation is counted
with gutters other than those asked for, where ours keeps them. So where the atlas comes
out another size, xatlas's own charts are packed again by xatlas's packer
(:func:`texture.placement.xatlas_pack`, the stage ``generate`` ends with) at exactly the
resolution, at the largest scale at which one atlas holds them all (bracketed by
:data:`HOLD_STEP`, bisected to :data:`HOLD_TOL`). Charts and seams do not change;
distortion moves only by xatlas's snapping of each chart to whole texels at the new scale
(the milk truck 0.0073 -> 0.0130). ``seconds`` stays ``generate``'s time (xatlas's own
speed, as it is compared with ours); ``seconds_total`` and ``calls`` count the packings
after it.
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import numpy as np

from mnacore.errors import InputError
from mnacore.frame import unit_ball_normalization
from mnacore.triangles import triangle_areas
from mnacore.uvmesh import UVMesh, make_uv_mesh, weld_ids


@dataclass
class XatlasOptions:
    """The xatlas options exposed by ``mna uv`` (xatlas's defaults unless noted)."""

    max_cost: float = 2.0
    """Chart growth stops when the cost of adding a face exceeds this (larger = fewer charts)."""
    max_iterations: int = 1
    """Chart segmentation refinement iterations."""
    max_chart_area: float = 0.0
    """Largest chart area, unit-ball frame (0 = no limit)."""
    max_boundary_length: float = 0.0
    """Largest chart boundary length, unit-ball frame (0 = no limit)."""
    normal_deviation_weight: float = 2.0
    roundness_weight: float = 0.01
    straightness_weight: float = 6.0
    normal_seam_weight: float = 4.0
    texture_seam_weight: float = 0.5
    resolution: int = 2048
    """Target atlas size in texels (ours; xatlas's default 0 picks one from the area)."""
    padding: int = 8
    """Texels of gutter around each chart (ours; xatlas's default is 0)."""
    texels_per_unit: float = 0.0
    """0 = estimated by xatlas from ``resolution``."""
    bilinear: bool = True
    brute_force: bool = False
    rotate_charts: bool = True
    normalize: bool = True
    """Hand xatlas the mesh in the unit-ball frame (its segmentation depends on the mesh's units)."""

    def validate(self) -> "XatlasOptions":
        if not (np.isfinite(self.max_cost) and self.max_cost > 0):
            raise InputError(f"--max-cost must be a positive number, got {self.max_cost}")
        if int(self.max_iterations) < 1:
            raise InputError(f"--max-iterations must be >= 1, got {self.max_iterations}")
        if int(self.resolution) != 0 and int(self.resolution) < 16:
            raise InputError(f"--resolution must be 0 (automatic) or an integer >= 16, got {self.resolution}")
        if int(self.padding) < 0:
            raise InputError(f"--padding must be >= 0, got {self.padding}")
        return self


#: scale step while the largest scale that fits is bracketed, bisection's stopping width, and
#: the most packings (past them xatlas's own atlas stands)
HOLD_STEP, HOLD_TOL, HOLD_TRIES = 1.05, 0.005, 24


@dataclass
class XatlasResult:
    """Output of :func:`unwrap`.

    Attributes:
        mesh: split-vertex UV mesh in the input frame, UVs in [0,1]^2 (isotropic).
        vmapping: (V',) input vertex of each output vertex.
        charts: xatlas's chart count.
        atlas_size: (width, height) in texels.
        utilization: xatlas's own utilisation (of width x height).
        seconds: time of ``generate`` (segmentation + parametrisation + packing).
        seconds_total: that and the packings that held the atlas to the resolution (module
            docstring).
        calls: xatlas calls made: ``generate`` and those packings.
    """

    mesh: UVMesh
    vmapping: np.ndarray
    charts: int
    atlas_size: tuple[int, int]
    utilization: float
    seconds: float
    options: dict
    seconds_total: float = 0.0
    calls: int = 1

    def record(self) -> dict:
        """The fields every xatlas record carries (``mna uv``'s and ``mna compare``'s
        ``metrics.json``): charts, atlas size, utilisation, packings after ``generate``, times."""
        return {"xatlas_charts": self.charts, "xatlas_atlas_size": list(self.atlas_size),
                "xatlas_utilization": self.utilization, "xatlas_packings_after": self.calls - 1,
                "timings": {"xatlas": self.seconds, "xatlas_total": self.seconds_total}}


def check_mesh(vertices: np.ndarray, faces: np.ndarray, name: str = "mesh") -> None:
    """Reject degenerate faces (zero area or a repeated vertex) and non-manifold edges.

    Positions are welded first, so seam duplicates do not count as boundaries.
    """
    vertices = np.asarray(vertices, np.float64)
    faces = np.asarray(faces, np.int64)
    if len(faces) == 0:
        raise InputError(f"{name} has no faces")
    ids = weld_ids(vertices)
    f = ids[faces]
    repeated = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])
    area = triangle_areas(vertices, faces)
    diag = float(np.linalg.norm(vertices.max(0) - vertices.min(0)))
    degenerate = repeated | (area <= 1e-14 * diag * diag)
    if degenerate.any():
        raise InputError(f"{name} has {int(degenerate.sum())} degenerate face(s) (zero area or a repeated vertex), "
                         f"first: face {int(np.argmax(degenerate))}")
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    if (counts > 2).any():
        raise InputError(f"{name} is non-manifold: {int((counts > 2).sum())} edge(s) shared by more than two faces")


#: XatlasOptions field -> (xatlas ChartOptions / PackOptions attribute, type)
CHART_OPTIONS = {"max_cost": ("max_cost", float), "max_iterations": ("max_iterations", int),
                 "max_chart_area": ("max_chart_area", float), "max_boundary_length": ("max_boundary_length", float),
                 "normal_deviation_weight": ("normal_deviation_weight", float),
                 "roundness_weight": ("roundness_weight", float), "straightness_weight": ("straightness_weight", float),
                 "normal_seam_weight": ("normal_seam_weight", float),
                 "texture_seam_weight": ("texture_seam_weight", float)}
PACK_OPTIONS = {"resolution": ("resolution", int), "padding": ("padding", int),
                "texels_per_unit": ("texels_per_unit", float), "bilinear": ("bilinear", bool),
                "brute_force": ("bruteForce", bool), "rotate_charts": ("rotate_charts", bool)}


def _set_options(target, opts: XatlasOptions, spec: dict):
    """``target`` (an xatlas options object) with every field of ``spec`` copied from ``opts``."""
    for name, (attr, kind) in spec.items():
        setattr(target, attr, kind(getattr(opts, name)))
    return target


def unwrap(vertices: np.ndarray, faces: np.ndarray, options: XatlasOptions | None = None,
           check: bool = True) -> XatlasResult:
    """UV-map ``(vertices (V,3), faces (F,3))`` with xatlas; see the module docstring."""
    import xatlas

    opts = (options or XatlasOptions()).validate()
    vertices = np.asarray(vertices, np.float64)
    faces = np.asarray(faces, np.int64)
    if check:
        check_mesh(vertices, faces)
    norm = unit_ball_normalization(vertices[np.unique(faces)])
    positions = norm.apply(vertices) if opts.normalize else vertices
    co = _set_options(xatlas.ChartOptions(), opts, CHART_OPTIONS)
    po = _set_options(xatlas.PackOptions(), opts, PACK_OPTIONS)
    atlas, seconds = _generate(positions, faces, co, po)
    if atlas.atlas_count != 1:
        raise InputError(f"xatlas made {atlas.atlas_count} atlases; raise --resolution or lower --padding")
    vmap, idx, uv = atlas[0]
    w, h = int(atlas.width), int(atlas.height)
    uv = uv.astype(np.float64) * np.array([w, h])  # texels
    idx, vmap = idx.astype(np.int64), vmap.astype(np.int64)
    total, calls, utilization = seconds, 1, float(atlas.utilization)
    if opts.resolution > 0 and opts.texels_per_unit == 0 and max(w, h) != opts.resolution:
        t0 = time.perf_counter()
        held, packings = _held(uv, idx, opts)
        total, calls = total + time.perf_counter() - t0, calls + packings
        if held is not None:
            held_vmap, held_idx, held_uv = held[0]
            w = h = int(opts.resolution)
            uv, idx, vmap = held_uv.astype(np.float64) * w, held_idx.astype(np.int64), vmap[held_vmap]
            utilization = float(held.utilization)
    mesh = make_uv_mesh(vertices[vmap], idx, uv / max(w, h), name="xatlas output")
    return XatlasResult(mesh, vmap, int(atlas.chart_count), (w, h), utilization, seconds, asdict(opts), total, calls)


def _held(px: np.ndarray, faces: np.ndarray, opts: XatlasOptions):
    """(xatlas's atlas of its charts ``(px (V, 2) texels, faces)`` packed at exactly
    ``opts.resolution`` at the largest scale where one atlas holds them, or None where none
    within ``HOLD_TRIES`` packings does; the packings made): see the module docstring."""
    from .harness import uv_islands
    from .placement import xatlas_pack
    from .scale_search import largest_fit

    island = uv_islands(faces, px)
    res, pad = int(opts.resolution), int(opts.padding)
    extra = {"bilinear": bool(opts.bilinear), "bruteForce": bool(opts.brute_force),
             "rotate_charts": bool(opts.rotate_charts)}

    def pack(scale):
        a = xatlas_pack(px, faces, island, res, pad, scale, extra)
        return a if a.atlas_count == 1 else None

    side = float(np.ptp(px, axis=0).max()) or 1.0
    fit, calls = largest_fit(pack, res / side, 1 / HOLD_STEP, HOLD_TOL, HOLD_TRIES)
    return (None if fit is None else fit[1]), calls


def _generate(positions: np.ndarray, faces: np.ndarray, chart_options, pack_options):
    """(xatlas's atlas of the mesh, seconds of its ``generate``)."""
    import xatlas

    atlas = xatlas.Atlas()
    atlas.add_mesh(positions.astype(np.float32), faces.astype(np.uint32))
    t0 = time.perf_counter()
    atlas.generate(chart_options, pack_options)
    return atlas, time.perf_counter() - t0
