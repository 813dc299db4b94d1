"""Posterior sampling: emcee over planet position and disc geometry, templates as a discrete choice.

Continuous parameters (:data:`spiralbayes.posterior.PARAMETER_NAMES`): ``r_p`` [arcsec],
``phi_p`` [rad], ``inc`` [deg], ``PA`` [deg], ``dRA``, ``dDec`` [arcsec]. The likelihood is
:class:`spiralbayes.posterior.SpiralLikelihood` (axisymmetric profile held at the frank fit,
its visibilities re-evaluated under each sampled geometry).

Priors (:class:`Priors`): ``r_p`` uniform on ``[r_min, r_max]`` (default: the disc's extent,
``R_eff / 25`` to ``R_eff``, never beyond the profile's ``Rmax``), ``phi_p`` uniform on the circle
(the likelihood is 2 pi-periodic, so walkers wrap around freely; samples are reported wrapped into
``[mu - pi, mu + pi)`` around their circular mean), and Gaussian ``inc``, ``PA``, ``dRA``,
``dDec`` centred on the frank geometry with user-set widths (defaults 5 deg, 5 deg, 0.05 arcsec,
0.05 arcsec).

The template is a discrete parameter. **Choice: per-template runs combined by their evidence.**
For each template ``T`` the posterior of the six continuous parameters is sampled with emcee and
its evidence ``Z_T = int L pi`` estimated; then ``P(T | data) = Z_T pi_T / sum_T' Z_T' pi_T'``
(uniform ``pi_T`` by default). Why not an emcee move over a template index carried in the state:
the modes of different templates sit at different ``(r_p, phi_p)`` and geometries, so a jump
between templates at fixed continuous parameters is almost always rejected (a mirror template's
best planet lies elsewhere), and affine-invariant stretch/DE moves are undefined on a discrete
coordinate — mixing would be poor and hard to diagnose. Per-template runs are independent
(parallel over templates or walkers, resumable one by one), each has its own convergence test,
and the evidences come from two estimators that check each other:

* ``laplace``: Gaussian approximation at the optimum, ``ln Z = ln(L pi)(theta*) + (d/2) ln 2 pi +
  (1/2) ln det Sigma`` with ``Sigma`` from a finite-difference Hessian;
* ``importance`` (used when a chain exists): importance sampling of ``L pi`` with a multivariate
  Student-t (5 degrees of freedom) proposal fitted to the chain, ``Z = E_q[L pi / q]``; its error
  comes from the weights' variance. A Gaussian/unimodal posterior is assumed by both; a very large
  error flags a multimodal or badly fitted posterior.

Templates whose grid-scan peak (``ScanResult``) is far below the best template's
(``prune_delta_lnL``, default 25 in ln L) get the Laplace evidence only (no chain): their
probabilities are < e^-20 of the best's anyway. Thermodynamic integration or nested sampling would be
exact but 10-100x more expensive.

Chains: emcee's ``HDFBackend``, by default ``chains/<run_name>.h5``, one group per template
(named after it), with the run's inputs (priors, template metadata, geometry, data hash, table
settings) and package versions as JSON attributes of the group and the file. **Resuming**: emcee's
``run_mcmc`` always *adds* ``n`` steps to what the backend holds; :func:`sample_posterior` takes the
*total* ``n_steps`` and runs only the remainder (a finished run does nothing), and refuses to
resume a file written for other inputs.

Convergence: emcee's integrated autocorrelation time ``tau`` is the primary test — chain length
> 50 tau for every parameter (after burn-in; burn-in = 5 max tau) — with ESS = n_walkers n_steps / tau.
arviz's R-hat and ESS (:meth:`TemplateRun.inference_data`) are reported too, with the caveat that
emcee's walkers are not independent chains (R-hat near 1 is necessary, not sufficient). Policy for
unconverged runs: ``convergence="raise" | "warn" | "ignore"``; the message says roughly how many
more steps are needed.

Parallelism: ``processes=k`` runs walkers in a ``multiprocessing`` pool whose workers receive the
likelihood once (pool initializer; emcee #199) and pin BLAS threads; ``pool="mpi"`` uses
``schwimmbad.MPIPool`` (imported lazily): run the *same script on every rank*
(``mpiexec -n 8 python run.py``); every rank builds the likelihood tables, worker ranks serve
log-probability calls until the master closes the pool, then move on to the next template
together; only the master returns a result. Any object with a ``map`` method may also be passed
as ``pool``.
"""

