"""Posterior sampling: no planet against a planet of each template, profile and amplitude integrated out.

Why this module is long: it is the one place where the run's stages meet — the no-planet
hypothesis, the per-template likelihoods, optimisation, emcee with resumable chain files and
pools, the evidences and the combination — and splitting it would scatter one procedure.

Hypotheses (:mod:`~spiralbayes.inference.posterior.results`): the disc alone ("no planet",
parameters ``inc, PA, dRA, dDec``) and,
for every template, the disc plus that spiral (``r_p`` [arcsec], ``phi_p`` [rad], amplitude ``A``
and the same geometry). In both the frank profile is integrated out analytically, and in the
spiral model the amplitude too (:mod:`.likelihood`); priors in :mod:`.priors`.

Procedure (:func:`sample_posterior`):

1. **No planet.** The geometry's posterior mode under the disc-alone likelihood
   (:func:`.optimise.fit_null_geometry`), its Laplace covariance, the profile refitted there
   (the spiral term's profile), and ``ln Z_0`` by importance sampling with a t proposal from the
   Laplace fit (:mod:`.evidence`).
2. **Which templates are sampled.** With a scan, every template's Bayes factor is first read off
   the scan's grid (:mod:`.scan_evidence`: milliseconds for the whole bank); the ``max_chains``
   best within ``prune_delta_lnL`` of the best get a chain, the others keep the grid's evidence
   (``pruned_evidence = "laplace"``: a Laplace evidence from a table over a window around the scan's
   peak instead). Without a scan every template is sampled.
3. **Each sampled template** gets its likelihood tables (mirror templates share their partner's), its
   mode (started from the no-planet geometry and the scan's best instances,
   :func:`.optimise.find_map`), then a chain. emcee samples ``(r_p, phi_p, inc, PA, dRA, dDec)`` with
   differential evolution and normal proposals fitted to the ensemble (:func:`.moves.default_moves`);
   ``phi_p`` lives on the circle. ``A`` is integrated out of the target and drawn
   exactly for every stored sample from its conditional posterior (the amplitude terms are
   emcee "blobs"). The evidence: importance sampling with a defensive mixture, cross-checked by
   Laplace and Savage–Dickey (:mod:`.evidence`).
4. **Combination**: ``P(planet | data)``, the Bayes factor, ``P(T | data, planet)``
   (:class:`.results.PosteriorResult`).

Why per-template runs rather than a template index inside emcee: the modes of different
templates sit at different ``(r_p, phi_p)`` and geometries, so jumps between templates at fixed
continuous parameters are almost always rejected, and stretch/DE moves are undefined on a
discrete coordinate. Per-template runs are independent, resumable one by one, and each has its
own convergence test.

Convergence: the default runs in chunks of ``check_every`` steps until every parameter's chain is
longer than 50 autocorrelation times and its ESS reaches ``min_ess`` — or, when the template's
Bayes factor shows the planet is not preferred, until the geometry's chain is (:mod:`.stopping`:
a flat, prior-dominated ``(r_p, phi_p)`` posterior would otherwise take hours to reach 50 tau) —
or ``max_steps`` (:mod:`~spiralbayes.inference.posterior.diagnostics`); ``n_steps`` fixes the total instead.

Chains and resume (:mod:`.chains`): ``<chains_dir>/<run_name>.h5``, one group per template plus
``__null__``, each rewritten atomically every ``flush_every`` steps with emcee's random state.
Every template (and the null) draws from its own random streams, seeded by ``(seed, name)``, so a
run killed at any point and started again continues exactly as the uninterrupted run: finished
templates are read back, the interrupted one continues from its last flushed batch, later ones
are as they would have been. A file written for other inputs (data, model, priors, templates,
settings) is refused with :class:`~spiralbayes.exceptions.ResumeMismatchError`.

Parallelism (:mod:`.chain_runner`): by default a template's walkers are evaluated by forked worker
processes, one per available core up to four, where the platform forks them (Linux; the tables are
shared page by page, nothing is pickled; :func:`.chain_runner.resolve_processes`), and by threads
elsewhere and when a ``threads`` count is given (the NUFFTs and the linear algebra release the
GIL); a continuous-mass family's node tables are built by the workers before its chain, and with
threads they are built when a walker first needs one; ``processes=k``
asks for ``k`` workers, which receive the log-posterior once (pool initializer; emcee #199) and pin
BLAS threads; ``pool="mpi"`` uses ``schwimmbad.MPIPool`` (run the same script on every rank; worker
ranks serve log-posterior calls and only the master writes files and returns a result); any object
with ``map`` may be passed as ``pool``. The same workers serve everything else of a template that
evaluates many independent points: the optimiser's start points and its two local optimisations,
and the evidence draws. Without a ``pool``, the table's ``r_p`` nodes and the no-planet evidence
draws go to as many local workers (:mod:`.forked`). Every value is the one a single process
computes.
"""

from __future__ import annotations

