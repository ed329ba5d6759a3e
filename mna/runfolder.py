"""The run folder (DESIGN contract): the names mna writes there, and preparing one for a new run.

Torch-free, so every command that writes a run folder (``fit``, ``reconstruct``, ``demo``,
``unwrap``) prepares it the same way with :func:`prepare_run_folder`:

* a new run goes into a missing or empty folder;
* ``--resume`` continues the run that is there (what was made from its charts before, an
  export, comparison or renders, is removed once the fit resumes: :func:`remove_derived`);
* ``--overwrite`` replaces it: everything mna wrote there is removed first, so no file of
  the old run (an old ``mesh.obj``, ``compare.md``, ``renders/`` ...) sits beside the new one.
  Files mna does not write are never deleted: the folder is refused instead.
"""
from __future__ import annotations

import fnmatch
import shutil
from pathlib import Path
from typing import Iterable

from mnacore.atomic import clean_stale_temporaries
from mnacore.errors import MnaError

#: files and folders of a run folder written by some mna command (see DESIGN's layout)
RUN_FILES = (
    "config.yaml", "checkpoint.pt", "metrics.json", "points.ply", "charts.npz", "charts.ply",
    "mesh.obj", "mesh.mtl", "mesh_texture.png", "mesh.glb", "atlas.json", "unwrap.json",
    "compare.json", "compare.md", "report.html", "report.md",
)
RUN_FOLDERS = ("xatlas", "xatlas_input", "renders")
#: what ``mna fit`` writes: kept when ``mna unwrap --run RUN -o RUN`` replaces its own outputs
FIT_FILES = ("config.yaml", "checkpoint.pt", "metrics.json", "points.ply", "charts.npz", "charts.ply")
#: what later commands make from a fit's charts (export, unwrap, compare, render, report):
#: stale once the fit continues, so ``mna fit --resume`` removes them
DERIVED = tuple(n for n in RUN_FILES if n not in FIT_FILES) + RUN_FOLDERS
#: ``mna demo``'s copy of its built-in input shape
RUN_PATTERNS = ("input_*.ply",)


def is_run_output(name: str, extra: Iterable[str] = ()) -> bool:
    """True when ``name`` (an entry of a run folder) is something mna writes there."""
    patterns = (*RUN_FILES, *RUN_FOLDERS, *RUN_PATTERNS, *extra)
    return any(fnmatch.fnmatchcase(name, p) for p in patterns)


def _remove(p: Path, option: str) -> None:
    """Remove the file or folder ``p`` (a link itself, never what it points to)."""
    try:
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p)
        else:
            p.unlink()
    except OSError as exc:
        raise MnaError(f"{option}: cannot remove {p}: {exc.strerror or exc}") from None


def remove_derived(out: str | Path) -> list[str]:
    """Remove from the run folder ``out`` what was made from its charts (:data:`DERIVED`);
    returns the names removed."""
    gone = []
    for name in DERIVED:
        p = Path(out) / name
        if p.exists() or p.is_symlink():
            _remove(p, "--resume")
            gone.append(name + ("/" if name in RUN_FOLDERS else ""))
    return gone


def _listing(paths: list[Path], limit: int = 4) -> str:
    names = sorted(p.name + ("/" if p.is_dir() else "") for p in paths)
    return ", ".join(names[:limit]) + (f" and {len(names) - limit} more" if len(names) > limit else "")


def prepare_run_folder(out: str | Path, *, resume: bool = False, overwrite: bool = False,
                       keep: Iterable[str | Path] = (), resume_file: str | None = None,
                       extra_outputs: Iterable[str] = (), can_resume: bool = False) -> Path:
    """Check (and create or empty) the run folder ``out`` for a command about to write it.

    Call it after every input and option is validated: it is the first thing that changes
    the disk. Stale temporaries of a killed write are removed in every case.

    Args:
        out: the run folder.
        resume: continue the run that is there: nothing is removed here (the fit removes its
            derived outputs once it resumes, :func:`remove_derived`); ``resume_file`` (e.g.
            ``checkpoint.pt``) must exist in it.
        overwrite: replace an existing run: remove every entry :func:`is_run_output` knows.
        keep: paths never removed and not counted as content (the command's own input
            when it lies inside ``out``, as in ``mna demo``).
        extra_outputs: more names or glob patterns the calling command writes.
        can_resume: the command has ``--resume`` (the refusal then mentions it).

    Raises:
        MnaError: ``out`` is a file; ``--resume`` without ``resume_file``; a non-empty folder
            without ``resume``/``overwrite``; ``overwrite`` with files mna did not write;
            an unwritable folder.
    """
    out = Path(out)
    if resume and overwrite:
        raise MnaError("--resume and --overwrite exclude each other")
    if out.exists() and not out.is_dir():
        raise MnaError(f"output path exists and is not a folder: {out}")
    legacy = (*RUN_FILES, "log.csv", "texture.png", "render.json")
    clean_stale_temporaries(out, legacy=legacy)
    if resume:
        if resume_file and not (out / resume_file).is_file():
            raise MnaError(f"--resume: no {resume_file} in {out}")
        return out
    if out.is_dir():
        kept = {Path(k).resolve() for k in keep}
        entries = [p for p in out.iterdir() if p.resolve() not in kept]
        if entries and not overwrite:
            how = "--resume to continue its fit, --overwrite" if can_resume else "--overwrite"
            raise MnaError(f"run folder {out} is not empty ({_listing(entries)}); use {how} to replace it, "
                           f"or another folder")
        foreign = [p for p in entries if not is_run_output(p.name, extra_outputs)]
        if foreign:
            raise MnaError(f"--overwrite: {out} holds files mna does not write ({_listing(foreign)}); "
                           f"not deleting them: move them away or choose another folder")
        for p in entries:
            _remove(p, "--overwrite")
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / ".mna-write-test"
        probe.write_text("")
        probe.unlink()
    except OSError as exc:
        raise MnaError(f"output folder {out} is not writable: {exc.strerror or exc}") from None
    return out