from __future__ import annotations

import json
import logging
import os
import time
from pathlib import Path

import numpy as np

from .._provenance import data_hash, json_default, provenance_record
from ..axisymmetric import DEFAULT_HYPERPARAMETERS, fit_axisymmetric
from ..exceptions import InputError
from ..geometry import DiscGeometry
from ..templates.template import template_metadata
from .diagnostics import (
    _apply_policy,
    _convergence_message,
    arviz_diagnostics,
    convergence_diagnostics,
)
from .evidence import _hessian_cov, _importance_evidence, _laplace_evidence
from .likelihood import PARAMETER_NAMES, SpiralLikelihood
from .optimise import find_map
from .priors import N_DIM, Priors
from .results import PosteriorResult, TemplateRun, _wrap_phi

__all__ = ["LogPosterior", "refit_axisymmetric", "sample_posterior"]

log = logging.getLogger(__name__)

HDF5_KIND = "spiralbayes.PosteriorRun"


class LogPosterior:
    """``ln pi(theta) + ln L(theta)`` for one template (picklable; the emcee log-probability)."""

    def __init__(self, likelihood: SpiralLikelihood, priors: Priors):
        self.likelihood = likelihood
        self.priors = priors

    def __call__(self, theta) -> float:
        lp = self.priors.log_prior(theta)
        if not np.isfinite(lp):
            return -np.inf
        return lp + self.likelihood(theta)


# -- worker-side globals (load the likelihood once per process, emcee #199) -----------------------
_WORKER_LOGPOST: LogPosterior | None = None


def _pin_threads() -> None:
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
        os.environ[var] = "1"
    try:  # pragma: no cover - optional
        from threadpoolctl import threadpool_limits

        threadpool_limits(1)
    except ImportError:
        pass


def _init_worker(logpost: LogPosterior) -> None:
    global _WORKER_LOGPOST
    _pin_threads()
    _WORKER_LOGPOST = logpost


def _worker_log_prob(theta) -> float:
    return _WORKER_LOGPOST(theta)


def _initial_walkers(logpost, theta_map, cov, priors, n_walkers, rng, initial=None):
    """Walkers around the optimum (Laplace covariance / 4), redrawn where ln p = -inf."""
    if initial is not None:
        p0 = np.array(initial, dtype=float)
        if p0.shape != (n_walkers, N_DIM):
            raise InputError(f"initial walkers have shape {p0.shape}, expected ({n_walkers}, {N_DIM})")
    else:
        p0 = rng.multivariate_normal(theta_map, cov * 0.25, size=n_walkers)
    lp = np.array([logpost(p) for p in p0])
    for _ in range(50 if initial is None else 0):
        bad = ~np.isfinite(lp)
        if not bad.any():
            break
        p0[bad] = rng.multivariate_normal(theta_map, cov * 0.05, size=int(bad.sum()))
        lp[bad] = [logpost(p) for p in p0[bad]]
    bad = np.flatnonzero(~np.isfinite(lp))
    if bad.size:
        i = int(bad[0])
        raise InputError(f"walker {i} starts at theta = {np.round(p0[i], 6).tolist()} "
                         f"({', '.join(PARAMETER_NAMES)}) where the log posterior is -inf "
                         f"({bad.size} such walkers): move the start inside the prior "
                         f"(r_p in {priors.r_p}, 0 <= inc < 90)")
    return p0


def _inputs_record(vis, priors, template, likelihood, n_walkers, moves_name) -> dict:

    return {"priors": priors.to_dict(), "template": template_metadata(template),
            "data_hash": data_hash(vis.u, vis.v, vis.V, vis.weights), "n_data": int(vis.n),
            "reference_geometry": likelihood.reference_geometry.to_dict(), "n_walkers": int(n_walkers),
            "parameters": list(PARAMETER_NAMES), "moves": moves_name}


def _check_resume(path, group, inputs):
    import h5py

    if not Path(path).exists():
        return 0
    with h5py.File(path, "r") as f:
        if group not in f:
            return 0
        g = f[group]
        stored = json.loads(g.attrs.get("spiralbayes_inputs", "{}"))
        iteration = int(g.attrs.get("iteration", 0))
    if iteration and stored != json.loads(json.dumps(inputs, default=json_default)):
        diff = sorted(k for k in set(stored) | set(inputs) if stored.get(k) != json.loads(json.dumps(inputs.get(k), default=json_default)))
        raise InputError(f"chain file {path} (group {group!r}) was written for different inputs (differ in {diff}): "
                         "delete it or choose another run_name to start afresh")
    return iteration