import logging
import time
import warnings
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..._provenance import check_output_name, data_hash, provenance_record
from ...settings import with_overrides
from ..._threads import blas_threads
from ..._version import __version__
from ...axisymmetric import DEFAULT_HYPERPARAMETERS, fit_axisymmetric
from ...axisymmetric.gp import ProfilePrior
from ...exceptions import InputError
from ...geometry import DiscGeometry
from ...templates.asymmetry import perturbation_profile
from ...templates.template import template_metadata
from ...units import wrap_angle
from .chain_runner import _set_mpi_rank, _writes_files, resolve_processes, run_chain, walker_pool
from .chain_runner import streams as chain_streams
from .chains import ChainBackend, ChainState, ChainStore, _saved_samples
from .diagnostics import _apply_policy, _convergence_message, arviz_diagnostics, chain_inference_data
from .evidence import StudentT, hessian_cov, importance_evidence, laplace_evidence, savage_dickey_log_bayes
from .likelihood import MarginalSpiralLikelihood, ProfileMarginal
from .optimise import _scales, find_map, fit_null_geometry
from .family_run import family_metadata, family_name, sample_family, scan_peak
from .mass import MassPrior, group_families
from .moves import DEFAULT_MOVES
from .perturbation import FastPerturbation
from .priors import N_DIM, Priors
from .results import NullRun, PosteriorResult, TemplateRun, _with_amplitude, wrap_phi
from .scan_evidence import family_grid_evidence, grid_run, template_grid_evidence
from .settings import SamplingSettings
from .odds import scan_alternatives
from ...templates.asymmetry import asymmetry_templates
from .stopping import StoppingRule, template_evidence

__all__ = ["LogPosterior", "NullLogPosterior", "lower_grid_runs", "refit_axisymmetric", "sample_posterior"]

log = logging.getLogger(__name__)

NULL_GROUP = "__null__"
_NAN_BLOB = np.array([np.nan, np.nan])


class LogPosterior:
    """``ln pi(theta) + ln L(theta)`` of one template, with the amplitude terms ``(c1, c2)`` as blob."""

    def __init__(self, likelihood: MarginalSpiralLikelihood, priors: Priors):
        self.likelihood = likelihood
        self.priors = priors

    def __call__(self, theta):
        lp = self.priors.log_prior(theta)
        lo, hi = self.likelihood.r_range  # narrower than the prior for Laplace-only templates
        if not np.isfinite(lp) or not lo <= theta[0] <= hi:
            return -np.inf, _NAN_BLOB
        terms = self.likelihood.amplitude_terms(theta)
        return lp + self.likelihood.marginal(terms), np.array(terms[1:])


class NullLogPosterior:
    """``ln pi(g) + ln L_0(g)`` of the disc alone, ``g = (inc, PA, dRA, dDec)``."""

    def __init__(self, base: ProfileMarginal, priors: Priors):
        self.base = base
        self.priors = priors

    def __call__(self, g) -> float:
        lp = self.priors.log_prior_geometry(g)
        return lp + self.base.log_likelihood(g) if np.isfinite(lp) else -np.inf


def _model_hash(axisymmetric, prior: ProfilePrior) -> str:
    g = axisymmetric.geometry
    return data_hash(axisymmetric.I, np.array([axisymmetric.Rmax, g.inc, g.PA, g.dRA, g.dDec]), prior.power)


def _template_hash(template) -> str:
    return data_hash(np.asarray(template.x, float), np.asarray(template.phi, float), np.asarray(template.delta, float))


