"""The demo report: ``RUN/report.md`` and a self-contained ``RUN/report.html``.

Contents, each only when its file exists: the figure(s) (``RUN/renders/figure*.png`` or
those passed in), the comparison table (``RUN/compare.md``, else built from
``RUN/compare.json``), the fit metrics (``RUN/metrics.json``), how the images were
rendered (``RUN/renders/render.json``) and links to the textured GLBs. The HTML inlines
every image as base64, so the one file can be mailed or attached as it is; the GLB
stays a relative link (``mesh.glb`` beside the report).
"""
from __future__ import annotations

import base64
import html
import json
import re
from dataclasses import dataclass
from pathlib import Path

from mnacore.atomic import write_text

#: fit metrics shown in the report (metrics.json keys), in order
METRIC_KEYS = ("chamfer_pcl", "fscore_pcl", "chamfer_mesh", "fscore_mesh", "distortion_metric",
               "distortion_conformal", "distortion_area")
#: the subfolder `mna demo` unwraps the input mesh into
UNWRAP_DIR = "unwrap"
GLB_FILES = (("your mesh, mna unwrap", "unwrap/mesh.glb"), ("your mesh, xatlas", "unwrap/xatlas/mesh.glb"),
             ("reconstruction, mna export", "mesh.glb"), ("reconstruction, xatlas", "xatlas/mesh.glb"))


@dataclass
class Report:
    markdown: Path
    html: Path