def _write_attrs(path, group, kind: str | None = None, **items):
    """JSON-encode ``items`` as attributes of ``group``; tag the file with ``kind`` when given."""
    import h5py

    with h5py.File(path, "a") as f:
        if kind is not None:
            f.attrs["kind"] = kind
        g = f.require_group(group)
        for k, v in items.items():
            g.attrs[k] = json.dumps(v, default=json_default)


def _make_pool(pool, processes, logpost):
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


def _default_moves():
    import emcee

    return [(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)]


def _sample_one(vis, axisymmetric, template, priors, *, scan, chain_path, n_walkers, n_steps, max_steps,
                check_every, convergence, min_ess, pool, processes, rng, moves, progress, evidence_draws,
                likelihood_kwargs, mode, initial):
    import emcee


    t0 = time.perf_counter()
    name = getattr(template, "name", "template")
    likelihood = SpiralLikelihood(vis, axisymmetric, template, priors.r_p,
                                  reference_geometry=DiscGeometry(priors.inc[0], priors.PA[0], priors.dRA[0], priors.dDec[0]),
                                  **likelihood_kwargs)
    logpost = LogPosterior(likelihood, priors)
    scales = priors.widths * np.array([0.1, 0.05, 0.1, 0.1, 0.1, 0.1])
    theta_map = find_map(logpost, likelihood, priors, scan, name, scales)
    cov = _hessian_cov(logpost, theta_map, scales, priors)
    lp_map = logpost(theta_map)
    lnz_laplace = _laplace_evidence(lp_map, cov)
    meta = template_metadata(template)
    log.info("%s: optimum ln p = %.2f at %s; Laplace ln Z = %.2f", name, lp_map, np.round(theta_map, 5), lnz_laplace)
    if mode == "laplace":
        samples = rng.multivariate_normal(theta_map, cov, size=4000)
        samples, _ = _wrap_phi(samples)
        return TemplateRun(name, meta, "laplace", samples, theta_map, cov, lnz_laplace, float("nan"), lnz_laplace,
                           {"time_s": time.perf_counter() - t0, "likelihood": likelihood.describe()})

    group = name
    inputs = _inputs_record(vis, priors, template, likelihood, n_walkers, "DE+snooker" if moves is None else repr(moves))
    done = _check_resume(chain_path, group, inputs)
    backend = emcee.backends.HDFBackend(str(chain_path), name=group)
    if done == 0:
        backend.reset(n_walkers, N_DIM)
    elif backend.shape != (n_walkers, N_DIM):
        raise InputError(f"chain file {chain_path} has {backend.shape} walkers x dims, asked for ({n_walkers}, {N_DIM})")
    _write_attrs(chain_path, group, spiralbayes_inputs=inputs, provenance=provenance_record(
        likelihood=likelihood.describe()))
    pool_obj, owned, fn, is_worker = _make_pool(pool, processes, logpost)
    if is_worker:
        return None
    try:
        sampler = emcee.EnsembleSampler(n_walkers, N_DIM, fn, pool=pool_obj, backend=backend,
                                        moves=moves if moves is not None else _default_moves())
        sampler.random_state = np.random.RandomState(int(rng.integers(2 ** 31))).get_state()
        state = backend.get_last_sample() if done else _initial_walkers(logpost, theta_map, cov, priors, n_walkers,
                                                                         rng, initial)
        if done:
            log.info("%s: resuming %s at step %d", name, chain_path, done)
        target = n_steps if n_steps is not None else max_steps
        while backend.iteration < target:
            chunk = min(check_every, target - backend.iteration) if n_steps is None else target - backend.iteration
            state = sampler.run_mcmc(state, chunk, progress=progress)
            if n_steps is None and backend.iteration >= 2 * check_every:
                diag = convergence_diagnostics(backend.get_chain(), min_ess=min_ess)
                log.info("%s: %d steps, max tau %.1f", name, backend.iteration, diag["tau_max"])
                if diag["converged"]:
                    break
        chain = backend.get_chain()
        diag = convergence_diagnostics(chain, min_ess=min_ess)
        mapper = pool_obj.map if pool_obj is not None else map
        flat = backend.get_chain(discard=diag["burn_in"], thin=diag["thin"], flat=True)
        lnz, lnz_err, ess_w = _importance_evidence(fn, flat, evidence_draws, rng, mapper)
    finally:
        if owned:
            pool_obj.close()
    run = TemplateRun(name, meta, "mcmc", _wrap_phi(flat)[0], theta_map, cov, lnz, lnz_err, lnz_laplace,
                      {**diag, "importance_ess": ess_w, "time_s": time.perf_counter() - t0,
                       "acceptance": float(np.mean(sampler.acceptance_fraction)), "likelihood": likelihood.describe()},
                      str(chain_path), group)
    try:
        run.diagnostics["arviz"] = arviz_diagnostics(run.inference_data())
    except Exception as exc:  # pragma: no cover - diagnostics must not lose a run
        log.warning("arviz diagnostics failed: %s", exc)
    _write_attrs(chain_path, group, result=run.to_json())
    if not diag["converged"]:
        _apply_policy(convergence, _convergence_message(name, diag))
    return run


