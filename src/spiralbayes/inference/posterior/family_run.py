"""One template family's posterior with the planet mass sampled (``sample_posterior(..., mass="continuous")``).

:func:`sample_family` is the family's counterpart of a template's run in :mod:`.sampler`: the mode
(the template's six parameters at the scan's best bank mass, then ``ln M_p`` freed), its Laplace
covariance and evidence, then — unless the family is pruned to a Laplace evidence — an emcee chain
over ``(r_p, phi_p, inc, PA, dRA, dDec, ln M_p)`` with the wrapped DE moves (blocks: the planet with
its mass, and the geometry), stopped by the fixed templates' :class:`~.stopping.StoppingRule` with
``ln M_p`` among the parameters (every parameter past 50 tau, or the planet not preferred and the
geometry converged). The evidence
is importance-sampled from a t fitted to the chain and a defensive component that draws the planet's
position and mass from their priors. The likelihood and the priors are in :mod:`~spiralbayes.inference.posterior.mass`.
"""

from __future__ import annotations

import contextlib
import logging
import time
from dataclasses import replace

import numpy as np

from ..._provenance import data_hash
from ...geometry import DiscGeometry
from .chain_runner import resolve_processes, run_chain, walker_pool
from .chain_runner import streams as chain_streams
from .chains import ChainBackend, ChainState, ChainStore, _saved_samples
from .diagnostics import _apply_policy, _convergence_message, arviz_diagnostics, chain_inference_data
from .evidence import GaussianGeometry, StudentT, hessian_cov, importance_evidence, laplace_evidence
from .mass import MASS_PARAMETER_NAMES, FamilyPerturbation, MassLikelihood, MassLogPosterior, MassPrior
from .moves import default_moves
from .optimise import _nelder_mead, _scales, find_map
from .priors import Priors
from .results import TemplateRun, _with_amplitude, wrap_phi
from .stopping import StoppingRule

__all__ = ["family_evidence", "family_metadata", "family_name", "sample_family"]

log = logging.getLogger(__name__)


class _MassPlateau:
    """The evidence's defensive component: the no-planet geometry as a t, ``(r_p, phi_p)`` and ``ln M_p``
    from their priors."""

    def __init__(self, geometry_component, mass_prior: MassPrior):
        self.geometry = geometry_component
        self.lo, self.hi = mass_prior.ln_range

    def draw(self, n: int, rng) -> np.ndarray:
        return np.column_stack([self.geometry.draw(n, rng), rng.uniform(self.lo, self.hi, n)])

    def logpdf(self, x: np.ndarray) -> np.ndarray:
        inside = (x[:, 6] >= self.lo) & (x[:, 6] <= self.hi)
        return np.where(inside, self.geometry.logpdf(x[:, :6]) - np.log(self.hi - self.lo), -np.inf)


def family_evidence(log_prob_fn, flat: np.ndarray, null, priors, mass_prior: MassPrior, scales, n_draws: int, rng,
                    mapper=map) -> dict:
    """A family's ``ln Z`` by importance sampling: a t fitted to chain samples ``flat`` (n, 7) plus the
    no-planet geometry with the planet's position and ``ln M_p`` from their priors (mixture 0.7 / 0.3,
    as :func:`~.stopping.template_evidence` for a template)."""
    centred, _ = wrap_phi(flat)
    chain_t = StudentT(centred.mean(axis=0), np.cov(centred, rowvar=False) * 1.2 ** 2, scales, periodic=(1,))
    plateau = _MassPlateau(GaussianGeometry(null.geometry_map, null.covariance * 1.5 ** 2, priors.geometry_widths,
                                            priors.r_p), mass_prior)
    return importance_evidence(log_prob_fn, [chain_t, plateau], [0.7, 0.3], n_draws, rng, mapper)


def family_name(family) -> str:
    """A family run's name: the bank's template name with the mass replaced by ``mcont``."""
    from ...templates.template import template_name

    prefix = "wake" if family.variant == "compromise" else family.variant
    name = template_name(1.0, family.tau0, family.beta, family.hand, prefix=prefix, h_p=float(family.h_ps[0]))
    return name.replace("_m1_", "_mcont_")


