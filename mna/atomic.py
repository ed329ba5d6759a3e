"""Atomic file output: write to a temporary name in the same folder, then rename.

An interrupted run never leaves a half-written file under its final name. Torch-free,
so ``texture`` and ``render`` use it too.

Temporaries are hidden and named ``.{name}.mna-tmp.{8 random chars}{suffix}`` (e.g.
``.checkpoint.pt.mna-tmp.k2j9x_0a.pt``): a process killed mid-write (SIGKILL, power loss)
leaves one behind, and :func:`clean_stale_temporaries` recognises exactly these names
(never a user's file) and removes those older than this process.
"""
from __future__ import annotations

import contextlib
import json
import os
import re
import tempfile
import time
from pathlib import Path
from typing import Any, Iterable, Iterator

_UMASK = os.umask(0)
os.umask(_UMASK)

TEMP_MARK = ".mna-tmp."
#: ``tempfile``'s random part: 8 characters of ``[a-z0-9_]``
_TEMP_RE = re.compile(r"^\..+" + re.escape(TEMP_MARK) + r"[a-z0-9_]{8}(\.[A-Za-z0-9]+)?$")
#: wall-clock time this process started using mna (temporaries older than this are stale)
PROCESS_START = time.time()


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success.

    The temporary keeps ``path``'s suffix (or ``suffix``) so libraries that pick a
    format from the extension (trimesh, OpenImageIO, Mitsuba) still work.
    On an exception the temporary is removed and ``path`` is left untouched.
    """
    path = Path(path)
    if path.is_dir():  # os.replace would fail naming the temporary instead
        raise IsADirectoryError(f"{path} is a folder; give a file path")
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}{TEMP_MARK}", suffix=suffix or path.suffix, dir=path.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        # mkstemp creates 0600 files; give the result the usual umask-based mode
        os.chmod(tmp_path, 0o666 & ~_UMASK)
        os.replace(tmp_path, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp_path.unlink()
        raise


def is_temporary_name(name: str, legacy: Iterable[str] = ()) -> bool:
    """True for a temporary name of :func:`atomic_path`; ``legacy`` final names (e.g.
    ``checkpoint.pt``) also match the earlier scheme ``.{stem}.{8 chars}{suffix}``."""
    if _TEMP_RE.match(name):
        return True
    for final in legacy:
        stem, suffix = os.path.splitext(final)
        if re.fullmatch(r"\." + re.escape(stem) + r"\.[a-z0-9_]{8}" + re.escape(suffix), name):
            return True
    return False


def clean_stale_temporaries(folder: str | os.PathLike, legacy: Iterable[str] = (), recursive: bool = True,
                            before: float | None = None) -> list[Path]:
    """Remove temporaries of :func:`atomic_path` left in ``folder`` by a killed process.

    Only names matching :func:`is_temporary_name` and last modified before ``before``
    (default: this process's start, so a write in progress elsewhere is never touched).
    Legacy names are matched in ``folder`` itself only. Returns the removed paths.
    """
    folder, before = Path(folder), PROCESS_START if before is None else before
    if not folder.is_dir():
        return []
    legacy = tuple(legacy)
    candidates = [p for p in (folder.rglob(".*") if recursive else folder.glob(".*"))
                  if is_temporary_name(p.name, legacy if p.parent == folder else ())]
    removed = []
    for p in candidates:
        try:
            if p.is_file() and not p.is_symlink() and p.stat().st_mtime < before:
                p.unlink()
                removed.append(p)
        except OSError:  # vanished meanwhile, or not ours to remove: leave it
            pass
    return removed


def write_text(path: str | os.PathLike, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def write_bytes(path: str | os.PathLike, data: bytes) -> None:
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def write_json(path: str | os.PathLike, obj: Any) -> None:
    """Strict JSON (RFC 8259): NaN and infinities are written as ``null``, which every parser reads."""
    text = json.dumps(strict_json(obj), indent=2, sort_keys=False, default=_json_default, allow_nan=False)
    write_text(path, text + "\n")


def strict_json(o: Any) -> Any:
    """``o`` with every non-finite float (also numpy's, and inside arrays) replaced by None."""
    if isinstance(o, float):
        return o if o == o and o not in (float("inf"), float("-inf")) else None
    if isinstance(o, dict):
        return {k: strict_json(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [strict_json(v) for v in o]
    if hasattr(o, "tolist") and not isinstance(o, (str, bytes)):
        return strict_json(o.tolist())
    return o


def _json_default(o: Any) -> Any:
    # numpy scalars/arrays without importing numpy at module load
    if hasattr(o, "tolist"):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")