def sample_posterior(vis, axisymmetric, templates, *, scan=None, priors: Priors | None = None,
                     run_name: str = "posterior", chains_dir="chains", n_walkers: int = 32,
                     n_steps: int | None = None, max_steps: int = 20000, check_every: int = 500,
                     convergence: str = "warn", min_ess: float = 400.0, processes: int | None = None, pool=None,
                     seed: int = 0, moves=None, template_prior=None, mcmc_templates=None,
                     prune_delta_lnL: float = 25.0, evidence_draws: int = 2000, progress: bool = True,
                     initial=None, likelihood_kwargs: dict | None = None) -> PosteriorResult:
    """Sample the posterior of every template and combine them by their evidence.

    Parameters
    ----------
    vis : Visibilities
    axisymmetric : AxisymmetricModel
        The frank fit (held fixed); its geometry centres the default priors.
    templates : SpiralTemplate, TemplateBank or sequence
    scan : ScanResult, optional
        Initialises each template's optimiser from its best grid instances, and prunes templates
        (``prune_delta_lnL``).
    priors : Priors, optional
        Default :meth:`Priors.default` (``axisymmetric``).
    run_name, chains_dir : str, path
        Chains go to ``<chains_dir>/<run_name>.h5`` (one group per template). An existing file with
        the same inputs is resumed.
    n_walkers : int
        emcee walkers (>= 2 x 6; default 32).
    n_steps : int, optional
        Total steps per walker (an interrupted run continues up to this total). ``None``: run in
        chunks of ``check_every`` until converged (> 50 tau and ESS >= ``min_ess``) or
        ``max_steps``.
    convergence : {'warn', 'raise', 'ignore'}
        What to do when a chain fails the 50-tau / ESS test.
    processes : int, optional
        Run walkers in a multiprocessing pool of this size. ``pool``: ``"mpi"`` or any object with
        ``map`` (then ``processes`` is ignored).
    seed : int
        Seed of the initialisation, the moves and the evidence draws.
    moves : emcee moves, optional
        Default: 80 % DEMove + 20 % DESnookerMove.
    template_prior : array_like, optional
        Prior probabilities of the templates (default uniform).
    mcmc_templates : list of str, optional
        Templates that get a chain; the others get the Laplace evidence only. Default: those
        within ``prune_delta_lnL`` of the best scan peak (every template without a scan).
    evidence_draws : int
        Proposal draws of the importance-sampled evidence.
    initial : array_like, optional
        Explicit initial walkers (n_walkers, 6) for every template (checked: none may start at
        -inf).
    likelihood_kwargs : dict, optional
        Passed to :class:`~spiralbayes.posterior.SpiralLikelihood` (``epsilon``, ``rp_tolerance``,
        ``oversample``, ...).
    progress : bool
        Show emcee's progress bar for each chunk of steps (default True).

    Returns
    -------
    PosteriorResult
    """
    if convergence not in ("warn", "raise", "ignore"):
        raise InputError(f"convergence = {convergence!r}: use 'warn', 'raise' or 'ignore'")
    if hasattr(templates, "evaluate"):
        templates = [templates]
    templates = list(templates)
    if not templates:
        raise InputError("no templates: pass a SpiralTemplate, a TemplateBank or a list of them")
    names = [t.name for t in templates]
    if len(set(names)) != len(names):
        raise InputError(f"template names must be unique, got {names}")
    if n_walkers < 2 * N_DIM:
        raise InputError(f"n_walkers = {n_walkers}: emcee needs at least 2 x {N_DIM} = {2 * N_DIM} walkers")
    if n_steps is not None and n_steps < 1:
        raise InputError(f"n_steps = {n_steps} must be a positive number of steps")
    vis = vis.standardised()
    priors = priors or Priors.default(axisymmetric)
    priors.check_data(vis, axisymmetric)
    prior_t = np.full(len(templates), 1.0 / len(templates)) if template_prior is None else np.asarray(template_prior, float)
    if prior_t.shape != (len(templates),) or np.any(prior_t <= 0):
        raise InputError("template_prior must hold one positive probability per template")
    prior_t = prior_t / prior_t.sum()
    chain_path = Path(chains_dir) / f"{run_name}.h5"
    chain_path.parent.mkdir(parents=True, exist_ok=True)
    selected = _select_mcmc(names, scan, mcmc_templates, prune_delta_lnL)
    rng = np.random.default_rng(seed)
    runs = []
    for template in templates:
        mode = "mcmc" if template.name in selected else "laplace"
        run = _sample_one(vis, axisymmetric, template, priors, scan=scan, chain_path=chain_path, n_walkers=n_walkers,
                          n_steps=n_steps, max_steps=max_steps, check_every=check_every, convergence=convergence,
                          min_ess=min_ess, pool=pool, processes=processes, rng=rng, moves=moves, progress=progress,
                          evidence_draws=evidence_draws, likelihood_kwargs=likelihood_kwargs or {}, mode=mode,
                          initial=initial)
        if run is None:  # an MPI worker rank
            continue
        runs.append(run)
    if pool == "mpi" and not runs:
        return None
    result = PosteriorResult(runs, priors, prior_t, run_name, str(chain_path),
                             provenance_record(data_hash=data_hash(vis.u, vis.v, vis.V, vis.weights),
                                               geometry=axisymmetric.geometry.to_dict()))
    _write_attrs(chain_path, "/", kind=HDF5_KIND, summary=result.to_json())
    return result


