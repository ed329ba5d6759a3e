"""The machine a run or a benchmark ran on, named as its records state it.

The CPU's model and its widest vector extension are named, not only the architecture: a
fit repeats exactly on one machine but not across CPUs (their kernels sum in other orders;
the unwrap benchmark's 19 fits made again on a machine with AVX-512 moved the bunny's F
88.9 -> 88.5), so a run's numbers compare with another's only on the same CPU. Every
record that names the machine (a fit's ``metrics.json``, a training run's, ``unwrap.json``,
the benchmarks' blocks in RESULTS.md) reads it here.
"""
from __future__ import annotations

import os
import platform
from pathlib import Path

#: vector extensions, widest first: the first in the CPU's flags is named
_VECTOR = (("avx512f", "AVX-512"), ("avx2", "AVX2"), ("avx", "AVX"), ("asimd", "NEON"))
_CPUINFO = Path("/proc/cpuinfo")


def cpu_name(cpuinfo: Path = _CPUINFO) -> str:
    """The CPU's model (``/proc/cpuinfo``) and its widest vector extension, e.g. ``Intel(R)
    Xeon(R) Processor, AVX-512``; the architecture where ``/proc`` is missing."""
    model, flags = "", set()
    try:
        for line in Path(cpuinfo).read_text().splitlines():
            key, _, value = line.partition(":")
            key = key.strip()
            if key == "model name" and not model:
                model = value.strip()
            elif key in ("flags", "Features") and not flags:
                flags = set(value.split())
    except OSError:
        pass
    model = model or platform.processor() or platform.machine()
    vector = next((name for flag, name in _VECTOR if flag in flags), "")
    return f"{model}, {vector}" if vector else model


def cpu_summary() -> str:
    """``<cpu>, <n> cores``: what a run's record names as its machine."""
    return f"{cpu_name()}, {os.cpu_count()} cores"