def family_metadata(family, mass_prior: MassPrior) -> dict:
    physics = getattr(family.nodes, "physics", None) or {}  # a learned family's disc (slope, alpha, orbits)
    return {"name": family_name(family), "mass": None, "tau0": family.tau0, "beta": family.beta, "hand": family.hand,
            "h_p": float(family.h_ps[0]), "variant": family.variant, "mass_mode": "continuous",
            **mass_prior.to_dict(), "n_mass_nodes": int(family.masses.size), **physics}


def scan_peak(scan, name: str) -> float:
    """The template's best scan Delta chi2 (-inf without a scan or the template)."""
    if scan is not None:
        with contextlib.suppress(KeyError, IndexError):
            return float(np.nanmax(scan.delta_chi2()[scan.template_index(name)]))
    return -np.inf


def _start_mass(members, scan, mass_prior: MassPrior) -> float:
    """The bank member the scan rates best (else the range's geometric mean) [M_th]."""
    lo, hi = mass_prior.mass_range
    inside = [t for t in members if lo <= float(t.mass) <= hi]
    if scan is None or not inside:
        return float(np.sqrt(lo * hi))
    return float(max(inside, key=lambda t: scan_peak(scan, t.name)).mass)


class _AtMass:
    """The family's log posterior over the template's six parameters at a fixed ``ln M_p`` (picklable:
    a pool's workers evaluate it through their own copy of ``log_prob``)."""

    def __init__(self, log_prob, ln_mass: float):
        self.log_prob, self.ln_mass = log_prob, float(ln_mass)

    def __call__(self, theta):
        return self.log_prob(np.append(theta, self.ln_mass))


def _in_window(logpost, r_range):
    """``ln p`` of 7 parameters, ``-inf`` outside the family's ``r_p`` window."""
    return lambda t: float(logpost(t)[0]) if r_range[0] <= t[0] <= r_range[1] else -np.inf


def _family_scales(priors: Priors, null, mass_prior: MassPrior) -> tuple:
    """:func:`.optimise._scales` with ``ln M_p`` (uniform over its prior) appended."""
    g_sigma, scales6, max_var6 = _scales(priors, null)
    lo, hi = mass_prior.ln_range
    return g_sigma, np.append(scales6, (hi - lo) / np.sqrt(12.0)), np.append(max_var6, (hi - lo) ** 2 / 12.0)


def _family_mode(logpost, members, scan, priors: Priors, null, mass_prior: MassPrior, r_range, name: str,
                 walkers=None) -> tuple:
    """The family's mode, Laplace covariance, ``ln p`` there and Laplace ``ln Z``: the template's six at the
    scan's best bank mass (start points and local optimisations in ``walkers``' pool where given), then
    ``ln M_p`` freed."""
    g_sigma, scales, max_var = _family_scales(priors, null, mass_prior)
    lo, hi = mass_prior.ln_range
    m0 = _start_mass(members, scan, mass_prior)
    start_name = next((t.name for t in members if float(t.mass) == m0), name)
    f7 = _in_window(logpost, r_range)
    pool = {} if walkers is None else {"pool_map": walkers.map, "pool_log_prob": _AtMass(walkers.log_prob,
                                                                                          np.log(m0))}
    six = find_map(lambda t: f7(np.append(t, np.log(m0))), priors, scan, start_name, null.geometry_map, g_sigma,
                   **pool)
    masses = [m for m in sorted({m0, *(float(t.mass) for t in members)}) if np.exp(lo) <= m <= np.exp(hi)]
    starts = [np.append(six, np.log(m)) for m in masses]
    x0 = max(starts, key=f7)
    steps = np.concatenate([[0.01 * (priors.r_p[1] - priors.r_p[0]), 0.02], 3.0 * g_sigma, [0.2]])
    theta_map = _nelder_mead(f7, x0, steps, 700, restarts=2)
    theta_map[6] = np.clip(theta_map[6], lo + 1e-6 * (hi - lo), hi - 1e-6 * (hi - lo))
    room = np.full(7, np.inf)
    room[0] = 0.9 * min(theta_map[0] - r_range[0], r_range[1] - theta_map[0])
    room[2] = 0.9 * min(theta_map[2], 90.0 - theta_map[2])
    room[6] = 0.9 * min(theta_map[6] - lo, hi - theta_map[6])
    cov = hessian_cov(f7, theta_map, scales * 1e-2, room=room, max_var=max_var)
    lp_map = f7(theta_map)
    lnz_laplace = laplace_evidence(lp_map, cov)
    log.info("%s: optimum ln p = %.2f at M_p = %.3g M_th, %s; Laplace ln Z = %.2f", name, lp_map,
             np.exp(theta_map[6]), np.round(theta_map[:6], 5), lnz_laplace)
    return theta_map, cov, lp_map, lnz_laplace


