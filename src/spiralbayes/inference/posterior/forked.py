"""Forked worker processes that inherit the parent's tables instead of receiving pickled copies.

A template's likelihood holds hundreds of megabytes of tables; a worker forked after they are built
shares them page by page, and only the arguments and results of each task travel (Linux's ``fork``
start method). :func:`forked_map` spreads independent evaluations of one function over such
workers — the table's ``r_p`` nodes, the optimiser's starts — and falls back to the built-in map
where workers cannot be forked (:func:`can_fork`).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterable, Iterator
from typing import Any

from ..._threads import blas_threads

__all__ = ["can_fork", "forked_map", "pin_threads"]

_TASK: Callable[[Any], Any] | None = None  # the function forked_map's workers inherit


def can_fork() -> bool:
    """True where worker processes can be forked: Linux, from the main thread of a process that is not
    itself a daemonic worker (a Dask or multiprocessing worker cannot have children)."""
    import multiprocessing
    import sys
    import threading

    return (sys.platform.startswith("linux") and "fork" in multiprocessing.get_all_start_methods()
            and not multiprocessing.current_process().daemon
            and threading.current_thread() is threading.main_thread())


def pin_threads() -> None:
    """One BLAS/OpenMP thread for the rest of this (worker) process: the workers are the parallelism."""
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
        os.environ[var] = "1"
    blas_threads(1, all_pools=True)


def _run_task(item):
    if _TASK is None:
        raise RuntimeError("this worker process inherited no task: it was not forked by forked_map")
    return _TASK(item)


@contextlib.contextmanager
def forked_map(fn: Callable[[Any], Any], processes: int) -> Iterator[Callable[[Iterable], Iterator]]:
    """A ``map(items)`` of ``fn`` over ``processes`` forked workers: an iterator over the results in the
    items' order, each as soon as it and those before it are done.

    The workers are forked on entry, so they see ``fn`` and everything it refers to as they are then;
    they are stopped on exit. With ``processes <= 1``, or where :func:`can_fork` is False, the map is
    the built-in one, in this process (the same values: every worker runs one BLAS thread, as the
    posterior's own evaluations do).
    """
    if processes <= 1 or not can_fork():
        yield lambda items: map(fn, items)
        return
    import multiprocessing

    global _TASK
    _TASK = fn
    try:
        with multiprocessing.get_context("fork").Pool(int(processes), initializer=pin_threads) as pool:
            yield lambda items: pool.imap(_run_task, items)
    finally:
        _TASK = None
