"""Running emcee in flushed batches: pools, random streams, initial walkers, the chain loop.

:func:`run_chain` advances an ensemble ``flush_every`` steps at a time, storing its steps in a
:class:`.chains.ChainBackend` (an emcee backend) that writes the whole chain with emcee's random
state to the chain file after every batch, so a killed run
loses at most one batch and continues exactly where it stopped; convergence is checked from
``2 check_every`` steps on, after every batch (:func:`.diagnostics.convergence_diagnostics`; a
stopping rule's costlier parts every ``check_every`` steps), so checks fall on the same steps
when a run resumes. Every template (and the
no-planet run) has its own random streams (:func:`streams`). Pools: by default a template's
walkers are evaluated by forked worker processes where the platform forks them (Linux;
:func:`resolve_processes`; a continuous-mass family's node tables are built first, by forked
workers too) and by threads elsewhere (:class:`ThreadMap`, one per available core);
``processes=k`` asks for ``k`` workers, which receive the log-posterior once (pool initializer;
emcee #199) and pin BLAS threads; ``pool="mpi"`` uses ``schwimmbad.MPIPool``.
"""

from __future__ import annotations

import contextlib
import logging
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...exceptions import InputError
from ...units import wrap_angle
from .chains import ChainBackend
from .diagnostics import convergence_diagnostics
from .forked import can_fork, pin_threads
from .conditional import PARAMETER_NAMES
from .moves import default_moves
from .settings import SamplingSettings

__all__ = ["MAX_AUTO_THREADS", "ThreadMap", "WalkerPool", "initial_walkers", "make_pool", "resolve_processes",
           "resolve_threads", "run_chain", "streams", "walker_pool"]

log = logging.getLogger(__name__)


# -- worker-side globals (load the log-posterior once per process, emcee #199) ----------------------
_WORKER_LOGPOST: Callable[[np.ndarray], Any] | None = None


def _init_worker(logpost) -> None:
    global _WORKER_LOGPOST
    pin_threads()
    _WORKER_LOGPOST = logpost


def _worker_log_prob(theta):
    if _WORKER_LOGPOST is None:
        raise RuntimeError("this worker process holds no log posterior: make_pool did not initialise it")
    return _WORKER_LOGPOST(theta)


MAX_AUTO_THREADS = 4
"""Most walker threads (or processes) chosen automatically (beyond it the Python between the NUFFTs
holds threads back)."""


class ThreadMap:
    """``map`` over a thread pool, for emcee's ``pool``: the likelihood's NUFFTs and linear algebra release
    the GIL, and threads share tables that are still being built (a continuous-mass family's nodes).
    Results come back in order, so a run gives the same chain with any number of threads."""

    def __init__(self, threads: int):
        from concurrent.futures import ThreadPoolExecutor

        self.threads = int(threads)
        self._executor = ThreadPoolExecutor(self.threads, thread_name_prefix="spiralbayes-walker")

    def map(self, fn, iterable) -> list:
        return list(self._executor.map(fn, iterable))

    def close(self) -> None:
        self._executor.shutdown(wait=True)

    terminate = close


def resolve_threads(threads: int | None) -> int:
    """The walker threads of ``threads`` (None or 0: one per available core, at most :data:`MAX_AUTO_THREADS`)."""
    if threads:
        return int(threads)
    from ...cluster import available_cores

    return max(1, min(available_cores(), MAX_AUTO_THREADS))


def resolve_processes(processes: int | None, threads: int | None) -> int:
    """Worker processes for one template's walkers (1: none; the walkers then go to threads).

    ``processes`` when given (> 0). Otherwise (None or 0) one per available core, at most
    :data:`MAX_AUTO_THREADS`, where workers can be forked: on Linux, from the main thread of a
    process that is not itself a worker (a daemonic Dask or multiprocessing worker cannot have
    children), and when no ``threads`` count (> 0) was asked for. Forked workers share the parent's
    tables page by page and need nothing pickled, and they run the Python between the NUFFTs in
    parallel where threads share one interpreter lock: on 36,000 visibilities and 2 cores an ensemble
    step is about 1.6× faster than with two threads (``benchmarks/bench_sample.py --walker-pools``).
    """
    if processes:
        return int(processes)
    if threads or not can_fork():
        return 1
    return resolve_threads(None)


