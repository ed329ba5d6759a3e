"""Render benchmark: seconds per image for each Mitsuba variant present and for the pyrender preview.

    .venv/bin/python benchmarks/render.py                 # 1024^2 at 64 and 256 spp, writes RESULTS.md
    .venv/bin/python benchmarks/render.py --res 256 --no-write

Scene: the studio preset (3 area lights, dim environment, ground plane, path tracer of
depth 6) around a parametric torus (2,304 triangles) with a 2048^2 checker texture, the
three-quarter view. Each variant first renders once at 1 spp (JIT compilation and scene
upload are excluded), then each spp count is timed ``--repeats`` times (best kept).
Scene loading (``mi.load_dict``) is timed apart. A render predicted (linearly in spp from
the previous one) to take longer than ``--budget`` seconds is not run; its cell shows the
prediction marked with ``≈``. The ``## render`` section of
benchmarks/RESULTS.md is replaced (re-read just before writing; other sections untouched).
"""
from __future__ import annotations

import argparse
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from machine import describe  # noqa: E402  (benchmarks/machine.py)

from render.backend import available_variants, import_mitsuba, use_variant  # noqa: E402
from render.images import write_png  # noqa: E402
from render.meshes import UVMesh, vertex_normals, write_ply  # noqa: E402
from render.mitsuba_scene import material_bitmap, scene_dict, to_mitsuba  # noqa: E402
from render.pipeline import framing_for  # noqa: E402
from scenes.cameras import camera_rig  # noqa: E402
from scenes.presets import load_preset  # noqa: E402
from texture.textures import checker_image, squares_per_uv_unit  # noqa: E402

RESULTS = ROOT / "benchmarks" / "RESULTS.md"


def torus(n: int = 48, m: int = 24) -> UVMesh:
    i, j = np.meshgrid(np.arange(n + 1), np.arange(m + 1), indexing="ij")
    th, ph = 2 * np.pi * i / n, 2 * np.pi * j / m
    v = np.stack([(1 + 0.4 * np.cos(ph)) * np.cos(th), 0.4 * np.sin(ph), (1 + 0.4 * np.cos(ph)) * np.sin(th)],
                 -1).reshape(-1, 3)
    a = (i[:-1, :-1] * (m + 1) + j[:-1, :-1]).ravel()
    f = np.concatenate([np.stack([a, a + 1, a + m + 2], 1), np.stack([a, a + m + 2, a + m + 1], 1)])
    return UVMesh(v, f, np.stack([i / n, j / m], -1).reshape(-1, 2), name="torus")


def bench_mitsuba(variant: str, scene: dict, base: Path, spps: list[int], repeats: int, budget: float) -> dict:
    mi = use_variant(variant)
    t0 = time.perf_counter()
    loaded = mi.load_dict(to_mitsuba(scene, base, mi))
    load_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    np.array(mi.render(loaded, spp=1))  # JIT compile + upload
    warm_s = time.perf_counter() - t0
    out = {"load_s": load_s, "first_render_1spp_s": warm_s, "predicted": set()}
    for k, spp in enumerate(spps):
        if k > 0 and out[spps[k - 1]] * spp / spps[k - 1] > budget:
            out[spp] = out[spps[k - 1]] * spp / spps[k - 1]
            out["predicted"].add(spp)
            print(f"  {variant} {spp} spp: predicted {out[spp]:.1f} s > budget, not run", file=sys.stderr)
            continue
        best = float("inf")
        for _ in range(repeats):
            t0 = time.perf_counter()
            np.array(mi.render(loaded, spp=spp, seed=0))
            best = min(best, time.perf_counter() - t0)
        out[spp] = best
        print(f"  {variant} {spp} spp: {best:.2f} s", file=sys.stderr)
    return out


def bench_preview(mesh: UVMesh, texture: np.ndarray, framing, cam, preset, res: int, repeats: int) -> dict | str:
    from render.preview import PreviewRenderer, PreviewUnavailable, _pyrender, mesh_node

    try:
        t0 = time.perf_counter()
        r = PreviewRenderer(mesh_node(_pyrender(), mesh, texture), framing.sphere, framing.lowest, preset, res, res)
        r.render(cam)
        setup = time.perf_counter() - t0
    except PreviewUnavailable as exc:
        return str(exc)
    best = float("inf")
    for _ in range(max(repeats, 3)):
        t0 = time.perf_counter()
        r.render(cam)
        best = min(best, time.perf_counter() - t0)
    r.close()
    return {"setup_s": setup, "frame_s": best}


