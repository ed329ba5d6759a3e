"""mnacore.memory: a process's own peak resident memory, not its parent's."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mnacore.memory import peak_rss_mb, reset_peak_rss

pytestmark = pytest.mark.skipif(not Path("/proc/self/status").is_file(), reason="needs Linux /proc")

MB = 1024 * 1024


def _touch(mb: int) -> np.ndarray:
    """``mb`` MB held resident (every page written)."""
    return np.ones(mb * MB // 8)


def test_peak_counts_what_this_process_held():
    before = peak_rss_mb()
    block = _touch(300)
    assert peak_rss_mb() >= max(before, 300.0)
    del block


def test_a_child_does_not_report_its_parents_peak():
    # getrusage's ru_maxrss in a child started from a parent holding 300 MB reads >= 300 MB
    # (the high-water mark survives fork and exec); the child itself holds a bare interpreter
    block = _touch(300)
    code = "from mnacore.memory import peak_rss_mb; print(peak_rss_mb())"
    root = Path(__file__).resolve().parents[2]
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=root)
    child = float(out.stdout.strip())
    assert peak_rss_mb() >= 300.0
    assert 1.0 < child < 100.0
    del block


def test_reset_starts_the_peak_over():
    block = _touch(300)
    held = peak_rss_mb()
    del block
    if not reset_peak_rss():
        pytest.skip("/proc/self/clear_refs not writable here")
    after = peak_rss_mb()
    assert after < held - 250.0  # the freed 300 MB are no longer part of the peak
    block = _touch(200)
    assert peak_rss_mb() >= after + 190.0
    del block