def make_pool(pool, processes, logpost, threads: int | None = 1):
    """(pool object or None, owned, emcee log-prob function, is_worker); ``threads`` applies when neither a
    pool nor worker processes are asked for (:func:`resolve_threads`)."""
    if pool == "mpi":
        from schwimmbad import MPIPool  # lazy: only needed on clusters

        global _WORKER_LOGPOST
        _WORKER_LOGPOST = logpost
        mpi = MPIPool()
        if not mpi.is_master():
            mpi.wait()
            return None, False, None, True
        return mpi, True, _worker_log_prob, False
    if pool is not None:
        return pool, False, logpost, False
    if processes and processes > 1:
        import multiprocessing

        # forked where possible: the workers inherit the log posterior instead of unpickling a copy
        context = multiprocessing.get_context("fork" if can_fork() else None)
        mp = context.Pool(processes, initializer=_init_worker, initargs=(logpost,))
        return mp, True, _worker_log_prob, False
    n_threads = resolve_threads(threads)
    if n_threads > 1:
        return ThreadMap(n_threads), True, logpost, False
    return None, False, logpost, False


_MPI_RANK = 0


def _writes_files() -> bool:
    """Only the master rank of an MPI run writes (every rank computes the same no-planet result)."""
    return _MPI_RANK == 0


def _set_mpi_rank(pool) -> None:
    global _MPI_RANK
    _MPI_RANK = 0
    if pool == "mpi":
        from mpi4py import MPI  # lazy: only on clusters

        _MPI_RANK = MPI.COMM_WORLD.Get_rank()


def streams(seed: int, name: str):
    """Independent random streams of one template (or the null): init, emcee, evidence, amplitude."""
    ss = np.random.SeedSequence([int(seed), zlib.crc32(name.encode())])
    init, em, evidence, amplitude = ss.spawn(4)
    return (np.random.default_rng(init), int(em.generate_state(1)[0]), np.random.default_rng(evidence),
            np.random.default_rng(amplitude))


def initial_walkers(logpost, theta_map, cov, priors, n_walkers, rng, initial=None):
    """Walkers around the optimum (Laplace covariance / 4), redrawn where ln p = -inf."""
    if initial is not None:
        p0 = np.array(initial, dtype=float)
        if p0.shape != (n_walkers, len(theta_map)):
            raise InputError(f"initial walkers have shape {p0.shape}, expected ({n_walkers}, {len(theta_map)})")
    else:
        p0 = rng.multivariate_normal(theta_map, cov * 0.25, size=n_walkers)
    p0[:, 1] = wrap_angle(p0[:, 1], 0.0)
    lp = np.array([_value(logpost(p)) for p in p0])
    for _ in range(50 if initial is None else 0):
        bad = ~np.isfinite(lp)
        if not bad.any():
            break
        p0[bad] = rng.multivariate_normal(theta_map, cov * 0.05, size=int(bad.sum()))
        p0[:, 1] = wrap_angle(p0[:, 1], 0.0)
        lp[bad] = [_value(logpost(p)) for p in p0[bad]]
    bad = np.flatnonzero(~np.isfinite(lp))
    if bad.size:
        i = int(bad[0])
        raise InputError(f"walker {i} starts at theta = {np.round(p0[i], 6).tolist()} "
                         f"({', '.join(PARAMETER_NAMES)}) where the log posterior is -inf "
                         f"({bad.size} such walkers): move the start inside the prior "
                         f"(r_p in {priors.r_p}, 0 <= inc < 90)")
    return p0


def _value(out) -> float:
    return float(out[0] if isinstance(out, tuple) else out)


@dataclass
class WalkerPool:
    """Where the walkers' log posteriors are evaluated (see :func:`walker_pool`).

    Attributes
    ----------
    pool : object or None
        The pool emcee maps over (None: serial).
    log_prob : callable
        The function emcee calls (the log posterior, or its worker-side proxy).
    is_worker : bool
        True on an MPI worker rank, which only serves the master and runs nothing itself.
    """

    pool: Any  # anything with emcee's ``map`` (multiprocessing, schwimmbad's MPIPool), or None
    log_prob: Callable[..., Any] | None
    is_worker: bool = False

    @property
    def map(self):
        return self.pool.map if self.pool is not None else map


