"""One process pool helper for the export's independent pieces of work.

xatlas and SLIM hold the GIL and numpy's work here is mostly single-threaded, so threads do
not help: the jobs run in worker processes (default: the CPU count, at most 4). The result
is the same as running them one after the other here, which is also the fallback where
processes cannot be started.

Workers come from a fork server, not from a fork of the caller. The caller usually has
native threads alive (torch's pool after a fit, a test runner's), and a fork copies any lock
one of them holds at that instant, forever locked in the child. The fork server is a fresh
single-threaded interpreter that imports the modules below once; each worker is a fork of
it, so starting one costs little and inherits no other thread's locks.

A worker can still hang: twice a packing worker waited forever in xatlas's ``Destroy``,
joining a thread of xatlas's own scheduler (once with fork, once with the fork server, in
about a dozen test runs; presumably a wake-up its shutdown misses). So a pool in which no
job has finished for ``STALL_SECONDS``, and whose workers used next to no CPU time in it
(``WORKING_SHARE``: a long job is busy, a hung one waits), is taken for hung: its workers
are killed and the jobs they had not finished run here instead, with the same result (the jobs are
deterministic), only later. The hang comes with the number of xatlas calls: the unwrap's
quarter-turn search makes 256 per unwrap, and then a test run waited out a whole stall (one
of two full CI runs, one of 18 runs of the unwrap tests); the packer's own xatlas jobs
(:mod:`texture.scale_search`, milliseconds to a second each) therefore pass a shorter stall.
The cause is a lost wake-up in xatlas's scheduler at an atlas's destruction, right after its
call (it also hung a test process once, where no stall guards); the packer now destroys each
atlas several calls later (:func:`texture.placement.xatlas_pack`), and the stall stays a guard.

Each worker runs its numerical libraries (the BLAS under numpy and scipy) on one thread.
OpenBLAS starts a thread per core in every process, and its idle threads spin: two workers
with two BLAS threads each on two cores starved each other, so the same SLIM jobs of the
111k-face bunny took 2.2-107 s from one run to the next (3 of 13 runs over 80 s); with one
BLAS thread per worker 1.8-3.0 s in 24 of 24 (``threadpoolctl``, as scikit-learn does).
The pool already runs one job per core, so a worker loses nothing by it.

As with any fork server or spawn start (the default from Python 3.14), a script that calls
the unwrap or export directly must guard its entry with ``if __name__ == "__main__":``
(the ``mna`` commands do).
"""
from __future__ import annotations

import os
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Callable

from mnacore.memory import peak_rss_mb

_shared: Any = None

#: below this many faces in all, work is done in this process (starting workers costs more)
MIN_FACES = 20_000

#: seconds without any job finishing after which a pool is taken for hung (the longest job
#: measured, a 418k-face island's relaxation at 1M input faces, took under 30 s)
STALL_SECONDS = 180.0

#: a pool whose workers used at least this share of a stall window in CPU time is working,
#: not hung, and is waited for: the hang is a wait on a lost wake-up, which uses no CPU, while
#: a long job on a busy machine does (a sliver-pole sphere's SLIM, run beside two fits, passed
#: the stall, was killed and ran again here). Where the workers' CPU time cannot be read
#: (no /proc), a stall is taken for a hang, as before.
WORKING_SHARE = 0.01

#: imported once by the fork server, so that its workers start with them loaded
PRELOAD = ["numpy", "scipy.sparse", "scipy.spatial", "igl", "xatlas",
           "texture.relax", "texture.scale_search", "texture.orient", "texture.unwrap_islands"]

_peak_worker_mb = 0.0
_limits: Any = None  # the worker's BLAS thread limit (held so that it stays in force)


def default_workers() -> int:
    """Processes for parallel work: the CPU count, at most 4."""
    return min(os.cpu_count() or 1, 4)