# ---------------------------------------------------------------------------------------------
# the no-planet hypothesis
# ---------------------------------------------------------------------------------------------
def _run_null(vis, axisymmetric, priors, prior, store: ChainStore, inputs, seed, n_draws, likelihood_kwargs, *,
              processes: int = 1, threads: int | None = 1):
    """The no-planet posterior and evidence; returns (NullRun, the re-centred ProfileMarginal). The
    evidence draws are evaluated by ``processes`` local workers (or ``threads``, :func:`.make_pool`)."""
    t0 = time.perf_counter()
    reference = DiscGeometry(*priors.geometry_centre)
    base0 = ProfileMarginal(vis, axisymmetric, prior=prior, reference_geometry=reference,
                            **{k: likelihood_kwargs[k] for k in ("tolerance", "order") if k in likelihood_kwargs})
    saved = store.read()
    store.check_inputs(saved, inputs)
    if saved is not None and saved.result is not None:
        null = NullRun.from_record(saved.result, _saved_samples(saved, store))
        log.info("no planet: read back from %s (ln Z0 = %.2f)", store.path, null.ln_evidence)
        return null, base0.centred_at(DiscGeometry(*null.geometry_map))
    g_map, cov, lp_map = fit_null_geometry(base0.log_likelihood, priors)
    base = base0.centred_at(DiscGeometry(*g_map))
    logpost = NullLogPosterior(base, priors)
    _, _, rng, _ = chain_streams(seed, NULL_GROUP)
    proposal = StudentT(g_map, cov * 1.5 ** 2, priors.geometry_widths)
    with walker_pool(None, processes, logpost, threads) as pool:
        ev = importance_evidence(pool.log_prob, [proposal], [1.0], n_draws, rng, pool.map, with_draws=True)
    draws, lw = ev.pop("draws"), ev.pop("log_weights")  # resampled for the reported geometry samples
    w = np.exp(lw - np.nanmax(lw[np.isfinite(lw)])) if np.any(np.isfinite(lw)) else np.ones(len(draws))
    w = np.where(np.isfinite(w), w, 0.0)
    samples = draws[rng.choice(len(draws), size=len(draws), p=w / w.sum())]
    model = base.axisymmetric
    profile = {"r": model.r.tolist(), "I": model.I.tolist(),
               "I_err": None if model.I_err is None else model.I_err.tolist(), "prior": prior.source}
    null = NullRun(samples, g_map, cov, ev["ln_evidence"], ev["ln_evidence_err"], laplace_evidence(lp_map, cov),
                   profile, {"evidence": ev, "time_s": time.perf_counter() - t0})
    if _writes_files():
        store.write(ChainState(np.empty((0, 0, 4)), np.empty((0, 0)), None, np.zeros(0), None, inputs,
                               null.record(), samples))
    log.info("no planet: geometry mode inc %.4f PA %.4f dRA %.2f mas dDec %.2f mas; "
             "ln Z0 = %.2f +- %.2f (Laplace %.2f)",
             g_map[0], g_map[1], 1e3 * g_map[2], 1e3 * g_map[3], null.ln_evidence, null.ln_evidence_err,
             null.ln_evidence_laplace)
    return null, base


# ---------------------------------------------------------------------------------------------
# one template
# ---------------------------------------------------------------------------------------------
def _build_likelihood(base, template, r_range, null, priors, likelihood_kwargs, partners, progress, processes=1):
    lk = {k: v for k, v in likelihood_kwargs.items() if k not in ("tolerance", "order")}
    partner = partners.get(template.name)
    if callable(partner):  # the partner was read back from the chain file: rebuild its table to share it
        partner = partners[template.name] = partner()
    mirror_of = None
    if partner is not None and tuple(partner.r_range) == tuple(r_range):
        try:
            mirror_of = partner
            fp = FastPerturbation(base.u, base.v, base.weights, base.axisymmetric.brightness, template, r_range,
                                  DiscGeometry(*null.geometry_map), mirror_of=partner, **lk)
        except InputError:
            mirror_of = None
    if mirror_of is None:
        fp = FastPerturbation(base.u, base.v, base.weights, perturbation_profile(template, base.axisymmetric),
                              template, r_range, DiscGeometry(*null.geometry_map), progress=progress,
                              processes=processes, **lk)
    return MarginalSpiralLikelihood(base, fp, amplitude_max=priors.amplitude_max)


def _laplace(logpost, theta_map, priors, null):
    g_sigma, scales, max_var = _scales(priors, null)
    lo, hi = priors.r_p
    theta = theta_map.copy()
    theta[0] = np.clip(theta[0], lo + 1e-4 * (hi - lo), hi - 1e-4 * (hi - lo))
    room = np.full(N_DIM, np.inf)
    room[0] = 0.9 * min(theta[0] - lo, hi - theta[0])
    room[2] = 0.9 * min(theta[2], 90.0 - theta[2])
    f = lambda t: logpost(t)[0]  # noqa: E731
    cov = hessian_cov(f, theta, scales * 1e-2, room=room, max_var=max_var)
    lp = f(theta)
    return theta, cov, lp, laplace_evidence(lp, cov)


