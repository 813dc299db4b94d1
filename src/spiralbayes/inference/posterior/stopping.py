"""When a template's chain may stop: every parameter converged, or the reported quantities converged.

The default run tests a template's chain after every flush (``flush_every`` steps) from
``2 check_every`` steps on, rule 2 only every ``check_every`` steps. It stops when either rule
holds (:class:`StoppingRule`):

1. **Every parameter** (the planet's position and the geometry) is longer than
   ``TAU_FACTOR`` = 50 autocorrelation times with ESS >= ``min_ess``
   (:func:`.diagnostics.convergence_diagnostics`) — what a planet needs, since its position is
   reported.
2. **The planet is not preferred and everything reported has converged.** The geometry
   ``(inc, PA, dRA, dDec)`` alone passes the 50-tau / ESS test, and the template's Bayes factor
   against no planet, estimated at the check by the same importance sampler as the final evidence
   (a t fitted to the chain plus the defensive prior-plateau component, :mod:`.evidence`), lies
   below the "planet preferred" threshold with margin: ``ln B_T + 2 sigma < 1``
   (:data:`.results.INCONCLUSIVE_LN_B`), with ``sigma <=`` :data:`MAX_LN_B_ERROR`.

Why rule 2: on planet-free data the posterior of ``(r_p, phi_p)`` is its (flat) prior. A random
walk over the whole prior has a long autocorrelation time (tau(r_p) ~ 250 steps measured, so 50 tau
is ~13,000 steps: 87 min against 28 min for the same data with a planet), yet nothing reported
depends on it: the verdict gives no planet position unless a planet is preferred, the geometry
(the nuisances) has converged, and the evidence does not come from the chain's histogram — the
importance sampler's plateau component draws ``(r_p, phi_p)`` from their prior, and its error
follows from the spread of the weights. A planet that is preferred (``ln B_T + 2 sigma >= 1``)
always needs rule 1.

A check is a deterministic function of the chain and the seed (its evidence draws come from their
own stream, seeded by ``(seed, template, step)``), so a killed and resumed run stops at the same
step as the uninterrupted one.
"""

from __future__ import annotations

import logging
import zlib

import numpy as np

from .conditional import PARAMETER_NAMES
from .diagnostics import TAU_FACTOR, convergence_diagnostics
from .evidence import GaussianGeometry, StudentT, importance_evidence
from .priors import GEOMETRY_NAMES
from .results import INCONCLUSIVE_LN_B, wrap_phi

__all__ = ["MAX_LN_B_ERROR", "StoppingRule", "template_evidence"]

log = logging.getLogger(__name__)

MAX_LN_B_ERROR = 0.25
"""Largest standard error of ``ln B_T`` with which rule 2 may stop a chain."""
_GEOMETRY = [PARAMETER_NAMES.index(n) for n in GEOMETRY_NAMES]


def template_evidence(log_prob_fn, flat: np.ndarray, null, priors, scales, n_draws: int, rng, mapper=map) -> dict:
    """A template's ``ln Z`` by importance sampling: a t fitted to chain samples ``flat`` (n, 6) plus the
    prior plateau in ``(r_p, phi_p)`` at the no-planet geometry (mixture 0.7 / 0.3; :mod:`.evidence`)."""
    centred, _ = wrap_phi(flat)
    chain_t = StudentT(centred.mean(axis=0), np.cov(centred, rowvar=False) * 1.2 ** 2, scales, periodic=(1,))
    plateau = GaussianGeometry(null.geometry_map, null.covariance * 1.5 ** 2, priors.geometry_widths, priors.r_p)
    return importance_evidence(log_prob_fn, [chain_t, plateau], [0.7, 0.3], n_draws, rng, mapper)