def section(res: int, spps: list[int], results: dict, preview, mach: str, tris: int) -> str:
    mi = import_mitsuba()
    lines = ["## render", "",
             f"`benchmarks/render.py` ({time.strftime('%Y-%m-%d')}), Mitsuba {mi.__version__}: seconds per "
             f"{res}² image, studio preset (3 area lights + environment + ground, path depth 6), "
             f"torus of {tris} triangles with a 2048² checker texture, three-quarter view. Best of the repeats; "
             "JIT compilation and scene loading excluded (listed apart); ≈ marks a time predicted "
             "linearly in spp (render not run: over the time budget).", "",
             f"Machine: {mach}.", "",
             "| renderer | " + " | ".join(f"{s} spp (s)" for s in spps) + " | Msamples/s | scene load (s) | "
             "first 1-spp render incl. JIT (s) |",
             "|---|" + "---|" * (len(spps) + 3)]
    for v, r in results.items():
        measured = [s for s in spps if s not in r["predicted"]]
        rate = res * res * measured[-1] / r[measured[-1]] / 1e6
        lines.append(f"| Mitsuba `{v}` | " + " | ".join(("≈" if s in r["predicted"] else "") + f"{r[s]:.2f}"
                                                         for s in spps)
                     + f" | {rate:.2f} | {r['load_s']:.2f} | {r['first_render_1spp_s']:.2f} |")
    if isinstance(preview, dict):
        lines.append(f"| pyrender preview (EGL, Mesa software) | {preview['frame_s']:.3f} per frame (no spp) |"
                     + " |" * (len(spps) - 1) + f" – | {preview['setup_s']:.2f} (context + first frame) | – |")
    else:
        lines.append(f"| pyrender preview | unavailable: {preview} |" + " |" * (len(spps) + 2))
    missing = [v for v in ("cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb") if v not in results]
    if missing:
        lines += ["", f"Not measured here (backend unavailable): {', '.join(missing)}."]
    return "\n".join(lines) + "\n"


def write_section(text: str) -> None:
    """Replace (or append) the ``## render`` section of RESULTS.md, re-reading it just before writing."""
    from mnacore.atomic import write_text

    current = RESULTS.read_text() if RESULTS.is_file() else "# Benchmark results\n"
    pattern = re.compile(r"^## render\n.*?(?=^## |\Z)", re.MULTILINE | re.DOTALL)
    new = pattern.sub(lambda _: text + "\n", current) if pattern.search(current) else \
        current.rstrip("\n") + "\n\n" + text
    write_text(RESULTS, new)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--res", type=int, default=1024)
    ap.add_argument("--spp", default="64,256")
    ap.add_argument("--variants", default=None, help="comma-separated (default: every available RGB variant)")
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--budget", type=float, default=240.0, help="longest single render to run (seconds)")
    ap.add_argument("--no-write", action="store_true", help="print the section, do not touch RESULTS.md")
    args = ap.parse_args(argv)
    spps = [int(s) for s in args.spp.split(",")]
    variants = args.variants.split(",") if args.variants else available_variants()

    preset = load_preset("studio")
    mesh = torus()
    framing = framing_for(mesh, preset)
    (cam,) = camera_rig(framing.sphere, preset, args.res, args.res, ["three_quarter"])
    mach = describe()
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp)
        write_ply(base / "mesh.ply", mesh.vertices, mesh.faces, mesh.uv, vertex_normals(mesh.vertices, mesh.faces))
        freq = squares_per_uv_unit(mesh.vertices, mesh.faces, mesh.uv, framing.square_size)
        texture = checker_image(freq, 2048, preset.material.checker_colors)
        write_png(base / "texture.png", texture)
        scene = scene_dict("mesh.ply", material_bitmap("texture.png"), cam, framing.sphere, framing.lowest,
                           preset, spps[0])
        results = {v: bench_mitsuba(v, scene, base, spps, args.repeats, args.budget) for v in variants}
    preview = bench_preview(mesh, texture, framing, cam, preset, args.res, args.repeats)
    text = section(args.res, spps, results, preview, mach, len(mesh.faces))
    print(text)
    if not args.no_write:
        write_section(text)
        print(f"updated {RESULTS}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
