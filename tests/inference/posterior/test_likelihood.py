"""The profile- and amplitude-marginalised likelihood against independent references:

* frank's own marginal likelihood (``GaussianModel.log_likelihood()``) and posterior mean at the
  same power spectrum and geometry (frank ignores Im V, which the test adds back);
* a plain dense evaluation (DHT coefficients at every datum, the exact type-3 perturbation);
* the fully linear model, in which the spiral term's profile is integrated out too (every
  Fourier–Bessel column of the perturbation computed): this measures the stated approximation;
* numerical quadrature and sampling of the amplitude integral.
"""

import numpy as np
import pytest

from spiralbayes.axisymmetric import AxisymmetricModel
from spiralbayes.geometry import DiscGeometry
from spiralbayes.inference.posterior.likelihood import (
    MarginalSpiralLikelihood,
    ProfileMarginal,
    draw_amplitude,
    log_amplitude_integral,
)
from spiralbayes.inference.posterior.perturbation import FastPerturbation
from spiralbayes.model import make_quadrature, perturbation_visibilities
from spiralbayes.units import ARCSEC
from tests._support.posterior_setup import R_RANGE, TRUE_GEOMETRY, profile

N_FB = 40


@pytest.fixture(scope="module")
def small(setup):
    """800 of the posterior tests' visibilities and a 40-term profile started 2 deg off."""
    vis = setup["vis"].subset(np.arange(800))
    model = AxisymmetricModel.from_profile(profile, DiscGeometry(42.0, 70.0, 0.025, -0.01), N=N_FB)
    base = ProfileMarginal(vis, model)
    return vis, model, base


def _frank_marginal(vis, base, g):
    """frank's ln P(Re V | p) and posterior mean at geometry ``g``, plus our Im-part term."""
    from frank.geometry import FixedGeometry
    from frank.statistical_models import GaussianModel, VisibilityMapping

    geometry = FixedGeometry(g.inc, g.PA, g.dRA, g.dDec)
    mapping = VisibilityMapping(base.prior.dht, geometry, verbose=False, check_qbounds=False)
    mapped = mapping.map_visibilities(vis.u, vis.v, vis.V, vis.weights)
    fit = GaussianModel(base.prior.dht, mapped["M"], mapped["j"], base.prior.power,
                        noise_likelihood=mapped["null_likelihood"])
    D = vis.V * np.conj(g.phase_factor(vis.u, vis.v))
    return fit.log_likelihood() - 0.5 * np.sum(vis.weights * D.imag ** 2), fit.mean


def test_no_planet_likelihood_is_franks_marginal_likelihood(small):
    vis, model, base = small
    geometries = [DiscGeometry(42.0, 70.0, 0.025, -0.01), DiscGeometry(40.0, 70.0, 0.005, -0.01),
                  DiscGeometry(38.5, 72.0, -0.01, 0.004)]
    ours = np.array([base.log_likelihood(g) for g in geometries])
    franks = np.array([_frank_marginal(vis, base, g)[0] for g in geometries])
    np.testing.assert_allclose(ours - ours[0], franks - franks[0], atol=1e-5)
    assert np.ptp(ours) > 1  # the geometries are distinguishable: the comparison is not trivial
    # the conditional profile is frank's posterior mean there, and re-centring changes nothing
    g = geometries[1]
    np.testing.assert_allclose(base.conditional_profile(g).I, _frank_marginal(vis, base, g)[1], rtol=1e-7,
                               atol=1e-9 * np.max(np.abs(model.I)))
    moved = base.centred_at(g)
    for other in geometries:
        assert moved.log_likelihood(other) == pytest.approx(base.log_likelihood(other), abs=1e-6)
        assert base.exact_log_likelihood(other) == pytest.approx(base.log_likelihood(other), abs=1e-6)