def _sample_one(vis, base, null, template, priors, *, scan, chain_path, mode, r_range, partners, settings):
    s, sampling = settings, settings["sampling"]
    t0 = time.perf_counter()
    name = template.name
    streams = chain_streams(sampling.seed, name)
    store = ChainStore(chain_path, name)
    inputs = {**s["inputs"], "template": template_metadata(template), "template_hash": _template_hash(template),
              "mode": mode, "r_range": list(r_range)}
    saved = store.read()
    store.check_inputs(saved, inputs)
    if saved is not None and saved.result is not None:
        log.info("%s: finished earlier, read back from %s", name, chain_path)
        return TemplateRun.from_record(saved.result, _saved_samples(saved, store)), None
    processes = resolve_processes(sampling.processes, sampling.threads)
    likelihood = _build_likelihood(base, template, r_range, null, priors, s["likelihood_kwargs"], partners,
                                   s["progress"], processes if sampling.pool is None else 1)
    logpost = LogPosterior(likelihood, priors)
    g_sigma, _, _ = _scales(priors, null)
    # one pool, forked once the tables exist, serves the optimiser, the chain and the evidence draws
    with walker_pool(sampling.pool, processes, logpost, sampling.threads) as walkers:
        if walkers.is_worker:  # an MPI worker rank
            return None, likelihood
        theta_map = find_map(logpost, priors, scan, name, null.geometry_map, g_sigma, pool_map=walkers.map,
                             pool_log_prob=walkers.log_prob)
        theta_map, cov, lp_map, lnz_laplace = _laplace(logpost, theta_map, priors, null)
        meta = template_metadata(template)
        info = {"likelihood": likelihood.describe(), "build_time_s": likelihood.perturbation.build_time_s}
        log.info("%s: optimum ln p = %.2f at %s; Laplace ln Z = %.2f", name, lp_map, np.round(theta_map, 5),
                 lnz_laplace)
        _, _, rng_evidence, rng_amp = streams
        if mode == "laplace":
            draws = rng_evidence.multivariate_normal(theta_map, cov, size=400)
            draws[:, 1] = wrap_angle(draws[:, 1], 0.0)
            draws = draws[[np.isfinite(logpost(d)[0]) for d in draws]]
            terms = np.array([likelihood.amplitude_terms(d) for d in draws]).reshape(-1, 3)
            samples = _with_amplitude(draws, terms[:, 1], terms[:, 2], priors, rng_amp)
            run = TemplateRun(name, meta, "laplace", samples, theta_map, cov, lnz_laplace, float("nan"), lnz_laplace,
                              {**info, "time_s": time.perf_counter() - t0}, str(chain_path), name)
            n_walkers = sampling.n_walkers
            store.write(ChainState(np.empty((0, n_walkers, N_DIM)), np.empty((0, n_walkers)), None,
                                   np.zeros(n_walkers), None, inputs, run.record(), samples))
            return run, likelihood
        rule = StoppingRule(null, priors, _scales(priors, null)[1], min_ess=sampling.min_ess,
                            n_draws=sampling.evidence_draws, seed=sampling.seed, name=name,
                            planet_free_rule=sampling.stop_when_planet_free)
        backend = run_chain(ChainBackend(store, inputs), saved, walkers, theta_map, cov, priors, settings=sampling,
                            streams=streams, name=name, progress=s["progress"], logpost=logpost, stop_check=rule)
        chain, blobs, accepted = backend.get_chain(), backend.get_blobs(), backend.accepted
        diag = rule(chain, walkers.log_prob, walkers.map)
        sl = slice(diag["burn_in"], None, diag["thin"])
        flat = chain[sl].reshape(-1, N_DIM)
        fb = blobs[sl].reshape(-1, 2)
        samples = _with_amplitude(flat, fb[:, 0], fb[:, 1], priors, rng_amp)
        ev = template_evidence(walkers.log_prob, flat, null, priors, _scales(priors, null)[1],
                               sampling.evidence_draws, rng_evidence, walkers.map)
    sd = (savage_dickey_log_bayes(fb[:, 0], fb[:, 1], priors.amplitude_max)
          if priors.amplitude_max is not None else float("nan"))
    diag = {**diag, **info, "evidence": ev, "acceptance": float(np.mean(accepted) / max(chain.shape[0], 1)),
            "ln_bayes_savage_dickey": sd + 0.0, "time_s": time.perf_counter() - t0}
    run = TemplateRun(name, meta, "mcmc", samples, theta_map, cov, ev["ln_evidence"], ev["ln_evidence_err"],
                      lnz_laplace, diag, str(chain_path), name)
    try:
        run.diagnostics["arviz"] = arviz_diagnostics(chain_inference_data(wrap_phi(chain[sl])[0]))
    except Exception as exc:  # pragma: no cover - diagnostics must not lose a run
        log.warning("arviz diagnostics failed: %s", exc)
    store.write(_final_state(store, run, samples))
    if not diag["converged"]:
        _apply_policy(sampling.convergence, _convergence_message(name, diag))
    return run, likelihood


def lower_grid_runs(runs: dict, on_grid, grids: dict, null) -> float | None:
    """Lower the grid evidence of one hypothesis' unsampled templates (``on_grid``) by the median amount the
    grid over-counts its sampled ones (``ln Z_chain − ln Z_grid`` < 0); never raise it. Returns that offset.

    The grid leaves the geometry and the profile at the scan's (:mod:`.scan_evidence`), which over-counts
    the arc and ring families' evidence by 6-8 (measured on a planted arc) while it under-counts strong
    planets': a raw grid value could then outweigh the sampled templates of its own hypothesis.
    """
    diffs = [r.ln_evidence - (null.ln_evidence + grids[n].ln_bayes) for n, r in runs.items()
             if n not in on_grid and r.mode == "mcmc" and grids.get(n) is not None]
    if not diffs:
        return None
    offset = float(np.median(diffs))
    if offset < 0:
        for name in on_grid:
            run = runs[name]
            run.ln_evidence += offset
            run.diagnostics.setdefault("evidence", {})["grid_offset"] = offset
        log.info("%d templates' grid evidence lowered by %.2f, the median over-count on the sampled ones", len(on_grid),
                 -offset)
    return offset


