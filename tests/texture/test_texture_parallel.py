"""texture.parallel: workers give the serial result, in order, with shared state, and are not
forks of the caller (a lock another thread holds here must not reach them locked)."""
from __future__ import annotations

import os
import threading
import time

import numpy as np

from texture import parallel
from texture.parallel import parallel_map

LOCK = threading.Lock()


def _job(x, shared):
    return x * shared["factor"] + shared["offset"][x], os.getpid()


def _take_lock(x, shared):
    got = LOCK.acquire(timeout=2.0)
    if got:
        LOCK.release()
    return got


def test_parallel_map_matches_serial_and_uses_other_processes():
    shared = {"factor": 3, "offset": np.arange(10) ** 2}
    jobs = list(range(10))
    par = parallel_map(_job, jobs, workers=2, shared=shared)
    ser = parallel_map(_job, jobs, workers=2, shared=shared, parallel=False)
    assert [r for r, _ in par] == [r for r, _ in ser] == [3 * x + x * x for x in jobs]
    assert {pid for _, pid in ser} == {os.getpid()}
    assert os.getpid() not in {pid for _, pid in par}
    assert parallel.peak_worker_rss_mb() > 10  # a Python worker with numpy loaded


def test_workers_do_not_inherit_a_lock_another_thread_holds():
    # a forked worker would copy LOCK in its held state and wait out the timeout (False)
    held, release = threading.Event(), threading.Event()

    def hold():
        with LOCK:
            held.set()
            release.wait(30)

    t = threading.Thread(target=hold)
    t.start()
    try:
        held.wait(5)
        assert parallel_map(_take_lock, [0, 1], workers=2) == [True, True]
    finally:
        release.set()
        t.join()


def _hang_in_a_worker(x, shared):
    if os.getpid() != shared["caller"] and x == 1:
        time.sleep(600)  # as a worker stuck in xatlas's shutdown
    return x * 10


def test_a_stalled_pool_is_killed_and_its_unfinished_jobs_run_here(monkeypatch):
    monkeypatch.setattr(parallel, "STALL_SECONDS", 3.0)
    t0 = time.perf_counter()
    got = parallel_map(_hang_in_a_worker, [0, 1, 2, 3], workers=2, shared={"caller": os.getpid()})
    assert got == [0, 10, 20, 30]
    assert time.perf_counter() - t0 < 60


def test_a_caller_with_short_jobs_waits_out_its_own_shorter_stall():
    # STALL_SECONDS stays at its default (minutes): the call's own value decides
    assert parallel.STALL_SECONDS >= 60
    t0 = time.perf_counter()
    got = parallel_map(_hang_in_a_worker, [0, 1, 2, 3], workers=2, shared={"caller": os.getpid()}, stall_seconds=2.0)
    assert got == [0, 10, 20, 30]
    assert time.perf_counter() - t0 < 30


def test_jobs_of_a_killed_pool_run_here_even_once_the_pool_marked_them_broken(monkeypatch):
    # the executor's thread marks a killed pool's unfinished futures broken at its own pace;
    # waiting for it here makes the slow-reader side of that race certain
    from concurrent.futures import wait

    pooled = parallel._pooled

    def pooled_then_wait(*args):
        futures = pooled(*args)
        wait(futures, timeout=30)
        return futures

    monkeypatch.setattr(parallel, "STALL_SECONDS", 3.0)
    monkeypatch.setattr(parallel, "_pooled", pooled_then_wait)
    assert parallel_map(_hang_in_a_worker, [0, 1, 2, 3], workers=2, shared={"caller": os.getpid()}) == [0, 10, 20, 30]


def test_parallel_map_one_worker_runs_here():
    assert parallel_map(_job, [1, 2], workers=1, shared={"factor": 1, "offset": [0, 5, 7]}) == [
        (6, os.getpid()), (9, os.getpid())]


def _blas_threads(x=None, shared=None):
    from threadpoolctl import threadpool_info

    return {p["filepath"]: p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"}


def test_each_worker_runs_its_blas_on_one_thread_and_the_caller_keeps_its_own():
    # two workers whose BLAS threads spin on two cores starve each other (the module doc);
    # numpy and scipy each load an OpenBLAS, and each must be limited there
    import scipy.linalg  # noqa: F401  (scipy's OpenBLAS, loaded here as in the workers)

    before = _blas_threads()
    got = parallel_map(_blas_threads, [0, 1, 2, 3], workers=2)
    assert all(len(g) >= 2 and set(g.values()) == {1} for g in got)
    assert _blas_threads() == before  # the caller's own pools are left as they were


def _busy_in_a_worker(x, shared):
    if os.getpid() != shared["caller"]:
        end = time.process_time() + shared["seconds"]
        while time.process_time() < end:  # computing, as a long SLIM job does
            pass
    return x, os.getpid()


def test_a_pool_whose_workers_compute_past_the_stall_is_not_taken_for_hung():
    # each job computes for 3 CPU seconds, past a 1 s stall: its workers use CPU, so the pool
    # is waited for and every job runs once, in a worker (a killed pool reruns them here)
    caller = os.getpid()
    got = parallel_map(_busy_in_a_worker, [0, 1], workers=2, shared={"caller": caller, "seconds": 3.0},
                       stall_seconds=1.0)
    assert [x for x, _ in got] == [0, 1]
    assert caller not in {pid for _, pid in got}
