"""One BLAS thread for the product rule's small matrix products, cheaply.

``threadpoolctl.threadpool_limits`` finds the loaded BLAS libraries anew on every call by reading
``/proc/self/maps``: 14 ms per call with this package's dependencies loaded (measured on the
project's 2-core machine), paid once per template and planet radius by the scan, i.e. more than
the product it guards. A :class:`threadpoolctl.ThreadpoolController` made once and reused costs
0.3 ms per limit. It is made after NumPy and SciPy's linear algebra are loaded, so it knows
their BLAS libraries.
"""

from __future__ import annotations

__all__ = ["one_blas_thread"]

_CONTROLLER = []


def one_blas_thread():
    """A context manager holding BLAS to one thread (a threaded product may round differently, and
    the same inputs must give the same bits in every process; small products also ran 20x slower
    with OpenBLAS threads spinning on a busy 2-core machine)."""
    if not _CONTROLLER:
        import numpy  # noqa: F401  (their BLAS must be loaded when the controller looks)
        import scipy.linalg  # noqa: F401
        from threadpoolctl import ThreadpoolController

        _CONTROLLER.append(ThreadpoolController())
    return _CONTROLLER[0].limit(limits=1, user_api="blas")