def _template_runs(vis, base, null, templates, priors, scan, chain_path, run_settings, selected, on_grid, partners,
                   overall) -> dict:
    """Each template's run (chain or Laplace; those ``on_grid`` are left to the caller), by name; a
    sampled template's table is left in ``partners`` for its mirror."""
    runs = {}
    for template in templates:
        if template.name in on_grid:
            continue
        mode = "mcmc" if template.name in selected else "laplace"
        steps = "tables, optimum, chain" if mode == "mcmc" else "tables, optimum, Laplace evidence"
        overall.start(f"template {template.name} ({steps})")
        r_range = priors.r_p if mode == "mcmc" else _laplace_window(priors, scan, template.name)
        run, likelihood = _sample_one(vis, base, null, template, priors, scan=scan, chain_path=chain_path,
                                      mode=mode, r_range=r_range, partners=partners, settings=run_settings)
        if mode == "mcmc":  # its mirror shares the table (rebuilt on demand if read back from the file)
            partners[_mirror_name(template)] = (likelihood.perturbation if likelihood is not None else
                                                _deferred_table(base, template, r_range, null,
                                                                run_settings["likelihood_kwargs"]))
        if run is not None:
            runs[template.name] = run
    return runs


def _final_state(store, run, samples):
    """The stored chain with the finished result added."""
    state = store.read()
    state.result, state.samples = run.record(), samples
    return state


