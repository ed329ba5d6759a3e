"""Figure grids of renders (matplotlib): rows = methods, columns = views or shapes (runs).

``make_figure([RUN])`` lays out one run's views; ``make_figure([RUN1, RUN2, ...])`` one
column per run (shape) at a single view. Each cell shows
``RUN/renders/{method}/{prefix}{view}.png`` with a caption of the method's key numbers
from ``RUN/compare.json`` when present (charts, seam length, metric distortion). For
heat maps the colour bar uses the scale stored in ``RUN/renders/render.json``, which
``render_run`` shared across methods, so one bar serves a whole row set.

``compare.json`` is read leniently: the numbers of method ``m`` are the first mapping
found at ``data[m]``, ``data["methods"][m]`` or a list entry with ``"method": m``,
optionally under ``"summary"``; keys ``charts``, ``seam_length``, ``distortion_metric``.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mnacore.atomic import atomic_path
from render.images import read_image

#: caption fields: (compare.json key, label, format)
CAPTION_FIELDS = (("charts", "islands", "{:.0f}"), ("seam_length", "seam", "{:.2f}"),
                  ("distortion_metric", "dist.", "{:.3f}"))
VIEW_PREFERENCE = ("three_quarter", "front", "side", "top")


@dataclass
class FigureResult:
    png: Path
    pdf: Path | None
    rows: list[str]
    columns: list[str]


def _method_numbers(data, method: str) -> dict | None:
    """The compare.json mapping of ``method``'s numbers (see module docs), or None."""
    cands = []
    if isinstance(data, dict):
        cands += [data.get(method), (data.get("methods") or {}).get(method)
                  if isinstance(data.get("methods"), dict) else None]
        for key in ("rows", "methods", "table"):
            if isinstance(data.get(key), list):
                cands += [r for r in data[key] if isinstance(r, dict) and r.get("method") == method]
    elif isinstance(data, list):
        cands += [r for r in data if isinstance(r, dict) and r.get("method") == method]
    for c in cands:
        if isinstance(c, dict):
            return c.get("summary") if isinstance(c.get("summary"), dict) else c
    return None


def caption(run_dir: Path, method: str) -> str:
    """``charts 12 · seam 3.41 · dist. 0.052`` from ``RUN/compare.json``, or '' when absent."""
    path = Path(run_dir) / "compare.json"
    if not path.is_file():
        return ""
    try:
        nums = _method_numbers(json.loads(path.read_text()), method)
    except (json.JSONDecodeError, OSError):
        return ""
    if not nums:
        return ""
    parts = []
    for key, label, fmt in CAPTION_FIELDS:
        v = nums.get(key)
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            parts.append(f"{label} {fmt.format(v)}")
    return " · ".join(parts)


def _views(run_dir: Path, method: str, prefix: str) -> list[str]:
    folder = Path(run_dir) / "renders" / method
    rec = folder / "render.json"
    if rec.is_file():
        keys = json.loads(rec.read_text()).get("images", {})
        return [k[len(prefix):] for k in keys if k.startswith(prefix) and not k[len(prefix):].startswith(
            ("heat_", "preview_"))]
    return []


def _pick_view(views: list[str]) -> str:
    for v in VIEW_PREFERENCE:
        if v in views:
            return v
    return views[0]


def _heat_range(run_dir: Path, kind: str):
    rec = Path(run_dir) / "renders" / "render.json"
    if not rec.is_file():
        return None
    return json.loads(rec.read_text()).get("heat_ranges", {}).get(kind)


def _layout(runs: list[Path], rows: list[str], prefix: str, image: str, view: str | None):
    """The grid: ``cells[i][j] = (run, method, view)`` and the column titles. One run: a
    column per view; several runs: a column per run at one view."""
    if len(runs) == 1:
        views = _views(runs[0], rows[0], prefix)
        if not views:
            raise ValueError(f"{runs[0]}/renders/{rows[0]} has no {image} renders")
        cols = [view] if view else views
        return [[(runs[0], m, v) for v in cols] for m in rows], [v.replace("_", " ") for v in cols]
    cells = [[(r, m, view or _pick_view(_views(r, m, prefix) or ["front"])) for r in runs] for m in rows]
    return cells, [r.name for r in runs]


