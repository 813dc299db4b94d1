"""The chain backend: batches flushed to the chain file give emcee's own uninterrupted chain, bit for bit.

Reference: ``emcee.EnsembleSampler`` with its default in-memory backend, run in one go from the
same walkers and random state. :func:`run_chain` runs in batches of ``flush_every`` steps through
:class:`ChainBackend`, writes each batch atomically, and a second call continues from the file.
"""

import emcee
import numpy as np
from emcee.state import State

from spiralbayes.inference.posterior.settings import SamplingSettings
from spiralbayes.inference.posterior import (
    ChainBackend,
    ChainStore,
    Priors,
    WalkerPool,
    chain_inference_data,
    default_moves,
    run_chain,
    streams,
)

N_WALKERS, N_DIM = 14, 6
CENTRE = np.array([0.3, 1.0, 30.0, 60.0, 0.0, 0.0])
WIDTH = np.array([0.02, 0.3, 0.5, 0.5, 0.01, 0.01])


def log_prob(theta):
    """A Gaussian with two blobs (as the sampled likelihood returns its amplitude terms)."""
    z = (np.asarray(theta) - CENTRE) / WIDTH
    return -0.5 * float(z @ z), float(z[0]), float(z[1] ** 2)


PRIORS = Priors((0.1, 0.6), (30.0, 1.0), (60.0, 1.0), (0.0, 0.01), (0.0, 0.01))


def _initial():
    return CENTRE + WIDTH * np.random.default_rng(5).normal(size=(N_WALKERS, N_DIM)) * 0.1


def _run(store, saved, n_steps, flush_every):
    settings = SamplingSettings(n_walkers=N_WALKERS, n_steps=n_steps, max_steps=n_steps, check_every=10,
                                flush_every=flush_every, min_ess=0, initial=_initial())
    return run_chain(ChainBackend(store, {"test": 1}), saved, WalkerPool(None, log_prob), CENTRE, np.diag(WIDTH ** 2),
                     PRIORS, settings=settings, progress=False, streams=streams(3, "t"), name="t", logpost=log_prob)


def _emcee_serial(n_steps):
    """The reference: emcee's own sampler, in memory, run in one go from the same walkers and random state."""
    _, seed, _, _ = streams(3, "t")
    reference = emcee.EnsembleSampler(N_WALKERS, N_DIM, log_prob, moves=default_moves())
    reference.run_mcmc(State(_initial(), random_state=np.random.RandomState(seed).get_state()), n_steps,
                       progress=False)
    return reference


def _chain_through(walkers, path, n_steps=30):
    """``n_steps`` of :func:`run_chain` with the walkers evaluated by ``walkers``; the stored chain."""
    settings = SamplingSettings(n_walkers=N_WALKERS, n_steps=n_steps, max_steps=n_steps, check_every=10,
                                flush_every=n_steps, min_ess=0, initial=_initial())
    store = ChainStore(path, "t")
    run_chain(ChainBackend(store, {"test": 1}), None, walkers, CENTRE, np.diag(WIDTH ** 2), PRIORS,
              settings=settings, progress=False, streams=streams(3, "t"), name="t", logpost=log_prob)
    return store.read().chain


def test_batches_and_resume_give_emcees_uninterrupted_chain(tmp_path):
    store = ChainStore(tmp_path / "chains.h5", "t")
    _run(store, None, 23, 7)  # stops after 23 steps: batches of 7, 7, 7, 2
    first = store.read()
    assert first.iteration == 23 and first.inputs == {"test": 1}
    backend = _run(store, first, 40, 7)  # continues from the file to 40
    stored = store.read()

    reference = _emcee_serial(40)
    np.testing.assert_array_equal(stored.chain, reference.get_chain())
    np.testing.assert_array_equal(stored.log_prob, reference.get_log_prob())
    np.testing.assert_array_equal(stored.blobs, reference.get_blobs())
    np.testing.assert_array_equal(stored.accepted, reference.backend.accepted)
    np.testing.assert_array_equal(backend.get_chain(discard=5, thin=3), reference.get_chain(discard=5, thin=3))
    # the file is emcee's HDFBackend layout: emcee reads it back itself
    hdf = emcee.backends.HDFBackend(store.path, name="t", read_only=True)
    np.testing.assert_array_equal(hdf.get_chain(), reference.get_chain())
    assert hdf.iteration == 40


def test_the_backend_grows_geometrically():
    backend = ChainBackend(None, {})
    backend.reset(3, 2)
    sizes = []
    for _ in range(40):
        backend.grow(1, np.zeros((3, 2)))
        sizes.append(len(backend.chain))
        backend.save_step(State(np.ones((3, 2)), log_prob=np.zeros(3), blobs=np.zeros((3, 2))), np.ones(3, bool))
    assert backend.iteration == 40 and len(set(sizes)) == 7  # 1, 2, 4, ..., 64: seven allocations
    assert backend.get_chain().shape == (40, 3, 2) and backend.get_blobs().shape == (40, 3, 2)