# ---------------------------------------------------------------------------------------------
def sample_posterior(vis, axisymmetric, templates, *, scan_result=None, priors: Priors | None = None,
                     settings: SamplingSettings | None = None, chains_dir="chains", progress: bool = True,
                     mass_prior: MassPrior | None = None, **overrides) -> PosteriorResult | None:
    """Sample the posterior of every template, the no-planet hypothesis, and combine them.

    Parameters
    ----------
    vis : Visibilities
    axisymmetric : AxisymmetricModel
        The frank fit: its profile starts the profile marginalisation, its power spectrum is the
        profile's prior (:class:`~spiralbayes.axisymmetric.gp.ProfilePrior`), its geometry centres
        the default priors. A fit at a wrong geometry is fine: the profile is refitted at every
        sampled geometry inside the likelihood.
    templates : SpiralTemplate, TemplateBank or sequence
        With ``mass="continuous"`` also :class:`~spiralbayes.templates.family.TemplateFamily` objects
        (used as they are; bank templates are grouped into families of 49 mass nodes).
    scan_result : ScanResult, optional
        Starts each template's optimiser from its best grid instances, and prunes templates
        (``prune_delta_lnL``). The keyword ``scan=`` is accepted with a FutureWarning.
    priors : Priors, optional
        Default :meth:`.Priors.default` (``axisymmetric``), including the amplitude prior.
    settings : SamplingSettings, optional
        How to sample (walkers, steps, convergence, seed, pruning, pool, ...); default
        ``SamplingSettings()``. Chains go to ``<chains_dir>/<settings.run_name>.h5``; an existing
        file with the same inputs is resumed (see the module docs). ``settings.n_steps = None``
        runs in chunks of ``check_every`` until converged (> 50 tau and ESS >= ``min_ess`` for
        every parameter) or ``max_steps``.
    chains_dir : str or path
        Folder of the chain files.
    progress : bool
        Progress bars for the table builds and the steps (default True).
    mass_prior : MassPrior, optional
        With ``mass="continuous"``: the planet mass's log-uniform range [M_th] and the stellar mass's
        prior [M_sun] (default :class:`~.mass.MassPrior`: 0.1-3 M_th, 0.8 +- 0.08 M_sun).
    **overrides
        Fields of :class:`SamplingSettings` replacing those of ``settings`` (e.g. ``n_walkers=48``).
        ``mass="continuous"`` samples the planet mass within each family of the templates (variant,
        τ0, β, hand, H/r) instead of treating each bank mass as its own hypothesis
        (:mod:`~spiralbayes.inference.posterior.mass`): every family is one run whose samples add
        ``M_p`` [M_th] and ``M_p_MJup`` [M_Jup].

    Returns
    -------
    PosteriorResult or None
        ``p_planet``, ``ln_bayes_factor``, ``verdict``, per-template runs and the ``null`` run; None on an
        MPI worker rank (``pool="mpi"``), which only serves the master.

    Examples
    --------
    A short run (minutes on 2 cores; leave ``n_steps`` unset to sample until the chains converge):

    >>> import spiralbayes as sb
    >>> vis = sb.load_visibilities("disc.txt")  # doctest: +SKIP
    >>> disc = sb.fit_axisymmetric(vis, sb.DiscGeometry(inc=30, PA=60), progress=False)  # doctest: +SKIP
    >>> templates = sb.default_bank().select(mass=3.0, tau0=3.0, beta=10.0, h_p=0.07)  # doctest: +SKIP
    >>> result = sb.scan(vis, disc, templates, progress=False)  # doctest: +SKIP
    >>> post = sb.sample_posterior(vis, disc, templates, scan_result=result, progress=False,
    ...                            settings=sb.SamplingSettings(n_walkers=16, n_steps=150))  # doctest: +SKIP
    >>> print(post.verdict)  # doctest: +SKIP
    """
    if "scan" in overrides:
        if scan_result is not None:
            raise TypeError("sample_posterior() got both scan_result and scan: pass the ScanResult once, as "
                            "scan_result")
        warnings.warn("sample_posterior(scan=...) is renamed sample_posterior(scan_result=...)", FutureWarning,
                      stacklevel=2)
        scan_result = overrides.pop("scan")
    s = with_overrides(settings, SamplingSettings, overrides, "sample_posterior")
    run_name, n_walkers, seed, evidence_draws = s.run_name, s.n_walkers, s.seed, s.evidence_draws
    pool, moves, likelihood_kwargs = s.pool, s.moves, s.likelihood_kwargs
    template_prior, planet_prior = s.template_prior, s.planet_prior
    templates = _check_templates(templates, s.mass)
    vis = vis.standardised()
    priors = priors or Priors.default(axisymmetric)
    priors.check_data(vis, axisymmetric)
    names = [getattr(t, "name", None) or family_name(t) for t in templates]
    prior_t = (np.full(len(templates), 1.0 / len(templates)) if template_prior is None
               else np.asarray(template_prior, float))
    if prior_t.shape != (len(templates),) or np.any(prior_t <= 0):
        raise InputError("template_prior must hold one positive probability per template")
    prior_t = prior_t / prior_t.sum()
    chain_path = Path(chains_dir) / f"{check_output_name(run_name, 'run_name')}.h5"
    chain_path.parent.mkdir(parents=True, exist_ok=True)
    families: list = []
    mass_prior = mass_prior or MassPrior()
    if s.mass == "continuous":
        if template_prior is not None:
            raise InputError("template_prior is per template; with mass='continuous' the families share the prior "
                             "equally: leave template_prior unset")
        families = group_families(templates, mass_prior)
        prior_t = np.full(len(families), 1.0 / len(families))
        log.info("mass = 'continuous': %d templates in %d families, M_p log-uniform on %s M_th", len(templates),
                 len(families), mass_prior.mass_range)
    hypotheses = [family_name(f) for f, _ in families] if families else names
    grids = _grid_evidences(scan_result, templates, families, priors, mass_prior)
    selected = _select_mcmc(hypotheses, families, grids, s)
    on_grid = set() if s.pruned_evidence != "scan" else {n for n in hypotheses
                                                         if n not in selected and grids.get(n) is not None}
    likelihood_kwargs = dict(likelihood_kwargs or {})
    profile_prior = ProfilePrior.from_model(axisymmetric)
    common = {"data_hash": data_hash(vis.u, vis.v, vis.V, vis.weights), "n_data": int(vis.n), "mass": s.mass,
              "model_hash": _model_hash(axisymmetric, profile_prior), "priors": priors.to_dict(), "seed": int(seed),
              "likelihood_kwargs": likelihood_kwargs, "spiralbayes": __version__}
    run_settings = {"inputs": {**common, "n_walkers": int(n_walkers), "evidence_draws": int(evidence_draws),
                               "moves": DEFAULT_MOVES if moves is None else repr(moves)},
                    "sampling": s, "progress": progress, "likelihood_kwargs": likelihood_kwargs}
    _set_mpi_rank(pool)
    n_alternatives = sum(min(s.max_chains, len(asymmetry_templates(k))) for k in s.alternatives or ())
    overall = _Stages(len(hypotheses) - len(on_grid) + 1 + bool(on_grid) + n_alternatives, progress)
    with blas_threads(1, all_pools=True):
        overall.start("no planet: geometry mode and evidence")
        null, base = _run_null(vis, axisymmetric, priors, profile_prior, ChainStore(chain_path, NULL_GROUP),
                               {**common, "evidence_draws": int(evidence_draws)}, seed, evidence_draws,
                               likelihood_kwargs, **({"processes": resolve_processes(s.processes, s.threads),
                                                      "threads": s.threads} if pool is None else {}))
        runs: dict[str, TemplateRun] = {}
        partners: dict[str, FastPerturbation | Callable[[], FastPerturbation]] = {}  # mirror name -> its table
        family_partners: dict = {}
        if on_grid:
            overall.start(f"{len(on_grid)} of {len(hypotheses)} hypotheses without a chain: evidence from the scan")
        plan = []
        for family, members in families:
            fname = family_name(family)
            if fname in on_grid:
                continue
            best = max(members, key=lambda t: scan_peak(scan_result, t.name)).name if members else fname
            mode = "mcmc" if fname in selected else "laplace"
            r_range = priors.r_p if mode == "mcmc" else _laplace_window(priors, scan_result, best)
            key = (family.variant, family.tau0, family.beta, tuple(family.h_ps), tuple(family.masses),
                   tuple(r_range))
            plan.append((family, members, fname, mode, r_range, key))
        for i, (family, members, fname, mode, r_range, key) in enumerate(plan):
            overall.start(f"family {fname}: M_p continuous ({mode})")
            run, likelihood = sample_family(vis, base, null, family, members, priors, mass_prior,
                                            scan=scan_result, chain_path=chain_path, settings=run_settings, mode=mode,
                                            r_range=r_range, mirror_of=family_partners.pop(key, None))
            # node tables (~86 MB each on the fiducial observation) are kept only for a mirror family still to run
            if likelihood is not None and _mirror_later(plan[i + 1:], key, family.hand):
                family_partners[key] = likelihood.perturbation
            if run is not None:
                runs[fname] = run
        if not families:
            runs.update(_template_runs(vis, base, null, templates, priors, scan_result, chain_path, run_settings,
                                       selected, on_grid, partners, overall))
        if on_grid:
            metadata = {family_name(f): (family_metadata(f, mass_prior), float(f.h_ps[0])) for f, _ in families}
            for name in on_grid:
                meta, h_p = metadata.get(name) or (template_metadata(templates[names.index(name)]), None)
                runs[name] = grid_run(name, meta, grids[name], null, priors, chain_streams(seed, name)[3],
                                      mass_prior=mass_prior, h_p=h_p)
            lower_grid_runs(runs, on_grid, grids, null)
        alternative_runs = []
        if s.alternatives:
            alt_templates, alt_scan = scan_alternatives(vis, axisymmetric, s.alternatives, scan_result,
                                                        float(getattr(vis, "wavelength", None) or 0.87e-3))
            for temps in alt_templates.values():
                alt_names = [t.name for t in temps]
                alt_grids = _grid_evidences(alt_scan, temps, [], priors, mass_prior)
                alt_selected = _select_mcmc(alt_names, [], alt_grids, replace(s, mcmc_templates=None))
                alt_on_grid = set() if alt_scan is None else set(alt_names) - alt_selected
                done = _template_runs(vis, base, null, temps, priors, alt_scan, chain_path, run_settings,
                                      alt_selected, alt_on_grid, {}, overall)
                for name in alt_on_grid:
                    t = temps[alt_names.index(name)]
                    done[name] = grid_run(name, template_metadata(t), alt_grids[name], null, priors,
                                          chain_streams(seed, name)[3])
                lower_grid_runs(done, alt_on_grid, alt_grids, null)
                alternative_runs += [done[n] for n in alt_names if n in done]
    overall.close()
    if pool == "mpi" and not runs:
        return None
    result = PosteriorResult([runs[n] for n in hypotheses if n in runs], priors, prior_t, run_name, str(chain_path),
                             provenance_record(data_hash=common["data_hash"], geometry=axisymmetric.geometry.to_dict(),
                                               profile_prior=profile_prior.source),
                             null, float(planet_prior), alternative_runs)
    ChainStore(chain_path, NULL_GROUP).write_root(summary=result.to_dict())
    log.info("%s", result.verdict)
    return result