def _draw_cell(ax, png: Path, cap: str | None, title: str | None, ylabel: str | None, several_runs: bool) -> None:
    ax.set_xticks([]), ax.set_yticks([])
    for s in ax.spines.values():
        s.set_visible(False)
    if png.is_file():
        ax.imshow(np.clip(read_image(png)[..., :3], 0, 1), interpolation="lanczos")
    else:
        ax.text(0.5, 0.5, "missing", ha="center", va="center", transform=ax.transAxes, color="0.5")
    if cap and several_runs:
        ax.set_xlabel(cap, fontsize=7)
    if title is not None:
        ax.set_title(title, fontsize=9)
    if ylabel is not None:
        ax.set_ylabel(ylabel, fontsize=9)


def _check_request(runs: list[Path], out: Path, rows, prefix: str) -> list[str]:
    if not runs:
        raise ValueError("figure: give at least one run folder")
    for r in runs:
        if not (r / "renders").is_dir():
            raise ValueError(f"{r} has no renders/; run `mna render {r}` first")
    if out.suffix.lower() != ".png":
        raise ValueError(f"-o: the figure is written as PNG; give a .png path, got {out.name!r}")
    rows = [m for m in rows if any((r / "renders" / m).is_dir() for r in runs)]
    if not rows:
        raise ValueError(f"figure: none of the rows' methods have renders in {', '.join(map(str, runs))}")
    return rows


def make_figure(run_dirs: list[str | Path], out: str | Path, rows: tuple[str, ...] = ("mna", "xatlas"),
                image: str = "texture", view: str | None = None, pdf: bool = False,
                cell_inches: float = 2.4, dpi: int = 200) -> FigureResult:
    """Compose renders into a labelled grid PNG (and a vector PDF with ``pdf``).

    ``image``: ``texture`` (the textured renders), ``heat_metric`` / ``heat_conformal`` /
    ``heat_area`` / ``heat_charts``, or ``preview``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    runs, out = [Path(r) for r in run_dirs], Path(out)
    prefix = "" if image == "texture" else f"{image}_"
    rows = _check_request(runs, out, rows, prefix)
    cells, col_titles = _layout(runs, rows, prefix, image, view)
    heat = _heat_range(runs[0], image[5:]) if image.startswith("heat_") and image != "heat_charts" else None
    n_r, n_c = len(rows), len(col_titles)
    fig, axes = plt.subplots(n_r, n_c, figsize=(cell_inches * n_c, cell_inches * n_r + (0.6 if heat else 0.3)),
                             squeeze=False, layout="constrained")
    fig.get_layout_engine().set(w_pad=0.02, h_pad=0.02, wspace=0.01, hspace=0.01)
    for i, method in enumerate(rows):
        for j, (run, m, v) in enumerate(cells[i]):
            cap = caption(run, m)
            # one line per number: a single rotated line overflows a row's height
            one_run_cap = "\n" + cap.replace(" · ", "\n") if cap and len(runs) == 1 else ""
            _draw_cell(axes[i][j], run / "renders" / m / f"{prefix}{v}.png", cap,
                       col_titles[j] if i == 0 else None, f"{method}{one_run_cap}" if j == 0 else None,
                       len(runs) > 1)
    if heat:
        bar = fig.colorbar(ScalarMappable(Normalize(heat["vmin"], heat["vmax"]), heat["cmap"]), ax=axes,
                           location="bottom", shrink=0.5, aspect=40, extend="max")
        bar.set_label(f"{image[5:]} distortion per face (scale shared by all rows)", fontsize=7)
        bar.ax.tick_params(labelsize=6)
    if image == "heat_charts":  # categorical colours: say so, there is no scale to show
        fig.supxlabel("one colour per UV island (categorical, not a scale)", fontsize=7)
    with atomic_path(out) as tmp:
        fig.savefig(tmp, dpi=dpi, bbox_inches="tight", pad_inches=0.05)
    pdf_path = None
    if pdf:
        pdf_path = out.with_suffix(".pdf")
        with atomic_path(pdf_path) as tmp:
            fig.savefig(tmp, bbox_inches="tight", pad_inches=0.05)
    plt.close(fig)
    return FigureResult(out, pdf_path, list(rows), list(col_titles))