def _select_mcmc(names, scan, mcmc_templates, prune_delta_lnL) -> set:
    if mcmc_templates is not None:
        unknown = set(mcmc_templates) - set(names)
        if unknown:
            raise InputError(f"mcmc_templates names unknown templates {sorted(unknown)}")
        return set(mcmc_templates)
    if scan is None:
        return set(names)
    peaks = {}
    dchi2 = scan.delta_chi2()
    for name in names:
        try:
            peaks[name] = float(np.nanmax(dchi2[scan.template_index(name)]))
        except (KeyError, IndexError):
            peaks[name] = np.inf
    best = max(peaks.values())
    return {n for n, p in peaks.items() if (best - p) / 2 <= prune_delta_lnL}


def refit_axisymmetric(vis, axisymmetric, result, template=None, *, progress: bool = False):
    """Refit the frank profile at the posterior-median geometry: the likelihood's optional refit.

    The likelihood holds the axisymmetric profile at the frank fit while the geometry varies. A
    profile fitted at a wrong geometry absorbs part of the error (the inclination is nearly
    degenerate with the profile's normalisation and radial scale, flux ∝ cos i), so the geometry
    posterior is conditional on that profile and can be biased by it. Iterate: refit here with the
    same hyperparameters, then call :func:`sample_posterior` again with the returned model.

    Parameters
    ----------
    vis : Visibilities
    axisymmetric : AxisymmetricModel
        The model used for ``result``; its frank hyperparameters are reused.
    result : PosteriorResult or TemplateRun
    template : str or int, optional
        Which template's posterior gives the geometry (default: the most probable).
    """
    run = result.run(template) if hasattr(result, "run") else result
    median = {name: stats["median"] for name, stats in run.summary().items()}
    geometry = DiscGeometry(median["inc"], median["PA"], median["dRA"], median["dDec"])
    hyper = {k: axisymmetric.hyperparameters.get(k, v) for k, v in DEFAULT_HYPERPARAMETERS.items()}
    log.info("refitting the frank profile at the posterior geometry %s", geometry)
    return fit_axisymmetric(vis, geometry, progress=progress, **hyper)
