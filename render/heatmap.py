"""Per-face distortion heat maps and per-chart colours, with a colour scale shared across methods.

Values come from the one UV-metrics harness (``texture.harness``): per-face
``metric`` / ``conformal`` / ``area`` distortion (each a per-face decomposition of the
DESIGN aggregate, 0 for an isometry up to scale) and UV islands for ``charts``.

Shared scale: for one figure, ``shared_range`` takes the per-face values of *every*
method (ours, xatlas) and sets ``vmax`` to a high percentile of all of them together,
so one colour means one distortion value in every panel and one colour bar serves all.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mnacore.atomic import atomic_path
from render.meshes import UVMesh
from render.textures import chart_colors, hue_palette

HEATMAP_KINDS = ("metric", "conformal", "area", "charts")
#: colour of faces whose distortion is undefined (zero UV area -> NaN)
NAN_COLOR = (0.5, 0.5, 0.5)
#: above this many charts a 20-colour categorical map would repeat too often
MAX_CATEGORICAL = 20


@dataclass(frozen=True)
class HeatRange:
    """Colour scale of a distortion heat map: ``vmin`` maps to the bottom of ``cmap``."""

    vmin: float
    vmax: float
    cmap: str = "viridis"


def _harness():
    try:
        from texture import harness
    except ImportError as exc:  # pragma: no cover - texture ships with the project
        raise RuntimeError(f"heat maps need the UV-metrics harness texture.harness ({exc})") from None
    return harness


def face_values(mesh: UVMesh, kind: str) -> np.ndarray:
    """(F,) per-face value: distortion ``kind`` (float, NaN where undefined) or chart id (``charts``)."""
    if kind not in HEATMAP_KINDS:
        raise ValueError(f"--heatmap: unknown kind {kind!r}; choose from {', '.join(HEATMAP_KINDS)}")
    if mesh.uv is None:
        raise ValueError(f"mesh {mesh.name!r} has no UVs: a {kind} heat map needs a UV-mapped mesh")
    harness = _harness()
    if kind == "charts":
        return np.asarray(harness.uv_islands(mesh.faces, mesh.uv), np.int64)
    return np.asarray(harness.per_face_distortions(mesh.vertices, mesh.faces, mesh.uv)[kind], np.float64)


def shared_range(values: list[np.ndarray], percentile: float = 95.0, cmap: str = "viridis") -> HeatRange:
    """One scale for all methods: ``[0, percentile of all finite values]`` (``vmax > 0``)."""
    finite = np.concatenate([np.asarray(v, np.float64)[np.isfinite(v)] for v in values] or [np.zeros(0)])
    vmax = float(np.percentile(finite, percentile)) if finite.size else 1.0
    return HeatRange(0.0, vmax if vmax > 0 else 1.0, cmap)


def distortion_colors(values: np.ndarray, scale: HeatRange) -> np.ndarray:
    """(F, 3) sRGB colours of per-face values on ``scale`` (clipped; NaN -> ``NAN_COLOR``)."""
    from matplotlib import colormaps

    t = (np.asarray(values, np.float64) - scale.vmin) / (scale.vmax - scale.vmin)
    rgb = np.asarray(colormaps[scale.cmap](np.clip(np.nan_to_num(t, nan=0.0), 0, 1))[:, :3], np.float32)
    rgb[~np.isfinite(values)] = NAN_COLOR
    return rgb


def island_colors(ids: np.ndarray, cmap: str = "tab20") -> np.ndarray:
    """(F, 3) sRGB colour per face from its chart id (categorical; golden-ratio hues past 20)."""
    ids = np.asarray(ids, np.int64)
    n = int(ids.max()) + 1 if ids.size else 0
    palette = chart_colors(n, cmap) if n <= MAX_CATEGORICAL else hue_palette(n)
    return palette[ids]


def colorbar_png(path: str | Path, scale: HeatRange, label: str, width_in: float = 4.0) -> None:
    """A horizontal colour bar for ``scale`` as a small PNG (matplotlib, atomic)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    fig, ax = plt.subplots(figsize=(width_in, 0.6), dpi=150)
    fig.subplots_adjust(left=0.05, right=0.95, bottom=0.55, top=0.95)
    bar = fig.colorbar(ScalarMappable(Normalize(scale.vmin, scale.vmax), scale.cmap), cax=ax,
                       orientation="horizontal", extend="max")
    bar.set_label(label, fontsize=7)
    bar.ax.tick_params(labelsize=6)
    with atomic_path(path) as tmp:
        fig.savefig(tmp)
    plt.close(fig)
