"""The machine a benchmark ran on, as its block in RESULTS.md names it: the CPU as
:mod:`mnacore.machine` names it (model and vector extension: fits repeat on one CPU, not
across CPUs), the GPU, the load."""
from __future__ import annotations

import os
import subprocess

from mnacore.machine import cpu_summary


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
    return f"{cpu_summary()}{', GPU ' + gpu if gpu else ', no GPU'}; load average {load:.1f} at start"