class StoppingRule:
    """The stopping test of one template's chain (see the module docs).

    Parameters
    ----------
    null : NullRun
        The no-planet run (its ``ln_evidence`` and geometry mode).
    priors : Priors
    scales : ndarray, shape (6,)
        Regularisation scales of the chain's t proposal (as the final evidence).
    min_ess : float
        Minimum ESS of every tested parameter.
    n_draws : int
        Importance draws of the evidence at a check (the run's ``evidence_draws``).
    seed : int
    name : str
        The template (seeds the check's evidence stream).
    planet_free_rule : bool
        Allow rule 2 (default True); False tests every parameter, as before.
    names : sequence of str
        The chain's coordinates (default the template's six; a continuous-mass family adds ``lnM_p``).
    evidence : callable, optional
        ``evidence(log_prob_fn, flat, rng, mapper) -> dict`` with ``ln_evidence`` and
        ``ln_evidence_err``: rule 2's estimate (default :func:`template_evidence`).
    """

    _last: tuple[tuple, dict]  # (key of the chain diagnosed last, its diagnostics); unset before the first call

    def __init__(self, null, priors, scales, *, min_ess: float, n_draws: int, seed: int, name: str,
                 planet_free_rule: bool = True, names=PARAMETER_NAMES, evidence=None):
        self.null, self.priors, self.scales = null, priors, np.asarray(scales, float)
        self.min_ess, self.n_draws, self.seed, self.name = float(min_ess), int(n_draws), int(seed), name
        self.planet_free_rule = bool(planet_free_rule)
        self.names = tuple(names)
        self.evidence = evidence or (lambda fn, flat, rng, mapper: template_evidence(
            fn, flat, self.null, self.priors, self.scales, self.n_draws, rng, mapper))

    def __call__(self, chain: np.ndarray, log_prob_fn=None, mapper=map) -> dict:
        """Diagnostics of ``chain`` (n_steps, n_walkers, n_dim) with ``converged`` and the ``stopping_rule``.

        ``log_prob_fn`` (the chain's log posterior) and ``mapper`` evaluate rule 2's evidence; without
        ``log_prob_fn`` only rule 1 is tested. Under rule 2 ``burn_in`` and ``thin`` follow the
        geometry's autocorrelation times.
        """
        key = (chain.shape, log_prob_fn is None, chain[-1].tobytes() if chain.size else b"")
        if getattr(self, "_last", (None,))[0] == key:  # the sampler asks again for the chain the loop stopped
            return dict(self._last[1])
        diag = self._diagnostics(chain, log_prob_fn, mapper)
        self._last = (key, dict(diag))
        return diag

    def _diagnostics(self, chain, log_prob_fn, mapper) -> dict:
        diag = convergence_diagnostics(chain, min_ess=self.min_ess, names=self.names)
        diag["stopping_rule"] = "every parameter > 50 tau" if diag["converged"] else None
        if diag["converged"] or not self.planet_free_rule or log_prob_fn is None:
            return diag
        n_steps, n_walkers, _ = chain.shape
        tau_g = np.array([diag["tau"][n] for n in GEOMETRY_NAMES])
        burn = int(min(np.ceil(5 * tau_g.max()), n_steps // 2))
        ess_g = n_walkers * (n_steps - burn) / tau_g
        if not (np.all(n_steps > TAU_FACTOR * tau_g) and np.all(ess_g >= self.min_ess)):
            return diag
        flat = chain[burn:].reshape(-1, chain.shape[2])
        ev = self.evidence(log_prob_fn, flat, self._rng(n_steps), mapper)
        ln_b, err = ev["ln_evidence"] - self.null.ln_evidence, ev["ln_evidence_err"]
        diag["check_ln_bayes"] = {"ln_b": ln_b, "err": err, "n_steps": int(n_steps)}
        log.info("%s: geometry converged at %d steps (max tau %.1f); ln B(planet : none) = %.2f +- %.2f",
                 self.name, n_steps, tau_g.max(), ln_b, err)
        if err <= MAX_LN_B_ERROR and ln_b + 2 * err < INCONCLUSIVE_LN_B:
            diag.update(converged=True, more_steps=0, burn_in=burn, thin=max(1, int(tau_g.max() / 2)),
                        stopping_rule=(f"planet not preferred (ln B = {ln_b:.2f} +- {err:.2f}) and the geometry "
                                       f"> {TAU_FACTOR:g} tau; r_p, phi_p not tested"))
        return diag

    def _rng(self, n_steps: int):
        return np.random.default_rng([self.seed, zlib.crc32(self.name.encode()), int(n_steps), 0x5709])