def test_spiral_likelihood_matches_dense_reference(setup, small):
    vis, model, base = small
    base = base.centred_at(TRUE_GEOMETRY)
    fp = FastPerturbation(base.u, base.v, base.weights, base.axisymmetric.brightness, setup["template"], R_RANGE,
                          TRUE_GEOMETRY)
    lik = MarginalSpiralLikelihood(base, fp, amplitude_max=2.0)
    rng = np.random.default_rng(3)
    thetas = [np.array([0.35, 2.0, 40.0, 70.0, 0.005, -0.01])]
    for _ in range(2):
        thetas.append(np.array([rng.uniform(*R_RANGE), rng.uniform(0, 2 * np.pi), 40 + rng.normal(0, 1.5),
                                70 + rng.normal(0, 1.5), rng.normal(0, 0.01), rng.normal(0, 0.01)]))
    for theta in thetas:
        amplitudes = (0.0, 0.6, 1.7)
        for A, exact in zip(amplitudes, lik.exact_log_likelihood(theta, amplitudes)):
            fast = lik.log_likelihood_at(theta, A)
            assert abs(fast - exact) < 0.02 + 1e-5 * abs(exact), (theta, A, fast, exact)
    # the amplitude marginal is the integral of the conditional over the prior
    theta = thetas[0]
    grid = np.linspace(0, 2, 4001)
    vals = np.array([lik.log_likelihood_at(theta, a) for a in grid[::400]])
    l0, c1, c2 = lik.amplitude_terms(theta)
    np.testing.assert_allclose(vals, l0 + grid[::400] * c1 - 0.5 * grid[::400] ** 2 * c2, atol=1e-6)
    direct = np.log(np.trapezoid(np.exp(l0 + grid * c1 - 0.5 * grid ** 2 * c2 - lik(theta)), grid) / 2.0)
    assert abs(direct) < 1e-6
    assert lik(theta) - lik.null_log_likelihood(TRUE_GEOMETRY) > 30  # the planet is seen
    fixed = MarginalSpiralLikelihood(base, fp, amplitude_max=None)  # the paper's A = 1
    assert fixed(theta) == pytest.approx(lik.log_likelihood_at(theta, 1.0), abs=1e-9)


def test_spiral_profile_approximation_against_fully_linear_model(setup, small):
    """The spiral term's profile is held at the conditional mean I0; integrating it out too changes
    ln L(A) - ln L(0) by little (the neglected term is A x template x profile spread)."""
    vis, model, base = small
    template = setup["template"]
    g = TRUE_GEOMETRY
    base = base.centred_at(g)
    r_p, phi_p = 0.35, 2.0
    uv_max = float(np.max(vis.uv_distance))
    quad = make_quadrature(template, r_p, uv_max, cell_factor=5)
    # perturbation visibilities of every Fourier-Bessel basis function (de-phased)
    basis = []
    for k in range(N_FB):
        e = np.zeros(N_FB)
        e[k] = 1.0
        column = AxisymmetricModel(model.r, e, g, model.Rmax)
        dV = perturbation_visibilities(vis.u, vis.v, g, column.brightness, template, r_p, phi_p, quad=quad,
                                       epsilon=1e-9)
        basis.append(dV * np.conj(g.phase_factor(vis.u, vis.v)))
    G = np.stack(basis, axis=1)  # (n, N): already includes cos i
    ci, H, D = base.dense_design(g)
    w = vis.weights
    Sinv = base.prior.precision

    def linear(A):
        X = ci * H + A * G
        Xs, d = np.vstack([X.real, X.imag]), np.r_[D.real, D.imag]
        ws = np.r_[w, w]
        K = Xs.T @ (ws[:, None] * Xs) + Sinv
        j = Xs.T @ (ws * d)
        return -0.5 * (np.sum(ws * d * d) - j @ np.linalg.solve(K, j) + np.linalg.slogdet(K)[1])

    p_held = base.axisymmetric.I @ G.T  # the approximation's spiral: profile I0
    for A in (0.5, 1.0):
        exact = linear(A) - linear(0.0)
        approx = base.exact_log_likelihood(g, A * p_held) - base.exact_log_likelihood(g)
        assert abs(approx - exact) < 0.05 + 0.01 * abs(exact), (A, approx, exact)
    _ = ARCSEC


def test_amplitude_integral_and_draws():
    from scipy import integrate

    rng = np.random.default_rng(1)
    for c1, c2 in [(0.0, 0.0), (3.0, 0.0), (-3.0, 0.0), (5.0, 4.0), (-50.0, 10.0), (40.0, 15.0), (3e3, 1e3)]:
        f = lambda a, c1=c1, c2=c2: np.exp(a * c1 - 0.5 * a * a * c2 - max(0.0, c1 * 2.0))  # noqa: E731
        shift = max(0.0, c1 * 2.0)
        if c1 < 100:
            ref = np.log(integrate.quad(f, 0, 2, limit=200)[0] / 2) + shift
            assert log_amplitude_integral(c1, c2, 2.0) == pytest.approx(ref, abs=1e-8)
            A = draw_amplitude(np.full(20000, c1), np.full(20000, c2), 2.0, rng)
            mean = integrate.quad(lambda a, f=f: a * f(a), 0, 2)[0] / integrate.quad(f, 0, 2)[0]
            assert A.mean() == pytest.approx(mean, abs=5 * A.std() / np.sqrt(A.size) + 1e-6)
            assert A.min() >= 0 and A.max() <= 2
        else:  # far outside the prior: piled against A_max
            A = draw_amplitude(np.full(1000, c1), np.full(1000, c2), 2.0, rng)
            assert np.all(A > 1.99) and np.all(A <= 2.0)
