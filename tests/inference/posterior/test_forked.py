"""Forked workers: the map's values are the in-process ones, the work happens in the workers, and
where workers cannot be forked the map runs in this process.

Reference: the built-in ``map`` of the same function in this process.
"""

import os
import sys
import threading

import numpy as np
import pytest

from spiralbayes.inference.posterior.forked import can_fork, forked_map

linux = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="workers are forked on Linux only")


def _task_factory():
    table = np.random.default_rng(4).normal(size=(200, 200))
    # a closure over a large array cannot be pickled: the workers must inherit it
    return lambda k: (float(np.linalg.norm(table[k] * np.sin(k))), os.getpid())


@linux
def test_forked_map_inherits_the_function_and_returns_the_in_process_values():
    task = _task_factory()
    items = list(range(40))
    with forked_map(task, 2) as mapped:
        out = list(mapped(items))
    assert [v for v, _ in out] == [task(k)[0] for k in items]  # bit for bit, in the items' order
    assert os.getpid() not in {pid for _, pid in out}  # computed by the workers


def test_forked_map_runs_in_process_where_it_cannot_fork():
    task = _task_factory()
    found = {}

    def from_a_thread():
        found["can_fork"] = can_fork()
        with forked_map(task, 2) as mapped:
            found["pids"] = {pid for _, pid in mapped(range(5))}

    t = threading.Thread(target=from_a_thread)
    t.start()
    t.join()
    assert found == {"can_fork": False, "pids": {os.getpid()}}
    with forked_map(task, 1) as mapped:
        assert {pid for _, pid in mapped(range(5))} == {os.getpid()}
