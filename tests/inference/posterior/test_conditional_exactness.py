"""The likelihood's quadrature against an independent, converged reference (issue 11 exactness suite).

The posterior tests' observation (3000 baselines, an inclined disc with an offset phase centre, a
3 M_th planet) at points spread over the planet's r_p window and over the geometry (inclination,
PA and offsets away from the likelihood's reference geometry). The reference ln L uses the exact
(Hankel) axisymmetric visibilities and ΔV from :mod:`tests._support.quadrature_reference`, converged by
raising its orders. The likelihood's exact path must match it to 1e-6 in ln L and stay within
its own reported ``quadrature_error``; the fast path (tables, issue 15's) is held to the bound its
table refinement states — ``sqrt(sum w |dV|^2) <= rp_tolerance`` at node midpoints, so by
Cauchy-Schwarz ``|d ln L| <= sqrt(chi2) rp_tolerance + rp_tolerance^2 / 2`` — and its difference
is printed.
"""

from __future__ import annotations

import inspect

import numpy as np
import pytest

from spiralbayes.inference.posterior.conditional import SpiralLikelihood, geometry_from_theta
from tests._support.posterior_setup import R_RANGE, TRUTH
from tests._support.quadrature_reference import reference_visibilities

ORDERS = ((5, 4), (7, 6))
RP_TOLERANCE = inspect.signature(SpiralLikelihood).parameters["rp_tolerance"].default  # the fixture's


def _points(n, seed=3):
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        theta = TRUTH.copy()
        theta[0] = rng.uniform(*R_RANGE)
        theta[1] = rng.uniform(0, 2 * np.pi)
        theta[2] += rng.uniform(-6, 6)       # inc [deg]
        theta[3] += rng.uniform(-15, 15)     # PA [deg]
        theta[4:] += rng.uniform(-0.03, 0.03, 2)  # dRA, dDec [arcsec]
        out.append(TRUTH.copy() if k == 0 else theta)
    return out


def reference_log_likelihood(likelihood, theta, orders):
    geometry = geometry_from_theta(theta)
    model = likelihood.axisymmetric
    V = model.visibilities(likelihood.u, likelihood.v, geometry)
    V = V + reference_visibilities(likelihood.u, likelihood.v, geometry, likelihood.profile, likelihood.template,
                                   float(theta[0]), float(theta[1]), order_r=orders[0], order_phi=orders[1],
                                   support=model.Rmax)
    return -0.5 * (float(np.sum(likelihood.weights * np.abs(V - likelihood.V) ** 2)) - likelihood.chi2_ref)


def check_points(likelihood, points):
    worst_exact = worst_fast = worst_ref = fast_ratio = 0.0
    qerr = likelihood.quadrature_error
    for k, theta in enumerate(points):
        ref = reference_log_likelihood(likelihood, theta, ORDERS[0])
        if k < 3:  # the reference itself has converged
            worst_ref = max(worst_ref, abs(reference_log_likelihood(likelihood, theta, ORDERS[1]) - ref))
        exact, fast = likelihood.exact_log_likelihood(theta), likelihood(theta)
        chi2 = 2 * abs(ref) + likelihood.chi2_ref  # |δ ln L| <= sqrt(chi2) qerr + qerr^2 / 2
        assert abs(exact - ref) <= np.sqrt(chi2) * qerr + qerr ** 2 + 2 * worst_ref + 1e-9, (theta, exact, ref)
        worst_exact = max(worst_exact, abs(exact - ref))
        worst_fast = max(worst_fast, abs(fast - ref))
        tol = RP_TOLERANCE
        fast_ratio = max(fast_ratio, abs(fast - ref) / (np.sqrt(chi2) * tol + tol ** 2))
    print(f"likelihood at {len(points)} points: max |exact - reference| = {worst_exact:.2e}, "
          f"max |fast - reference| = {worst_fast:.2e}, reference change at orders {ORDERS[1]} = {worst_ref:.2e}, "
          f"reported quadrature_error = {qerr:.2e}")
    assert worst_ref < 1e-7
    assert worst_exact < 1e-6
    assert fast_ratio <= 1.0, (worst_fast, fast_ratio)
    assert qerr < 1e-6  # far below rp_tolerance (0.01), in the same norm sqrt(sum w |dV|^2)


def test_likelihood_quadrature_is_exact_at_varied_geometry(likelihood):
    check_points(likelihood, _points(4))


@pytest.mark.slow
def test_likelihood_quadrature_is_exact_at_twenty_points(likelihood):
    check_points(likelihood, _points(24, seed=11))