@contextlib.contextmanager
def walker_pool(pool, processes, logpost, threads: int | None = 1):
    """A :class:`WalkerPool`; a pool made here is closed on exit (terminated on an error)."""
    pool_obj, owned, fn, is_worker = make_pool(pool, processes, logpost, threads)
    try:
        yield WalkerPool(pool_obj, fn, is_worker)
    except BaseException:
        if owned:
            getattr(pool_obj, "terminate", pool_obj.close)()
        raise
    if owned:
        pool_obj.close()


def run_chain(backend: ChainBackend, saved, walkers: WalkerPool, theta_map, cov, priors, *,
              settings: SamplingSettings, streams, name: str, logpost, progress: bool = False,
              stop_check=None) -> ChainBackend:
    """Sample in batches of ``flush_every`` steps, flushing ``backend`` after each; returns it.

    ``saved`` (a :class:`~.chains.ChainState` with steps) is continued exactly; otherwise walkers
    start around ``theta_map`` (:func:`initial_walkers`). With ``n_steps`` None the chain runs
    until converged (checked after every batch from ``2 check_every`` steps on; ``stop_check`` gets
    ``log_prob_fn = None`` except at multiples of ``check_every``) or ``max_steps``. ``settings`` gives the
    walkers, steps, flushes, convergence test, moves and initial walkers (:class:`SamplingSettings`);
    ``streams`` the template's random streams (:func:`streams`).

    ``stop_check(chain, log_prob_fn, mapper)`` returns diagnostics whose ``converged`` stops the
    run (default: every parameter's 50-tau / ESS test; the sampler passes a
    :class:`.stopping.StoppingRule`).
    """
    n_walkers, n_steps, max_steps = settings.n_walkers, settings.n_steps, settings.max_steps
    check_every, flush_every, min_ess = settings.check_every, settings.flush_every, settings.min_ess
    moves, initial = settings.moves, settings.initial
    import emcee
    from emcee.state import State

    rng_init, emcee_seed, _, _ = streams
    if stop_check is None:
        stop_check = lambda c, *_: convergence_diagnostics(c, min_ess=min_ess)  # noqa: E731
    if saved is not None and saved.iteration > 0:
        backend.restore(saved)
        state = backend.get_last_sample()
        log.info("%s: resuming %s at step %d", name, backend.store.path, saved.iteration)
    else:
        backend.reset(n_walkers, len(theta_map))
        p0 = initial_walkers(_as_scalar(logpost), theta_map, cov, priors, n_walkers, rng_init, initial)
        state = State(p0, random_state=np.random.RandomState(emcee_seed).get_state())
    sampler = emcee.EnsembleSampler(n_walkers, len(theta_map), walkers.log_prob, pool=walkers.pool, backend=backend,
                                    moves=moves if moves is not None else default_moves())
    target = n_steps if n_steps is not None else max_steps
    bar = _bar(progress, target, backend.iteration, name)
    try:
        while backend.iteration < target:
            done = backend.iteration
            stop = min(target, (done // flush_every + 1) * flush_every)
            if n_steps is None:  # convergence checks land on multiples of check_every
                stop = min(stop, (done // check_every + 1) * check_every)
            state = sampler.run_mcmc(state, stop - done, progress=False)
            backend.flush()
            bar.update(stop - bar.n)
            if n_steps is None and stop >= 2 * check_every:
                # every parameter's 50-tau test at each flush (emcee's own recipe checks every 100
                # steps; it costs milliseconds), the rest of the stopping rule (an evidence) only
                # every check_every steps
                full = stop % check_every == 0
                diag = stop_check(backend.get_chain(), walkers.log_prob if full else None, walkers.map)
                log.log(logging.INFO if full or diag["converged"] else logging.DEBUG,
                        "%s: %d steps, max tau %.1f, min ESS %.0f", name, stop, diag["tau_max"],
                        min(diag["ess"].values()))
                if diag["converged"]:
                    break
    finally:
        bar.close()
    return backend


def _as_scalar(logpost):
    return lambda t: _value(logpost(t))


def _bar(enabled: bool, total: int, initial: int, name: str):
    from tqdm.auto import tqdm

    return tqdm(total=total, initial=initial, desc=f"{name}: steps", unit="step", disable=not enabled,
                leave=False, mininterval=1.0)