class _Stages:
    """The run's overall progress: one log line per stage ("posterior 3/9: ...", with the time so far) and a
    bar over the stages; table builds, optimisation and chains have their own bars within a stage."""

    def __init__(self, total: int, progress: bool):
        from tqdm.auto import tqdm

        self.total, self.k, self.t0 = total, 0, time.perf_counter()
        self.bar = tqdm(total=total, desc="posterior", unit="stage", disable=not progress, mininterval=1.0)

    def start(self, what: str) -> None:
        if self.k:
            self.bar.update(1)
        self.k += 1
        log.info("posterior %d/%d: %s (%.1f min so far)", self.k, self.total, what,
                 (time.perf_counter() - self.t0) / 60)

    def close(self) -> None:
        self.bar.update(self.total - self.bar.n)
        self.bar.close()
        log.info("posterior: %d stages done in %.1f min", self.total, (time.perf_counter() - self.t0) / 60)


def _check_templates(templates, mass: str = "bank") -> list:
    from ...templates.family import TemplateFamily

    if hasattr(templates, "evaluate") or isinstance(templates, TemplateFamily):
        templates = [templates]
    templates = list(templates)
    if not templates:
        raise InputError("no templates: pass a SpiralTemplate, a TemplateBank or a list of them")
    if mass != "continuous" and any(isinstance(t, TemplateFamily) for t in templates):
        raise InputError("a TemplateFamily is sampled with its mass free: pass mass='continuous'")
    names = [family_name(t) if isinstance(t, TemplateFamily) else t.name for t in templates]
    if len(set(names)) != len(names) or NULL_GROUP in names:
        raise InputError(f"template names must be unique (and not {NULL_GROUP!r}), got {names}")
    return templates


def _deferred_table(base, template, r_range, null, likelihood_kwargs):
    """A function that builds ``template``'s table exactly as :func:`_sample_one` would."""
    lk = {k: v for k, v in likelihood_kwargs.items() if k not in ("tolerance", "order")}
    return lambda: FastPerturbation(base.u, base.v, base.weights, perturbation_profile(template, base.axisymmetric),
                                    template, r_range, DiscGeometry(*null.geometry_map), **lk)


