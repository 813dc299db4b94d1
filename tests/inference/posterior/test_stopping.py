"""The stopping rule (inference/posterior/stopping.py) against a posterior with a closed-form evidence.

The target: ``(r_p, phi_p)`` uniform on their prior, the geometry a Gaussian ``N(mu, Sigma)`` — the
posterior of planet-free data — scaled by ``exp(ln_b)``, so that ``Z_T = exp(ln_b)`` exactly and,
with ``ln Z_0 = 0``, the Bayes factor is ``ln_b`` (the independent reference). The chains are
synthetic: independent geometry draws (tau ~ 1) and an ``r_p`` random walk (AR(1), tau ~ 1000),
the shape of a planet-free run whose flat ``r_p`` never reaches 50 tau.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy import stats

from spiralbayes.inference.posterior.stopping import StoppingRule

R_RANGE = (0.1, 0.5)
MU = np.array([30.0, 60.0, 0.0, 0.0])
SIGMA = np.diag([0.05, 0.1, 1e-3, 1e-3]) ** 2
PRIORS = SimpleNamespace(r_p=R_RANGE, geometry_widths=np.array([5.0, 5.0, 0.02, 0.02]))
NULL = SimpleNamespace(ln_evidence=0.0, geometry_map=MU, covariance=SIGMA)
SCALES = np.array([0.1, 1.8, 0.5, 1.0, 0.01, 0.01])


def _log_post(ln_b: float):
    gauss = stats.multivariate_normal(MU, SIGMA)
    lo, hi = R_RANGE

    def f(theta):
        if not lo <= theta[0] <= hi:
            return -np.inf
        return ln_b + gauss.logpdf(theta[2:]) - np.log(hi - lo) - np.log(2 * np.pi)

    return f


def _chain(n_steps=3000, n_walkers=16, rho=0.998, geometry_rho=0.0, seed=0):
    rng = np.random.default_rng(seed)
    chain = np.empty((n_steps, n_walkers, 6))
    x = rng.uniform(-1, 1, n_walkers)
    g = rng.multivariate_normal(np.zeros(4), SIGMA, n_walkers)
    for i in range(n_steps):
        x = rho * x + np.sqrt(1 - rho ** 2) * 0.5 * rng.normal(size=n_walkers)
        g = geometry_rho * g + np.sqrt(1 - geometry_rho ** 2) * rng.multivariate_normal(np.zeros(4), SIGMA, n_walkers)
        chain[i, :, 0] = 0.3 + 0.2 * np.tanh(x)
        chain[i, :, 1] = rng.uniform(0, 2 * np.pi, n_walkers)
        chain[i, :, 2:] = MU + g
    return chain


def _rule(**kw):
    return StoppingRule(NULL, PRIORS, SCALES, min_ess=400, n_draws=3000, seed=0, name="t", **kw)


@pytest.fixture(scope="module")
def flat_chain():
    return _chain()


@pytest.mark.parametrize("ln_b,stops", [(-3.0, True), (0.3, True), (2.0, False)])
def test_planet_free_chain_stops_on_the_geometry_when_the_planet_is_not_preferred(flat_chain, ln_b, stops):
    diag = _rule()(flat_chain, _log_post(ln_b))
    assert diag["tau"]["r_p"] > flat_chain.shape[0] / 50  # rule 1 cannot stop it
    check = diag["check_ln_bayes"]
    assert check["ln_b"] == pytest.approx(ln_b, abs=max(3 * check["err"], 0.02))  # the closed form
    assert check["err"] < 0.1
    assert diag["converged"] is stops
    if stops:
        assert diag["stopping_rule"].startswith("planet not preferred")
        assert diag["burn_in"] < 50 and diag["thin"] == 1  # from the geometry's tau ~ 1, not r_p's
    else:
        assert diag["stopping_rule"] is None and diag["more_steps"] > 0


def test_the_rule_is_deterministic_and_can_be_switched_off(flat_chain):
    a, b = _rule()(flat_chain, _log_post(-3.0)), _rule()(flat_chain, _log_post(-3.0))
    assert a["check_ln_bayes"] == b["check_ln_bayes"]  # a resumed run stops at the same step
    off = _rule(planet_free_rule=False)(flat_chain, _log_post(-3.0))
    assert not off["converged"] and "check_ln_bayes" not in off
    assert not _rule()(flat_chain)["converged"]  # without the log posterior only rule 1


def test_an_unconverged_geometry_never_stops_and_costs_no_evidence():
    slow = _chain(n_steps=1000, geometry_rho=0.99, seed=1)  # geometry tau ~ 200 > 1000 / 50

    def never(theta):
        raise AssertionError("no evidence is computed before the geometry converges")

    diag = _rule()(slow, never)
    assert not diag["converged"] and "check_ln_bayes" not in diag


def test_a_chain_converged_in_every_parameter_stops_on_rule_one():
    mixed = _chain(n_steps=1000, rho=0.0, seed=2)
    diag = _rule()(mixed, _log_post(5.0))
    assert diag["converged"] and diag["stopping_rule"] == "every parameter > 50 tau"


def test_asking_again_for_the_same_chain_costs_no_second_evidence(flat_chain):
    calls = []
    f = _log_post(-3.0)

    def counted(theta):
        calls.append(1)
        return f(theta)

    rule = _rule()
    first = rule(flat_chain, counted)
    n = len(calls)
    assert rule(flat_chain, counted) == first and len(calls) == n == 3000
    rule(flat_chain[:-1], counted)  # another chain: a new check
    assert len(calls) == 2 * n


def test_a_continuous_mass_family_stops_on_the_geometry_with_its_own_evidence():
    """The same closed form with ``ln M_p`` uniform on its prior and wandering like ``r_p``: rule 2
    stops the 7-parameter chain and its evidence (t + plateau with the mass) finds ``ln_b``."""
    from spiralbayes.inference.posterior import MASS_PARAMETER_NAMES, MassPrior, family_evidence

    mass_prior = MassPrior()
    lo, hi = mass_prior.ln_range
    base = _chain()
    rng = np.random.default_rng(3)
    x = np.cumsum(rng.normal(0, 0.05, base.shape[:2]), axis=0)
    lnm = lo + (hi - lo) * (0.5 + 0.5 * np.tanh(x / 3))
    chain = np.concatenate([base, lnm[..., None]], axis=2)
    ln_b = -2.0
    six = _log_post(ln_b)

    def f(theta):
        return six(theta[:6]) + mass_prior.log_prior(theta[6])

    scales = np.append(SCALES, (hi - lo) / np.sqrt(12))
    rule = StoppingRule(NULL, PRIORS, scales, min_ess=400, n_draws=3000, seed=0, name="family",
                        names=MASS_PARAMETER_NAMES,
                        evidence=lambda fn, flat, r, m: family_evidence(fn, flat, NULL, PRIORS, mass_prior, scales,
                                                                        3000, r, m))
    diag = rule(chain, f)
    assert "lnM_p" in diag["tau"] and diag["tau"]["lnM_p"] > chain.shape[0] / 50
    check = diag["check_ln_bayes"]
    assert check["ln_b"] == pytest.approx(ln_b, abs=max(3 * check["err"], 0.02))
    assert diag["converged"] and diag["stopping_rule"].startswith("planet not preferred")
