"""One process pool helper for the export's independent pieces of work.

xatlas and SLIM hold the GIL and numpy's work here is mostly single-threaded, so threads do
not help: the jobs run in forked worker processes (default: the CPU count, at most 4). The
result is the same as running them one after the other here, which is also the fallback
where processes cannot be started.
"""
from __future__ import annotations

import os
from typing import Any, Callable

_shared: Any = None

#: below this many faces in all, work is done in this process (starting workers costs more)
MIN_FACES = 20_000


def default_workers() -> int:
    """Processes for parallel work: the CPU count, at most 4."""
    return min(os.cpu_count() or 1, 4)


def _call(arg):
    fn, job = arg
    return fn(job, _shared)


def parallel_map(fn: Callable[[Any, Any], Any], jobs: list, workers: int | None = None, shared: Any = None,
                 parallel: bool = True) -> list:
    """``[fn(job, shared) for job in jobs]`` in up to ``workers`` forked processes.

    ``fn`` must be a module-level function. ``shared`` reaches the workers by the fork itself,
    not by pickling (a KD-tree, a reference mesh): only the jobs and results are pickled.
    ``parallel=False`` (e.g. too little work to pay for starting processes) runs here.
    """
    global _shared
    workers = min(len(jobs), workers or default_workers())
    if parallel and workers > 1:
        _shared = shared
        try:
            import multiprocessing as mp
            from concurrent.futures import ProcessPoolExecutor

            with ProcessPoolExecutor(workers, mp_context=mp.get_context("fork")) as ex:
                return list(ex.map(_call, [(fn, j) for j in jobs]))
        except (OSError, RuntimeError, ValueError):  # no processes here: run in this one
            pass
        finally:
            _shared = None
    return [fn(j, shared) for j in jobs]
