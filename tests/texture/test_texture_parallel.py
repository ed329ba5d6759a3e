"""texture.parallel: forked workers give the serial result, in order, with shared state."""
from __future__ import annotations

import os

import numpy as np

from texture.parallel import parallel_map


def _job(x, shared):
    return x * shared["factor"] + shared["offset"][x], os.getpid()


def test_parallel_map_matches_serial_and_uses_other_processes():
    shared = {"factor": 3, "offset": np.arange(10) ** 2}  # reaches the workers by the fork
    jobs = list(range(10))
    par = parallel_map(_job, jobs, workers=2, shared=shared)
    ser = parallel_map(_job, jobs, workers=2, shared=shared, parallel=False)
    assert [r for r, _ in par] == [r for r, _ in ser] == [3 * x + x * x for x in jobs]
    assert {pid for _, pid in ser} == {os.getpid()}
    assert os.getpid() not in {pid for _, pid in par}


def test_parallel_map_one_worker_runs_here():
    assert parallel_map(_job, [1, 2], workers=1, shared={"factor": 1, "offset": [0, 5, 7]}) == [
        (6, os.getpid()), (9, os.getpid())]
