"""``mna compare``: our atlas vs xatlas on the same mesh, every method through one harness.

Methods (rows of ``RUN/compare.md``):

- ``mna``: our packed atlas (``mna export``; built first if ``RUN/atlas.json`` is missing
  or older than ``charts.npz``);
- ``xatlas``: xatlas (defaults, our padding/resolution) on the *same* reconstructed mesh,
  written to ``RUN/xatlas/`` like an export;
- ``xatlas_input``: xatlas on the input mesh (when the input is a mesh), ``RUN/xatlas_input/``;
- ``sweep``: xatlas over ``max_cost`` x ``max_iterations`` (chart count vs distortion),
  on the input mesh when there is one (same surface, far fewer faces), else on the
  reconstruction.

Every row is measured by :func:`texture.harness.measure` with the same reference
(the input mesh when there is one) and the same unit-ball frame (charts.npz's).
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mnacore.atomic import write_json, write_text
from mnacore.charts import load_charts
from mnacore.errors import InputError

from .atlas_stats import RelaxStats
from .export import export_textured, read_back
from .harness import measure
from .pipeline import export_run, load_input, make_texture
from .xatlas_uv import XatlasOptions, unwrap

SWEEP_MAX_COST = (0.5, 2.0, 8.0, 64.0, 1e4)
SWEEP_MAX_ITERATIONS = (1, 4)
COLUMNS = (("charts", "islands", "{:d}"), ("seam_length", "seam length", "{:.2f}"),
           ("distortion_metric", "distortion metric", "{:.3f}"), ("distortion_conformal", "conformal", "{:.3f}"),
           ("distortion_area", "area", "{:.3f}"), ("flipped_area_percent", "flipped %", "{:.3f}"),
           ("mirrored_area_percent", "mirrored %", "{:.1f}"),
           ("folded_area_percent", "folded %", "{:.3f}"),
           ("orientation_undecided_area_percent", "undecided %", "{:.3f}"),
           ("uv_overlap_percent", "overlap %", "{:.3f}"),
           ("utilization", "utilization", "{:.2f}"))


@dataclass(frozen=True)
class ExportSummary:
    """What ``mna compare`` takes from ``RUN/atlas.json``, read once.

    Attributes:
        atlas: the ``atlas`` section as written (copied into compare.json unchanged).
        uv_seconds: the UV method's time: trim, orient, relax and pack.
        export_seconds: the whole export (atlas, texture, write).
        relax: the relaxation's stats.
    """

    atlas: dict
    uv_seconds: float
    export_seconds: float
    relax: RelaxStats

    @classmethod
    def read(cls, path: Path) -> ExportSummary:
        info = json.loads(Path(path).read_text())
        t = info["timings"]
        uv = t["atlas_trim"] + t.get("atlas_orient", 0.0) + t.get("atlas_relax", 0.0) + t["atlas_pack"]
        return cls(info["atlas"], uv, t["export_total"], RelaxStats.from_json(info["atlas"]))

    @property
    def islands(self) -> int:
        return self.atlas["islands"]

    def sentence(self) -> str:
        """compare.md's line on our atlas."""
        a = self.atlas
        return (f"Our atlas: {a['islands']} islands from {a['charts_used']} charts, doubly covered "
                f"{a['doubly_covered_percent']:.2f} % of the area (before trimming "
                f"{a['doubly_covered_percent_before']:.1f} %), F-score drop {a.get('fscore_drop', float('nan')):.2f} "
                "points." + _relax_sentence(self.relax))


def _fresh_export(run: Path) -> bool:
    atlas, charts, obj = run / "atlas.json", run / "charts.npz", run / "mesh.obj"
    return atlas.is_file() and obj.is_file() and atlas.stat().st_mtime >= charts.stat().st_mtime


def _row(method: str, mesh_name: str, summary: dict, seconds: float, extra: dict | None = None) -> dict:
    return {"method": method, "mesh": mesh_name, "seconds": seconds, **summary, **(extra or {})}


def _xatlas_row(method, mesh_name, vertices, faces, opts, folder, harness_kw, size, check):
    res = unwrap(vertices, faces, opts, check=check)
    norm = harness_kw["normalization"]
    record = res.record()
    timings = record.pop("timings")
    row_extra = {**record, "max_cost": opts.max_cost, "max_iterations": opts.max_iterations}
    if folder is not None:
        image = make_texture("checker", res.mesh.transformed(norm), size, opts.padding)
        export_textured(folder, res.mesh, image)
    m = measure(res.mesh, **harness_kw)
    if folder is not None:
        write_json(Path(folder) / "metrics.json", {"method": method, "options": res.options, "uv_metrics": m.summary,
                                                   "timings": timings, **row_extra})
    return _row(method, mesh_name, m.summary, res.seconds, row_extra)


def harness_context(run: str | os.PathLike) -> dict:
    """The harness's keyword arguments for every mesh of ``run``: one reference and one frame.

    Reference = the run's input mesh (its normals decide folds, its open boundary which
    borders are seams); without one, the surface is taken as closed (every island border
    is a seam: the reconstruction's charts do not share border vertices). Frame = the
    run's unit ball (``charts.npz``). ``mna compare`` and ``mna uv-metrics`` on a file of
    the run both use this, so they report the same numbers for the same file.
    """
    run = Path(run)
    if (run / "unwrap.json").is_file():  # an `mna unwrap` folder
        from .unwrap_run import unwrap_harness_context

        return unwrap_harness_context(run)
    mesh_in, _ = load_input(run)
    return {"reference": mesh_in, "normalization": load_charts(run / "charts.npz").normalization,
            "reference_is_closed": mesh_in is None}


