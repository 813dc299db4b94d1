"""Running emcee in flushed batches: pools, random streams, initial walkers, the chain loop.

:func:`run_chain` advances an ensemble ``flush_every`` steps at a time and writes the whole chain
with emcee's random state through :class:`.chains.ChainStore` after every batch, so a killed run
loses at most one batch and continues exactly where it stopped; convergence is checked every
``check_every`` steps (:func:`.diagnostics.convergence_diagnostics`). Every template (and the
no-planet run) has its own random streams (:func:`streams`). Pools: ``processes=k`` runs walkers
in a ``multiprocessing`` pool whose workers receive the log-posterior once (pool initializer;
emcee #199) and pin BLAS threads; ``pool="mpi"`` uses ``schwimmbad.MPIPool``.
"""

from __future__ import annotations

import logging
import os
import zlib

import numpy as np

from ..._threads import blas_threads
from ...exceptions import InputError
from ...units import wrap_angle
from .chains import ChainState
from .diagnostics import convergence_diagnostics
from .conditional import PARAMETER_NAMES
from .moves import default_moves
from .priors import N_DIM
from .results import wrap_phi
from .settings import SamplingSettings

__all__ = ["initial_walkers", "make_pool", "run_chain", "streams"]

log = logging.getLogger(__name__)


# -- worker-side globals (load the log-posterior once per process, emcee #199) ----------------------
_WORKER_LOGPOST = None


def _pin_threads() -> None:
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
        os.environ[var] = "1"
    blas_threads(1, all_pools=True)  # for the rest of this worker process


def _init_worker(logpost) -> None:
    global _WORKER_LOGPOST
    _pin_threads()
    _WORKER_LOGPOST = logpost


def _worker_log_prob(theta):
    return _WORKER_LOGPOST(theta)


def make_pool(pool, processes, logpost):
    """(pool object or None, owned, emcee log-prob function, is_worker)."""
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

        mp = multiprocessing.Pool(processes, initializer=_init_worker, initargs=(logpost,))
        return mp, True, _worker_log_prob, False
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
        if p0.shape != (n_walkers, N_DIM):
            raise InputError(f"initial walkers have shape {p0.shape}, expected ({n_walkers}, {N_DIM})")
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


def run_chain(store, saved, inputs, logpost, theta_map, cov, priors, *, settings: SamplingSettings, streams,
              name: str, progress: bool = False):
    """Sample in batches, flushing each to ``store``.

    ``settings`` gives the walkers, steps, flushes, convergence test, pool, moves and initial
    walkers (:class:`SamplingSettings`); ``streams`` the template's random streams (:func:`streams`).

    Returns ``(chain, log_prob, blobs, accepted, mapper, owned pool or None, log-prob function)``,
    or None on an MPI worker rank.
    """
    n_walkers, n_steps, max_steps = settings.n_walkers, settings.n_steps, settings.max_steps
    check_every, flush_every, min_ess = settings.check_every, settings.flush_every, settings.min_ess
    pool, processes, moves, initial = settings.pool, settings.processes, settings.moves, settings.initial
    import emcee
    from emcee.state import State

    rng_init, emcee_seed, _, _ = streams
    pool_obj, owned, fn, is_worker = make_pool(pool, processes, logpost)
    if is_worker:
        return None
    sampler = emcee.EnsembleSampler(n_walkers, N_DIM, fn, pool=pool_obj,
                                    moves=moves if moves is not None else default_moves())
    if saved is not None and saved.iteration > 0:
        chain, log_prob, blobs, accepted = saved.chain, saved.log_prob, saved.blobs, saved.accepted.astype(float)
        state = State(chain[-1], log_prob=log_prob[-1], blobs=None if blobs is None else blobs[-1],
                      random_state=saved.random_state)
        log.info("%s: resuming %s at step %d", name, store.path, saved.iteration)
    else:
        p0 = initial_walkers(_as_scalar(logpost), theta_map, cov, priors, n_walkers, rng_init, initial)
        chain = np.empty((0, n_walkers, N_DIM))
        log_prob = np.empty((0, n_walkers))
        blobs = np.empty((0, n_walkers, 2))
        accepted = np.zeros(n_walkers)
        state = State(p0, random_state=np.random.RandomState(emcee_seed).get_state())
    target = n_steps if n_steps is not None else max_steps
    bar = _bar(progress, target, chain.shape[0], name)
    try:
        while chain.shape[0] < target:
            stop = min(target, (chain.shape[0] // flush_every + 1) * flush_every)
            if n_steps is None:  # convergence checks land on multiples of check_every
                stop = min(stop, (chain.shape[0] // check_every + 1) * check_every)
            sampler.reset()
            state = sampler.run_mcmc(state, stop - chain.shape[0], progress=False)
            chain = np.concatenate([chain, sampler.get_chain()])
            log_prob = np.concatenate([log_prob, sampler.get_log_prob()])
            blobs = np.concatenate([blobs, sampler.get_blobs()])
            accepted = accepted + sampler.backend.accepted
            store.write(ChainState(chain, log_prob, blobs, accepted, state.random_state, inputs))
            bar.update(stop - bar.n)
            if n_steps is None and chain.shape[0] % check_every == 0 and chain.shape[0] >= 2 * check_every:
                diag = convergence_diagnostics(chain, min_ess=min_ess)
                log.info("%s: %d steps, max tau %.1f, min ESS %.0f", name, chain.shape[0], diag["tau_max"],
                         min(diag["ess"].values()))
                if diag["converged"]:
                    break
    except BaseException:
        if owned:
            getattr(pool_obj, "terminate", pool_obj.close)()
        raise
    finally:
        bar.close()
    mapper = pool_obj.map if pool_obj is not None else map
    return chain, log_prob, blobs, accepted, mapper, (pool_obj if owned else None), fn


def _as_scalar(logpost):
    return lambda t: _value(logpost(t))


def _bar(enabled: bool, total: int, initial: int, name: str):
    from tqdm.auto import tqdm

    return tqdm(total=total, initial=initial, desc=f"{name}: steps", unit="step", disable=not enabled,
                leave=False, mininterval=1.0)


class _ChainData:
    """arviz view of an in-memory chain (phi_p wrapped around its circular mean)."""

    def __init__(self, chain):
        self.chain = wrap_phi(chain)[0]

    def inference_data(self):
        import warnings

        from .diagnostics import _ChainView, _import_arviz

        az = _import_arviz()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            return az.from_emcee(_ChainView(self.chain, np.zeros(self.chain.shape[:2])),
                                 var_names=list(PARAMETER_NAMES))