def peak_worker_rss_mb() -> float:
    """The largest peak resident memory of any worker so far, in MB (the workers are not
    this process's children, so ``RUSAGE_CHILDREN`` does not see them)."""
    return _peak_worker_mb


def _set_shared(shared) -> None:
    """A worker's initialiser: its shared object, and one BLAS thread (see the module doc)."""
    global _shared, _limits
    from threadpoolctl import threadpool_limits

    _limits = threadpool_limits(limits=1, user_api="blas")
    _shared = shared


def _call(arg):
    fn, job = arg
    return fn(job, _shared), peak_rss_mb()


def _context():
    import multiprocessing as mp

    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(PRELOAD)
    return ctx


def parallel_map(fn: Callable[[Any, Any], Any], jobs: list, workers: int | None = None, shared: Any = None,
                 parallel: bool = True, stall_seconds: float | None = None) -> list:
    """``[fn(job, shared) for job in jobs]`` in up to ``workers`` processes.

    ``fn`` must be a module-level function. ``shared`` (a KD-tree, a reference mesh) is
    pickled once per worker, not once per job. ``parallel=False`` (e.g. too little work to
    pay for starting processes) runs here. ``stall_seconds`` (default ``STALL_SECONDS``): how
    long no job may finish before the pool is taken for hung; callers whose jobs are short
    pass less, so a hang costs them that, not three minutes (the result is the same).
    """
    global _peak_worker_mb
    workers = min(len(jobs), workers or default_workers())
    if parallel and workers > 1:
        try:
            futures = _pooled(fn, jobs, workers, shared, STALL_SECONDS if stall_seconds is None else stall_seconds)
        except (OSError, RuntimeError, ValueError):  # no processes here: run in this one
            pass
        else:
            out = []
            for f, job in zip(futures, jobs):
                # a killed pool marks its unfinished futures broken (from the executor's own
                # thread, so sooner or later than this loop reads them): those jobs run here too
                if f.done() and not f.cancelled() and not isinstance(f.exception(), BrokenProcessPool):
                    r, mb = f.result()  # a job's own error is raised here, as in a serial run
                    _peak_worker_mb = max(_peak_worker_mb, mb)
                    out.append(r)
                else:  # its worker hung: run it here
                    out.append(fn(job, shared))
            return out
    return [fn(j, shared) for j in jobs]


def _cpu_seconds(ex) -> float | None:
    """User and system CPU seconds of the pool's worker processes so far (Linux's
    ``/proc/PID/stat``), or None where that cannot be read."""
    try:
        total = 0
        for pid in list(getattr(ex, "_processes", {}) or {}):
            with open(f"/proc/{pid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()  # the name may hold spaces
            total += int(fields[11]) + int(fields[12])  # utime, stime (fields 14 and 15)
        return total / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return None


def _pooled(fn, jobs: list, workers: int, shared, stall: float) -> list:
    """The jobs' futures, once every job finished or the pool stalled (no job finished for
    ``stall`` seconds while the workers used under ``WORKING_SHARE`` of it in CPU time: its
    workers are killed and the unfinished futures left undone)."""
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    ex = ProcessPoolExecutor(workers, mp_context=_context(), initializer=_set_shared, initargs=(shared,))
    futures = [ex.submit(_call, (fn, j)) for j in jobs]
    pending = set(futures)
    used = _cpu_seconds(ex)
    try:
        while pending:
            done, pending = wait(pending, timeout=stall, return_when=FIRST_COMPLETED)
            now = _cpu_seconds(ex)
            working = used is not None and now is not None and now - used >= WORKING_SHARE * stall
            used = now
            if not done and not working:
                break
    finally:
        if pending:
            # ProcessPoolExecutor cannot stop a running job before Python 3.14
            # (terminate_workers): kill its processes, then let it go
            for proc in list(getattr(ex, "_processes", {}).values()):
                proc.kill()
            ex.shutdown(wait=False, cancel_futures=True)
        else:
            ex.shutdown()
    return futures