def _fmt(v) -> str:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return str(v)
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def _table_md(header: list[str], rows: list[list]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(_fmt(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)


def compare_table(run_dir: Path) -> str | None:
    """Markdown comparison table from ``compare.json`` (``mna compare``'s rows), with its legend."""
    js = run_dir / "compare.json"
    if not js.is_file():
        return None
    from render.figure import _method_numbers

    data = json.loads(js.read_text())
    if isinstance(data, dict) and isinstance(data.get("methods"), list) and data["methods"]:
        from texture.compare import legend, table

        return table(data["methods"]) + "\n\n" + legend(data)
    methods = [m for m in ("mna", "ours", "xatlas") if _method_numbers(data, m)]
    if not methods and isinstance(data, dict):
        methods = [k for k, v in data.items() if isinstance(v, dict)]
    nums = {m: _method_numbers(data, m) or data.get(m, {}) for m in methods}
    keys = [k for k in dict.fromkeys(k for m in methods for k in nums[m])
            if all(isinstance(nums[m].get(k), (int, float)) for m in methods)]
    if not keys:
        return None
    return _table_md(["metric", *methods], [[k, *[nums[m][k] for m in methods]] for k in keys])


def _metrics_table(run_dir: Path) -> str | None:
    path = run_dir / "metrics.json"
    if not path.is_file():
        return None
    data = json.loads(path.read_text())
    rows = [[k, data[k]] for k in METRIC_KEYS if isinstance(data.get(k), (int, float))]
    return _table_md(["metric", "value"], rows) if rows else None


def atlas_summary(run_dir: Path) -> tuple[int | None, int | None]:
    """(charts of the fit, islands of the exported atlas) from ``RUN/atlas.json``, None if absent."""
    path = run_dir / "atlas.json"
    if not path.is_file():
        return None, None
    a = json.loads(path.read_text()).get("atlas", {})
    return a.get("charts"), a.get("islands")


FIT_NOTE = ("The neural atlas itself, before export: its charts are continuous maps, measured on samples "
            "(chamfer and F-score against the input, F-score at 1 % of the diameter, in percent), and its "
            "distortions are those of the charts' own parameterisation. The exported UV atlas's distortions "
            "are the ones in the comparison above (after trimming, relaxation and packing).")
UNWRAP_NOTE = ("The input mesh itself, with its own vertices and faces, UV-mapped two ways: by mna unwrap "
               "(each face assigned to the neural chart that covers it, islands cut to disks, flattened and "
               "packed) and by xatlas with its default options.")
FIGURE_NOTE = ("Rows: our atlas (mna) and xatlas on the same mesh; columns: views. Textured renders show a "
               "checkerboard whose squares have the same size on the surface for both methods, so distortion "
               "shows as squares changing size or shape. In the island image every UV island has its own "
               "colour (categorical, not a scale); in the distortion images the colour bar gives the scale.")


def _render_note(run_dir: Path) -> str | None:
    path = run_dir / "renders" / "render.json"
    if not path.is_file():
        return None
    data = json.loads(path.read_text())
    sub = run_dir / "renders" / next(iter(data.get("methods", {}).values()), "")
    opts = json.loads(sub.read_text()).get("options", {}) if sub.is_file() else {}
    return (f"Rendered with Mitsuba 3 (`{data.get('variant')}`), {opts.get('spp', '?')} spp, "
            f"{opts.get('res', '?')}² px, texture `{opts.get('texture', '?')}`; checker squares of "
            f"side {_fmt(data.get('checker_square_size'))} in 3D for every method.")


def _figures(run_dir: Path, folder: Path, figures: list[Path]) -> list[str]:
    parts = []
    for fig in figures:
        parts += [f"![{fig.stem}]({fig.relative_to(run_dir).as_posix()})", ""]
    if figures:
        parts += [FIGURE_NOTE, ""]
    note = _render_note(folder)
    return parts + ([note, ""] if note else [])


def _islands(folder: Path) -> str:
    """``, 5 islands (xatlas: 17)`` from a folder's compare.json, or ''."""
    path = folder / "compare.json"
    if not path.is_file():
        return ""
    rows = {r.get("method"): r for r in json.loads(path.read_text()).get("methods", []) if isinstance(r, dict)}
    if "mna" not in rows:
        return ""
    xa = f" (xatlas: {rows['xatlas']['charts']})" if "xatlas" in rows else ""
    return f": {rows['mna']['charts']} UV islands{xa}"


def _markdown(run_dir: Path, title: str, figures: list[Path]) -> str:
    parts = [f"# {title}", ""]
    unwrap = run_dir / UNWRAP_DIR
    if (unwrap / "compare.json").is_file():  # the input mesh itself, UV-mapped (mna unwrap)
        figs = sorted((unwrap / "renders").glob("figure*.png"))
        parts += [f"## Your mesh, UV-mapped by mna unwrap and by xatlas{_islands(unwrap)}", "", UNWRAP_NOTE, ""]
        parts += _figures(run_dir, unwrap, figs)
        table = compare_table(unwrap)
        parts += [table, ""] if table else []
    table = compare_table(run_dir)
    if figures or table:
        parts += [f"## The neural atlas's reconstruction, UV-mapped by mna export and by xatlas{_islands(run_dir)}",
                  ""]
        parts += _figures(run_dir, run_dir, figures)
        parts += [table, ""] if table else []
    metrics = _metrics_table(run_dir)
    if metrics:
        parts += ["## Neural atlas fit (before export)", "", FIT_NOTE, "", metrics, ""]
    glbs = [(label, rel) for label, rel in GLB_FILES if (run_dir / rel).is_file()]
    if glbs:
        parts += ["## Textured meshes", ""]
        parts += [f"- {label}: [{rel}]({rel})" for label, rel in glbs]
        parts += [""]
    return "\n".join(parts)


#: link targets the report may make live: relative paths (no scheme), http(s) and file URLs
_SAFE_HREF = re.compile(r"(https?://|file:|(?![a-zA-Z][a-zA-Z0-9+.-]*:))[^\s<>\"']*")


def _link(m: re.Match) -> str:
    label, href = m.group(1), m.group(2)
    if _SAFE_HREF.fullmatch(html.unescape(href)):
        return f'<a href="{href}">{label}</a>'
    return m.group(0)  # any other scheme (javascript:, data:, ...) stays text


def _inline(text: str) -> str:
    """Escaped text with `code` and [label](href) links; only safe hrefs become links."""
    text = html.escape(text)
    text = re.sub(r"`([^`]+)`", r"<code>\1</code>", text)
    return re.sub(r"\[([^\]]+)\]\(([^)]+)\)", _link, text)


def markdown_to_html(md: str, run_dir: Path) -> str:
    """The small Markdown subset we write (headings, images, pipe tables, lists, paragraphs)."""
    out, lines, i = [], md.splitlines(), 0
    while i < len(lines):
        line = lines[i].rstrip()
        img = re.fullmatch(r"!\[([^\]]*)\]\(([^)]+)\)", line)
        if img:
            data = base64.b64encode((run_dir / img.group(2)).read_bytes()).decode()
            out.append(f'<figure><img alt="{html.escape(img.group(1))}" src="data:image/png;base64,{data}"/></figure>')
        elif line.startswith("#"):
            level = len(line) - len(line.lstrip("#"))
            out.append(f"<h{level}>{_inline(line[level:].strip())}</h{level}>")
        elif line.startswith("|"):
            rows = []
            while i < len(lines) and lines[i].startswith("|"):
                cells = [c.strip() for c in lines[i].strip().strip("|").split("|")]
                if not all(re.fullmatch(r":?-+:?", c) for c in cells):
                    rows.append(cells)
                i += 1
            i -= 1
            head = "".join(f"<th>{_inline(c)}</th>" for c in rows[0])
            body = "".join("<tr>" + "".join(f"<td>{_inline(c)}</td>" for c in r) + "</tr>" for r in rows[1:])
            # the wrapper scrolls a wide table sideways instead of widening the page
            out.append(f'<div class="table"><table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table></div>')
        elif line.startswith("- "):
            items = []
            while i < len(lines) and lines[i].startswith("- "):
                items.append(f"<li>{_inline(lines[i][2:])}</li>")
                i += 1
            i -= 1
            out.append("<ul>" + "".join(items) + "</ul>")
        elif line:
            out.append(f"<p>{_inline(line)}</p>")
        i += 1
    return "\n".join(out)


_CSS = ("body{font-family:system-ui,sans-serif;max-width:1200px;margin:2em auto;padding:0 1em;color:#222}"
        "img{max-width:100%}div.table{overflow-x:auto;max-width:100%}"
        "table{border-collapse:collapse;margin:1em 0;font-size:.85em}"
        "td,th{border:1px solid #ccc;padding:.25em .5em;text-align:right}th{background:#f3f3f3}"
        "td:first-child,th:first-child{text-align:left}code{background:#f3f3f3;padding:0 .2em}")


def write_report(run_dir: str | Path, figures: list[str | Path] | None = None,
                 title: str | None = None) -> Report:
    """Write ``RUN/report.md`` and a self-contained ``RUN/report.html``; return their paths.

    ``figures``: images inside ``run_dir`` to show (default: ``RUN/renders/figure*.png``).
    """
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise ValueError(f"run folder not found: {run_dir}")
    if figures is None:  # globbed paths already start with run_dir
        figs = sorted((run_dir / "renders").glob("figure*.png"))
    else:
        figs = [Path(f) if Path(f).is_absolute() else run_dir / f for f in figures]
    for f in figs:
        if not f.is_file():
            raise ValueError(f"figure not found: {f}")
        if run_dir.resolve() not in f.resolve().parents:
            raise ValueError(f"figure {f} must lie inside the run folder {run_dir}")
    figs = [f.resolve().relative_to(run_dir.resolve()) for f in figs]
    figs = [run_dir / f for f in figs]
    title = title or f"mna report: {run_dir.resolve().name}"
    md = _markdown(run_dir, title, figs)
    page = (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>'
            f"<style>{_CSS}</style></head><body>\n{markdown_to_html(md, run_dir)}\n</body></html>\n")
    write_text(run_dir / "report.md", md)
    write_text(run_dir / "report.html", page)
    return Report(run_dir / "report.md", run_dir / "report.html")
