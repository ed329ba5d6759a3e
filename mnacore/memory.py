"""A process's own peak resident memory, as the benchmarks and the unwrap's workers report it.

``getrusage(RUSAGE_SELF).ru_maxrss`` is not a process's own peak on Linux: a forked child
starts from its parent's high-water mark and keeps it across ``exec``, so a benchmark's
child run started from a parent holding 617 MB reported 617 MB whatever it used itself
(xatlas on the 111k-face bunny: 383 MB when the parent was small). ``VmHWM`` in
``/proc/self/status`` belongs to the process's own address space, which ``exec`` replaces.
"""
from __future__ import annotations

import resource
from pathlib import Path

_STATUS = Path("/proc/self/status")
_CLEAR_REFS = Path("/proc/self/clear_refs")


def peak_rss_mb() -> float:
    """This process's peak resident memory in MB since it started (or since
    :func:`reset_peak_rss`): ``VmHWM`` where ``/proc`` has it, else ``ru_maxrss`` (which on
    Linux may include the parent's, see the module doc)."""
    try:
        for line in _STATUS.read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024  # kB
    except (OSError, ValueError, IndexError):
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def reset_peak_rss() -> bool:
    """Start this process's peak over from its present resident memory (Linux 4.0+: ``5``
    written to ``/proc/self/clear_refs``), so that one stage of a long run is measured on its
    own. False where the system does not allow it (the peak then runs on)."""
    try:
        _CLEAR_REFS.write_text("5")
        return True
    except OSError:
        return False
