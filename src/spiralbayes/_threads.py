"""The one place that limits the threads of BLAS and OpenMP pools (through threadpoolctl).

Many small matrix products run slower, not faster, with threaded BLAS on a busy machine: idle
threads spin-wait for work (measured on 2 busy cores: a frank fit 36-50 s instead of 6 s, a
template's scan terms 1.35 s instead of 0.06 s, L-BFGS-B steps 6 ms instead of ~0). A threaded
product may also round differently from a single-threaded one, so code that must give the same
bits in every process (data hashes, resumed runs, Dask workers) runs on one thread.

``threadpoolctl.threadpool_limits`` finds the loaded libraries anew on every call by reading
``/proc/self/maps`` (14 ms per call with this package's dependencies loaded, measured on the
project's 2-core machine — more than the products the scan guards, once per template and radius);
a :class:`threadpoolctl.ThreadpoolController` made once, after NumPy and SciPy's linear algebra
are loaded, and reused costs 0.3 ms per limit.
"""

from __future__ import annotations

import contextlib

__all__ = ["blas_threads"]


def blas_threads(n: int | None = 1, *, all_pools: bool = False):
    """Limit the BLAS thread pools to ``n`` threads.

    Use it as a context manager (``with blas_threads(1): ...``); called alone, the limit holds for
    the rest of the process (as in a worker's initialiser).

    Parameters
    ----------
    n : int or None
        Threads per pool; ``None`` leaves the pools alone (a no-op context).
    all_pools : bool
        Limit every pool threadpoolctl knows (BLAS and OpenMP) rather than BLAS only.

    Returns
    -------
    contextlib.AbstractContextManager
        threadpoolctl's limiter, or a null context when ``n`` is None.
    """
    if n is None:
        return contextlib.nullcontext()
    if all_pools:  # rare (a run's or a worker's start): look afresh, so pools loaded since are included
        from threadpoolctl import threadpool_limits

        return threadpool_limits(limits=int(n))
    return _controller().limit(limits=int(n), user_api="blas")


_CONTROLLER: list = []


def _controller():
    """The process's threadpoolctl controller, made on first use (see the module docstring)."""
    if not _CONTROLLER:
        import numpy  # noqa: F401  (their libraries must be loaded when the controller looks)
        import scipy.linalg  # noqa: F401
        from threadpoolctl import ThreadpoolController  # imported late to keep import time small

        _CONTROLLER.append(ThreadpoolController())
    return _CONTROLLER[0]
