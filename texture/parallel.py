"""One process pool helper for the export's independent pieces of work.

xatlas and SLIM hold the GIL and numpy's work here is mostly single-threaded, so threads do
not help: the jobs run in worker processes (default: the CPU count, at most 4). The result
is the same as running them one after the other here, which is also the fallback where
processes cannot be started.

Workers come from a fork server, not from a fork of the caller. The caller usually has
native threads alive (torch's pool after a fit, a test runner's), and a fork copies any lock
one of them holds at that instant, forever locked in the child: a packing worker once hung
in xatlas's thread join that way. The fork server is a fresh single-threaded interpreter
that imports the modules below once; each worker is a fork of it, so starting one costs
little and inherits no other thread's locks. As with any fork server or spawn start (the
default from Python 3.14), a script that calls the unwrap or export directly must guard its
entry with ``if __name__ == "__main__":`` (the ``mna`` commands do).
"""
from __future__ import annotations

import os
import resource
from typing import Any, Callable

_shared: Any = None

#: below this many faces in all, work is done in this process (starting workers costs more)
MIN_FACES = 20_000

#: imported once by the fork server, so that its workers start with them loaded
PRELOAD = ["numpy", "scipy.sparse", "scipy.spatial", "igl", "xatlas",
           "texture.relax", "texture.scale_search", "texture.orient", "texture.unwrap_islands"]

_peak_worker_kb = 0


def default_workers() -> int:
    """Processes for parallel work: the CPU count, at most 4."""
    return min(os.cpu_count() or 1, 4)


def peak_worker_rss_mb() -> float:
    """The largest peak resident memory of any worker so far, in MB (the workers are not
    this process's children, so ``RUSAGE_CHILDREN`` does not see them)."""
    return _peak_worker_kb / 1024


def _set_shared(shared) -> None:
    global _shared
    _shared = shared


def _call(arg):
    fn, job = arg
    return fn(job, _shared), resource.getrusage(resource.RUSAGE_SELF).ru_maxrss


def _context():
    import multiprocessing as mp

    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(PRELOAD)
    return ctx


def parallel_map(fn: Callable[[Any, Any], Any], jobs: list, workers: int | None = None, shared: Any = None,
                 parallel: bool = True) -> list:
    """``[fn(job, shared) for job in jobs]`` in up to ``workers`` processes.

    ``fn`` must be a module-level function. ``shared`` (a KD-tree, a reference mesh) is
    pickled once per worker, not once per job. ``parallel=False`` (e.g. too little work to
    pay for starting processes) runs here.
    """
    global _peak_worker_kb
    workers = min(len(jobs), workers or default_workers())
    if parallel and workers > 1:
        try:
            from concurrent.futures import ProcessPoolExecutor

            with ProcessPoolExecutor(workers, mp_context=_context(), initializer=_set_shared,
                                     initargs=(shared,)) as ex:
                done = list(ex.map(_call, [(fn, j) for j in jobs]))
        except (OSError, RuntimeError, ValueError):  # no processes here: run in this one
            pass
        else:
            _peak_worker_kb = max([_peak_worker_kb] + [kb for _, kb in done])
            return [r for r, _ in done]
    return [fn(j, shared) for j in jobs]