def _mirror_name(template) -> str:
    name = template.name
    hand = getattr(template, "hand", "")
    other = {"R": "L", "L": "R"}.get(hand, "")
    return name[:-1] + other if other and name.endswith("_" + hand) else f"{name}_mirror"


def _laplace_window(priors: Priors, scan, name: str) -> tuple:
    """A narrow r_p window around the template's best scan radius (its Laplace evidence needs no more)."""
    if scan is None:
        return priors.r_p
    try:
        k = scan.template_index(name)
    except (KeyError, IndexError):
        return priors.r_p
    dchi2 = np.nan_to_num(scan.delta_chi2()[k], nan=-np.inf)
    lo, hi = priors.r_p
    inside = (scan.r_p >= lo) & (scan.r_p <= hi)
    if not inside.any():
        return priors.r_p
    i = int(np.argmax(np.where(inside, np.max(dchi2, axis=1), -np.inf)))
    step = float(np.median(np.diff(scan.r_p))) if scan.r_p.size > 1 else 0.1 * (hi - lo)
    r_lo, r_hi = max(lo, scan.r_p[i] - 2 * step), min(hi, scan.r_p[i] + 2 * step)
    return (r_lo, r_hi) if r_hi > r_lo else priors.r_p


def _mirror_later(later: list, key, hand: str) -> bool:
    """Does a family still to run (``later``: the plan's entries) share ``key`` with the other hand?"""
    return any(k == key and f.hand != hand for f, *_, k in later)


def _grid_evidences(scan, templates, families, priors: Priors, mass_prior: MassPrior) -> dict:
    """``{hypothesis name: GridEvidence or None}`` from the scan (None where it lacks the template or a member)."""
    out: dict = {}
    if scan is None:
        return out
    scanned = {t["name"] for t in scan.templates}
    if families:
        for family, members in families:
            ok = members and all(t.name in scanned for t in members)
            out[family_name(family)] = (family_grid_evidence(scan, members, mass_prior.mass_range, priors) if ok
                                        else None)
        return out
    for t in templates:
        out[t.name] = template_grid_evidence(scan, t.name, priors) if t.name in scanned else None
    return out


def _select_mcmc(names, families, grids: dict, s: SamplingSettings) -> set:
    """The hypotheses that get a chain: named by ``mcmc_templates`` (a family by its name or a member's),
    else the ``max_chains`` best by scan-grid evidence within ``prune_delta_lnL`` of the best (all without
    a scan; those the scan lacks always), with a warning when the cap leaves some of the window out."""
    if s.mcmc_templates is not None:
        members = {family_name(f): {t.name for t in m} for f, m in families}
        known = set(names).union(*members.values())
        unknown = set(s.mcmc_templates) - known
        if unknown:
            raise InputError(f"mcmc_templates names unknown templates {sorted(unknown)}")
        asked = set(s.mcmc_templates)
        return {n for n in names if n in asked or members.get(n, set()) & asked}
    if not grids:
        return set(names)
    ln_b = {n: grids[n].ln_bayes for n in names if grids.get(n) is not None}
    best = max(ln_b.values(), default=-np.inf)
    ranked = sorted((n for n in ln_b if best - ln_b[n] <= s.prune_delta_lnL), key=lambda n: -ln_b[n])
    capped = ranked[s.max_chains:]
    if capped and s.pruned_evidence == "scan":
        log.warning("%d templates within prune_delta_lnL = %g of the best scan-grid evidence get no chain "
                    "(max_chains = %d), e.g. %s: the grid under-counts strong templates (by 6-8 in ln B on the demo "
                    "observation), so the template probabilities favour the sampled ones; raise max_chains to "
                    "sample them", len(capped), s.prune_delta_lnL, s.max_chains, ", ".join(capped[:3]))
    return set(ranked[:s.max_chains]) | {n for n in names if grids.get(n) is None}


def refit_axisymmetric(vis, axisymmetric, result, template=None, *, progress: bool = False):
    """Refit the frank profile (with frank's own iterations) at the posterior-median geometry.

    Not needed for the posterior — the likelihood integrates the profile out at every sampled
    geometry — but useful to inspect a frank fit, with its own power spectrum, at the geometry
    the data prefer.

    Parameters
    ----------
    vis : Visibilities
    axisymmetric : AxisymmetricModel
        Its frank hyperparameters are reused.
    result : PosteriorResult or TemplateRun
    template : str or int, optional
        Which template's posterior gives the geometry (default: the most probable).
    """
    run = result.run(template) if hasattr(result, "run") else result
    median = {name: stats["median"] for name, stats in run.percentiles().items()}
    geometry = DiscGeometry(median["inc"], median["PA"], median["dRA"], median["dDec"])
    hyper = {k: axisymmetric.hyperparameters.get(k, v) for k, v in DEFAULT_HYPERPARAMETERS.items()}
    log.info("refitting the frank profile at the posterior geometry %s", geometry)
    return fit_axisymmetric(vis, geometry, progress=progress, **hyper)
