"""``mna compare OUT`` for an ``mna unwrap`` folder: ours vs xatlas on the *same input mesh*.

Rows (one harness, :func:`texture.harness.measure`, reference = the input mesh, the
fit's unit-ball frame from ``unwrap.json``):

- ``mna``: ``OUT/mesh.obj`` as written by ``mna unwrap`` (time: the unwrap after the fit);
- ``xatlas``: xatlas with its default chart options (our padding and resolution) on the
  input mesh as ``mna unwrap`` read it (its own vertex list, so xatlas sees no artificial
  boundaries), written to ``OUT/xatlas/`` like an export;
- ``sweep``: xatlas over ``max_cost`` x ``max_iterations`` on that mesh.
"""
from __future__ import annotations

from pathlib import Path

from mnacore.atomic import write_json, write_text

from .compare import SWEEP_MAX_COST, SWEEP_MAX_ITERATIONS, _row, _xatlas_row, legend, table
from .export import read_back
from .harness import measure
from .unwrap_run import load_unwrap_input, read_unwrap_json, unwrap_harness_context
from .xatlas_uv import XatlasOptions


def compare_unwrap(run: str | Path, sweep: bool = True, size: int = 2048, padding: int = 8) -> dict:
    """Write ``OUT/compare.json`` and ``OUT/compare.md`` for an unwrap folder; returns the JSON content."""
    run = Path(run)
    info = read_unwrap_json(run)
    inp = load_unwrap_input(info["input"])
    # the one harness context of an unwrap folder, as `mna uv-metrics` uses on these files
    harness_kw = unwrap_harness_context(run, info, inp)
    norm = harness_kw["normalization"]
    ours = read_back(run / "mesh.obj")
    t = info["timings"]
    rows = [_row("mna", "input", measure(ours, **harness_kw).summary, t["unwrap_total"],
                 {"islands": info["islands"]})]
    opts = XatlasOptions(resolution=size, padding=padding)
    rows.append(_xatlas_row("xatlas", "input", inp.vertices, inp.faces, opts, run / "xatlas", harness_kw, size,
                            check=False))
    sweep_rows = []
    if sweep:
        for it in SWEEP_MAX_ITERATIONS:
            for cost in SWEEP_MAX_COST:
                o = XatlasOptions(max_cost=cost, max_iterations=it, resolution=size, padding=padding)
                sweep_rows.append(_xatlas_row(f"xatlas c={cost:g} it={it}", "input", inp.vertices, inp.faces, o,
                                              None, harness_kw, size, check=False))
    result = {"run": str(run), "reference": "input mesh", "normalization": norm.to_json(), "methods": rows,
              "sweep": sweep_rows, "unwrap": {k: info[k] for k in ("islands", "assignment", "regions", "relax")}}
    write_json(run / "compare.json", result)
    write_text(run / "compare.md", to_markdown(result))
    return result


def to_markdown(result: dict) -> str:
    a = result["unwrap"]["assignment"]
    parts = [f"# compare (unwrap): {result['run']}", "",
             "Ours (`mna unwrap`) and xatlas on the same input mesh, measured the same way; reference: the "
             "input mesh.", "", legend(result), "",
             table(result["methods"]), "",
             f"Face assignment: {a['far_faces']} faces farther than {a['far_tol']} from every chart "
             f"({100 * a['far_area_fraction']:.1f} % of the area, nearest-chart labels); fallback components "
             f"{a['fallback_components']} ({100 * a['fallback_area_fraction']:.1f} % of the area).", ""]
    if result["sweep"]:
        parts += ["## xatlas sweep (max_cost x max_iterations)", "", table(result["sweep"]), ""]
    return "\n".join(parts)