def test_inference_data_lays_walkers_out_as_chains():
    chain = np.arange(5 * 4 * 6, dtype=float).reshape(5, 4, 6)  # steps, walkers, parameters
    lp = np.arange(20, dtype=float).reshape(5, 4)
    idata = chain_inference_data(chain, lp)
    r_p = idata.posterior["r_p"].values
    assert r_p.shape == (4, 5)
    np.testing.assert_array_equal(r_p, chain[:, :, 0].T)
    np.testing.assert_array_equal(idata.posterior["dDec"].values, chain[:, :, 5].T)
    np.testing.assert_array_equal(idata.sample_stats["lp"].values, lp.T)


def test_walker_threads_give_the_serial_chain_bit_for_bit(tmp_path):
    """Walker threads (:class:`ThreadMap`, where no worker processes run) give the same chain as emcee's
    serial run, and ``threads = 0`` resolves to the available cores (at most MAX_AUTO_THREADS)."""
    from spiralbayes.inference.posterior import MAX_AUTO_THREADS, ThreadMap, resolve_threads, walker_pool

    assert resolve_threads(3) == 3 and 1 <= resolve_threads(0) == resolve_threads(None) <= MAX_AUTO_THREADS
    with walker_pool(None, None, log_prob, threads=3) as walkers:
        assert isinstance(walkers.pool, ThreadMap) and walkers.pool.threads == 3
        chain = _chain_through(walkers, tmp_path / "threads.h5")
    np.testing.assert_array_equal(chain, _emcee_serial(30).get_chain())
    with walker_pool(None, None, log_prob, threads=1) as walkers:
        assert walkers.pool is None


def _resolve_in_daemon(queue):
    from spiralbayes.inference.posterior import resolve_processes

    queue.put(resolve_processes(None, None))


def test_default_walker_processes_are_forked_where_possible_and_give_the_serial_chain(tmp_path):
    """By default (processes None or 0, no thread count) a template's walkers go to forked worker
    processes on Linux, one per available core up to MAX_AUTO_THREADS, except inside a daemonic
    process (a Dask worker may not have children); the chain is emcee's serial one, bit for bit."""
    import multiprocessing
    import sys

    from spiralbayes.inference.posterior import MAX_AUTO_THREADS, resolve_processes, resolve_threads, walker_pool

    assert resolve_processes(3, None) == 3 and resolve_processes(1, None) == 1
    assert resolve_processes(None, 2) == 1 and resolve_processes(0, 1) == 1  # a thread count asks for threads
    assert resolve_processes(None, 0) == resolve_processes(None, None)  # threads 0 is "automatic", as in TOML
    linux = sys.platform.startswith("linux")
    assert resolve_processes(None, None) == resolve_processes(0, None) == (resolve_threads(None) if linux else 1)
    assert resolve_threads(None) <= MAX_AUTO_THREADS
    if linux:
        ctx = multiprocessing.get_context("fork")
        queue = ctx.Queue()
        daemon = ctx.Process(target=_resolve_in_daemon, args=(queue,), daemon=True)
        daemon.start()
        assert queue.get(timeout=60) == 1
        daemon.join()
    with walker_pool(None, 2, log_prob, threads=None) as walkers:
        assert walkers.pool is not None and walkers.log_prob is not log_prob  # the workers' proxy
        chain = _chain_through(walkers, tmp_path / "processes.h5")
    np.testing.assert_array_equal(chain, _emcee_serial(30).get_chain())


def test_convergence_is_tested_after_every_flush_and_the_costly_rule_every_check_every(tmp_path):
    """From 2 check_every steps on, the 50-tau test follows every flush (emcee's recipe checks every 100
    steps) and the stopping rule gets the log posterior (for its evidence) only at multiples of check_every;
    a chain that passes at 35 steps stops there, not at the next multiple of check_every (40)."""
    calls = []

    def stop_check(chain, log_prob_fn, mapper):
        calls.append((chain.shape[0], log_prob_fn is not None))
        return {"converged": chain.shape[0] >= 35, "tau_max": 1.0, "ess": {"r_p": 100.0}}

    settings = SamplingSettings(n_walkers=N_WALKERS, n_steps=None, max_steps=60, check_every=10, flush_every=5,
                                min_ess=0, initial=_initial())
    store = ChainStore(tmp_path / "chains.h5", "t")
    run_chain(ChainBackend(store, {"test": 1}), None, WalkerPool(None, log_prob), CENTRE, np.diag(WIDTH ** 2),
              PRIORS, settings=settings, progress=False, streams=streams(3, "t"), name="t", logpost=log_prob,
              stop_check=stop_check)
    assert calls == [(20, True), (25, False), (30, True), (35, False)]
    assert store.read().iteration == 35