def run_folder_of(mesh_path: str | os.PathLike) -> Path | None:
    """The run folder a mesh file belongs to (``RUN/mesh.obj``, ``RUN/xatlas/mesh.glb``), or None."""
    for folder in Path(mesh_path).resolve().parents[:2]:
        if (folder / "unwrap.json").is_file() or ((folder / "charts.npz").is_file()
                                                  and (folder / "config.yaml").is_file()):
            return folder
    return None


def compare_run(run: str | os.PathLike, sweep: bool = True, size: int = 2048, padding: int = 8) -> dict:
    """Write ``RUN/compare.json`` and ``RUN/compare.md`` (see module docstring); returns the JSON content."""
    run = Path(run)
    if not run.is_dir():
        raise InputError(f"run folder not found: {run}")
    charts = load_charts(run / "charts.npz")
    norm = charts.normalization
    if not _fresh_export(run):
        export_run(run, size=size, padding=padding)
    export = ExportSummary.read(run / "atlas.json")
    ours = read_back(run / "mesh.obj")
    harness_kw = harness_context(run)
    mesh_in = harness_kw["reference"]
    rows = []
    m = measure(ours, **harness_kw)
    rows.append(_row("mna", "reconstruction", m.summary, export.uv_seconds,
                     {"export_seconds": export.export_seconds, "islands": export.islands}))
    opts = XatlasOptions(resolution=size, padding=padding)
    rows.append(_xatlas_row("xatlas", "reconstruction", ours.vertices, ours.faces, opts, run / "xatlas",
                            harness_kw, size, check=False))
    sweep_mesh = None
    if mesh_in is not None:
        rows.append(_xatlas_row("xatlas_input", "input", mesh_in.vertices, mesh_in.faces, opts, run / "xatlas_input",
                                harness_kw, size, check=True))
        sweep_mesh = ("input", mesh_in.vertices, mesh_in.faces)
    else:
        sweep_mesh = ("reconstruction", ours.vertices, ours.faces)
    sweep_rows = []
    if sweep:
        for it in SWEEP_MAX_ITERATIONS:
            for cost in SWEEP_MAX_COST:
                o = XatlasOptions(max_cost=cost, max_iterations=it, resolution=size, padding=padding)
                sweep_rows.append(_xatlas_row(f"xatlas c={cost:g} it={it}", sweep_mesh[0], sweep_mesh[1],
                                              sweep_mesh[2], o, None, harness_kw, size, check=False))
    result = {"run": str(run), "reference": "input mesh" if mesh_in is not None else "none (closed surface assumed)",
              "normalization": norm.to_json(), "methods": rows, "sweep": sweep_rows,
              "atlas": export.atlas}
    write_json(run / "compare.json", result)
    write_text(run / "compare.md", to_markdown(result, export))
    return result


#: what the columns mean, in words (shown under the table in compare.md and in the report)
LEGEND = ("Every row is measured the same way, in the unit-ball frame. Seam length: the 3D length of the "
          "cut edges divided by the square root of the surface area. Distortion: how far the map from "
          "texture to surface is from an isometry (metric; 0 = lengths kept up to one global scale), from "
          "a conformal map (conformal; 0 = angles kept) and from an equal-area map (area), averaged over "
          "texture area (docs/texture.md). Flipped, mirrored, folded and undecided are percentages of the "
          "surface area: flipped = UV triangles turned over within their island; mirrored = the texture "
          "reads mirror-inverted from the front; folded = facing the other way from the input; undecided "
          "= the input faces both ways within 1 % of its diameter there.")


def legend(result: dict) -> str:
    """:data:`LEGEND` and what the time column counts for ``result`` (``compare.json``): ours is
    the reconstruction's export stages, or, for an unwrap's comparison (it has an ``unwrap``
    entry), the unwrap after the fit."""
    ours = "the unwrap after the fit" if "unwrap" in result else "trim, orient, relax, pack"
    return f"{LEGEND} Time: the UV method alone (ours: {ours})."


def _fmt(value, spec):
    if value is None or (isinstance(value, float) and not np.isfinite(value)):
        return "-"
    return spec.format(value)


def table(rows: list[dict]) -> str:
    """Markdown table of harness rows (method, mesh, COLUMNS, seconds)."""
    head = ["method", "mesh", "faces"] + [c[1] for c in COLUMNS] + ["time s"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        cells = [r["method"], r["mesh"], str(r["faces"])] + [_fmt(r.get(k), s) for k, _, s in COLUMNS]
        cells.append(_fmt(r.get("seconds"), "{:.2f}"))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _relax_sentence(r: RelaxStats) -> str:
    if r.energy_before is None:
        return " Islands not relaxed (the charts' own UVs)."
    text = (" Islands relaxed toward an isometry (SLIM): symmetric Dirichlet energy per unit area"
            f" (0 = isometric) {r.energy_before:.3f} -> {r.energy_after:.3f}, at most "
            f"{r.iterations_max} iterations, {r.stopped_by_crossing} stopped by a border "
            "crossing.")
    return text


def to_markdown(result: dict, export: ExportSummary) -> str:
    parts = [f"# compare: {result['run']}", "",
             legend(result) + f" Reference surface: {result['reference']}.", "",
             table(result["methods"]), "",
             export.sentence(), ""]
    if result["sweep"]:
        parts += ["## xatlas sweep (max_cost x max_iterations)", "", table(result["sweep"]), ""]
    return "\n".join(parts)
