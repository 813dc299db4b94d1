"""Posterior sampling: fast likelihood vs exact, planet recovery, resume, convergence policy, priors.

A synthetic observation (seeded): 3000 random baselines up to 2 Mlambda, a smooth exponential
disc, a strong right-handed 3 M_th template planted with the exact type-3 NUFFT
(:func:`spiralbayes.model.perturbation_visibilities`), Gaussian noise. The sampler starts from a
geometry off by 20 mas in RA and 2 deg in inclination (the "frank geometry" of the test)."""

from __future__ import annotations

import numpy as np
import pytest

from spiralbayes.geometry import DiscGeometry
from spiralbayes.inference.posterior.results import wrap_phi
from tests._support.posterior_setup import R_RANGE, TRUE_GEOMETRY, TRUTH


# ------------------------------------------------------------------------------------------------
def test_axisymmetric_table_matches_exact_visibilities(setup, likelihood):
    assert likelihood.axis_table.max_error(setup["model"]) < 1e-6
    g = DiscGeometry(37.0, 65.0, -0.01, 0.02)
    vis = setup["vis"]
    exact = setup["model"].visibilities(vis.u, vis.v, g)
    up, vp = g.deproject_uv(vis.u, vis.v)
    fast = g.cos_inc * likelihood.axis_table(np.hypot(up, vp)) * g.phase_factor(vis.u, vis.v)
    assert np.max(np.abs(fast - exact)) < 1e-6 * np.max(np.abs(exact))


def test_fast_likelihood_matches_exact(setup, likelihood):
    """|Δ ln L| < 0.02 at random points (planet anywhere in the r_p window, geometry within ~2 prior sigma)."""
    rng = np.random.default_rng(7)
    priors = setup["priors"]
    for k in range(6):
        theta = priors.centre + rng.normal(size=6) * priors.widths * np.array([0, 0, 0.4, 0.4, 0.4, 0.4])
        theta[0] = rng.uniform(*R_RANGE)
        theta[1] = rng.uniform(-np.pi, 3 * np.pi)  # beyond 2 pi: periodic
        if k == 0:
            theta = TRUTH.copy()
        fast, exact = likelihood(theta), likelihood.exact_log_likelihood(theta)
        assert abs(fast - exact) < 0.02, (theta, fast, exact)
        V_fast, V_exact = likelihood.model_visibilities(theta), likelihood.exact_model_visibilities(theta)
        assert np.max(np.abs(V_fast - V_exact)) < 1e-4 * np.max(np.abs(V_exact))
    # the planet is detected: ln L(truth) far above the axisymmetric model at the true geometry
    assert likelihood(TRUTH) - likelihood.log_likelihood_axisymmetric(TRUE_GEOMETRY) > 200


def test_likelihood_is_periodic_in_phi_and_wrapping(likelihood, setup):
    assert likelihood(TRUTH) == pytest.approx(likelihood(TRUTH + np.array([0, 2 * np.pi, 0, 0, 0, 0])), abs=1e-6)
    outside = TRUTH.copy()
    outside[0] = 0.7
    assert setup["priors"].log_prior(outside) == -np.inf
    samples = np.zeros((100, 6))
    samples[:, 1] = np.r_[np.full(50, 0.05), np.full(50, 2 * np.pi - 0.05)]
    wrapped, mu = wrap_phi(samples)
    assert np.ptp(wrapped[:, 1]) == pytest.approx(0.1)
