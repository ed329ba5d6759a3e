"""The machine a benchmark ran on, as its block in RESULTS.md names it.

The CPU's model and its widest vector extension are named, not only the architecture: a
fit repeats exactly on one machine but not across CPUs (their kernels sum in other orders;
the unwrap benchmark's 19 fits made again on a machine with AVX-512 moved the bunny's F
88.9 -> 88.5), so a block's numbers compare with another's only on the same CPU.
"""
from __future__ import annotations

import os
import platform
import subprocess
from pathlib import Path

#: vector extensions, widest first: the first in the CPU's flags is named
_VECTOR = (("avx512f", "AVX-512"), ("avx2", "AVX2"), ("avx", "AVX"), ("asimd", "NEON"))


def cpu_name() -> str:
    """The CPU's model (``/proc/cpuinfo``) and its widest vector extension, e.g. ``Intel(R)
    Xeon(R) Processor, AVX-512``; the architecture where ``/proc`` is missing."""
    model, flags = "", set()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
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


def gpu_name() -> str:
    """The first NVIDIA GPU's name, or "" where there is none (or no ``nvidia-smi``)."""
    try:
        out = subprocess.run(["nvidia-smi", "--query-gpu=name", "--format=csv,noheader"], capture_output=True,
                             text=True, timeout=10).stdout
    except (OSError, subprocess.SubprocessError):
        return ""
    lines = out.strip().splitlines()
    return lines[0] if lines else ""


def describe() -> str:
    """``<cpu>, <n> cores, GPU <name> | no GPU; load average <x> at start``."""
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    gpu = gpu_name()
    return f"{cpu_name()}, {os.cpu_count()} cores{', GPU ' + gpu if gpu else ', no GPU'}; load average {load:.1f} at start"