def sample_family(vis, base, null, family, members, priors: Priors, mass_prior: MassPrior, *, scan, chain_path,
                  settings, mode: str = "mcmc", r_range=None, mirror_of: FamilyPerturbation | None = None) -> tuple:
    """One family's posterior over ``(r_p, phi_p, geometry, ln M_p)``; returns ``(TemplateRun, likelihood)``.

    ``members`` are the bank templates of the family (they start the optimiser at the scan's best
    instances). ``settings`` is :func:`~.sampler.sample_posterior`'s run settings. ``mode``
    ``"laplace"`` gives the Laplace evidence and Gaussian samples only, from tables over ``r_range``
    (a window around the scan's peak), as for a pruned template. ``mirror_of``: the mirror family's
    perturbation on the same ``r_range``, whose node tables this family shares.
    """
    s, sampling = settings, settings["sampling"]
    t0 = time.perf_counter()
    name = family_name(family)
    meta = family_metadata(family, mass_prior)
    streams = chain_streams(sampling.seed, name)
    store = ChainStore(chain_path, name)
    node0 = family.node(0)
    r_range = tuple(priors.r_p if r_range is None else r_range)
    inputs = {**s["inputs"], "template": meta, "mode": mode, "r_range": list(r_range),
              "family_nodes": family.masses.tolist(),
              "template_hash": data_hash(np.asarray(node0.x, float), np.asarray(node0.phi, float),
                                         np.asarray(node0.delta, float))}
    saved = store.read()
    store.check_inputs(saved, inputs)
    if saved is not None and saved.result is not None:
        log.info("%s: finished earlier, read back from %s", name, chain_path)
        return TemplateRun.from_record(saved.result, _saved_samples(saved, store)), None
    lk = {k: v for k, v in s["likelihood_kwargs"].items() if k not in ("tolerance", "order")}
    fp = FamilyPerturbation(base.u, base.v, base.weights, base.axisymmetric.brightness, family, r_range,
                            DiscGeometry(*null.geometry_map), progress=s["progress"], mirror_of=mirror_of, **lk)
    processes = resolve_processes(sampling.processes, sampling.threads)
    if mode == "mcmc" and (sampling.pool is not None or processes > 1):
        # every node the chain and the evidence's prior draws can reach, built before the workers fork
        fp.build_nodes(mass_prior.mass_range, processes=processes if sampling.pool is None else 1)
    likelihood = MassLikelihood(base, fp, amplitude_max=priors.amplitude_max)
    logpost = MassLogPosterior(likelihood, priors, mass_prior)
    scales = _family_scales(priors, null, mass_prior)[1]
    _, _, rng_evidence, rng_amp = streams
    if mode == "laplace":
        theta_map, cov, lp_map, lnz_laplace = _family_mode(logpost, members, scan, priors, null, mass_prior, r_range,
                                                           name)
        draws = rng_evidence.multivariate_normal(theta_map, cov, size=400)
        draws[:, 1] = np.mod(draws[:, 1], 2 * np.pi)
        in_window = _in_window(logpost, r_range)
        draws = draws[[np.isfinite(in_window(d)) for d in draws]]
        terms = np.array([likelihood.amplitude_terms(d) for d in draws]).reshape(-1, 3)
        samples = _with_amplitude(draws[:, :6], terms[:, 1], terms[:, 2], priors, rng_amp)
        samples = np.column_stack([samples, *mass_prior.planet_masses(np.exp(draws[:, 6]), float(family.h_ps[0]),
                                                                      rng_amp)])
        info = {"likelihood": likelihood.describe(), "build_time_s": fp.build_time_s,
                "time_s": time.perf_counter() - t0}
        run = TemplateRun(name, meta, "laplace", samples, theta_map, cov, lnz_laplace, float("nan"), lnz_laplace,
                          info, str(chain_path), name)
        store.write(ChainState(np.empty((0, sampling.n_walkers, 7)), np.empty((0, sampling.n_walkers)), None,
                               np.zeros(sampling.n_walkers), None, inputs, run.record(), samples))
        return run, likelihood
    chain_settings = replace(sampling, moves=sampling.moves if sampling.moves is not None
                             else default_moves(blocks=((0, 1, 6), (2, 3, 4, 5))), initial=None)

    def evidence(log_prob_fn, flat, rng, mapper=map) -> dict:
        return family_evidence(log_prob_fn, flat, null, priors, mass_prior, scales, sampling.evidence_draws, rng,
                               mapper)

    stop = StoppingRule(null, priors, scales, min_ess=sampling.min_ess, n_draws=sampling.evidence_draws,
                        seed=sampling.seed, name=name, planet_free_rule=sampling.stop_when_planet_free,
                        names=MASS_PARAMETER_NAMES, evidence=evidence)
    with walker_pool(sampling.pool, processes, logpost, sampling.threads) as walkers:
        if walkers.is_worker:
            return None, likelihood
        # the optimiser's start points and local optimisations in the walkers' pool, as for a template
        theta_map, cov, lp_map, lnz_laplace = _family_mode(logpost, members, scan, priors, null, mass_prior, r_range,
                                                           name, walkers)
        backend = run_chain(ChainBackend(store, inputs), saved, walkers, theta_map, cov, priors,
                            settings=chain_settings, streams=streams, name=name, progress=s["progress"],
                            logpost=logpost, stop_check=stop)
        chain, blobs, accepted = backend.get_chain(), backend.get_blobs(), backend.accepted
        diag = stop(chain, walkers.log_prob, walkers.map)
        sl = slice(diag["burn_in"], None, diag["thin"])
        flat = chain[sl].reshape(-1, 7)
        fb = blobs[sl].reshape(-1, 2)
        ev = evidence(walkers.log_prob, flat, rng_evidence, walkers.map)
    samples = _with_amplitude(flat[:, :6], fb[:, 0], fb[:, 1], priors, rng_amp)
    samples = np.column_stack([samples, *mass_prior.planet_masses(np.exp(flat[:, 6]), float(family.h_ps[0]),
                                                                  rng_amp)])
    diag = {**diag, "likelihood": likelihood.describe(), "build_time_s": fp.build_time_s, "evidence": ev,
            "acceptance": float(np.mean(accepted) / max(chain.shape[0], 1)), "time_s": time.perf_counter() - t0}
    run = TemplateRun(name, meta, "mcmc", samples, theta_map, cov, ev["ln_evidence"], ev["ln_evidence_err"],
                      lnz_laplace, diag, str(chain_path), name)
    try:
        run.diagnostics["arviz"] = arviz_diagnostics(chain_inference_data(wrap_phi(chain[sl])[0],
                                                                          names=MASS_PARAMETER_NAMES))
    except Exception as exc:  # pragma: no cover - diagnostics must not lose a run
        log.warning("arviz diagnostics failed: %s", exc)
    state = store.read()
    assert state is not None  # the chain was flushed to this group above
    state.result, state.samples = run.record(), samples
    store.write(state)
    if not diag["converged"]:
        _apply_policy(sampling.convergence, _convergence_message(name, diag))
    return run, likelihood
