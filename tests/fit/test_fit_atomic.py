"""Atomic writes: all or nothing under the final name."""
from __future__ import annotations

import os

import pytest

from mnacore.atomic import atomic_path, write_json, write_text


def test_failed_write_leaves_previous_file_and_no_temporary(tmp_path):
    target = tmp_path / "out.txt"
    write_text(target, "old")
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("interrupted")
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.txt"]


def test_written_file_has_umask_mode_and_suffix(tmp_path):
    seen = {}
    with atomic_path(tmp_path / "a.png") as tmp:
        seen["suffix"] = tmp.suffix
        tmp.write_bytes(b"x")
    assert seen["suffix"] == ".png"
    umask = os.umask(0)
    os.umask(umask)
    assert (tmp_path / "a.png").stat().st_mode & 0o777 == 0o666 & ~umask
    write_json(tmp_path / "m.json", {"a": 1.5})
    assert (tmp_path / "m.json").read_text() == '{\n  "a": 1.5\n}\n'
