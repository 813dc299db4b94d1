"""The angular part of the product rule: exact Fourier series of the template rows, Bessel tails."""

import numpy as np
import pytest
from scipy.special import jv

from spiralbayes.quadrature import TemplateSpectrum, angular_count, bessel_tail, bessel_tail_limit
from spiralbayes.templates import SpiralTemplate


def _template(phi0=0.0, n_t=72, seed=0):
    rng = np.random.default_rng(seed)
    phi = phi0 + 2 * np.pi * np.arange(n_t) / n_t
    return SpiralTemplate(np.array([0.5, 1.0, 2.0]), phi, rng.normal(size=(3, n_t)))


@pytest.mark.parametrize("phi0", [0.0, 0.5 * 2 * np.pi / 72])
def test_rows_carry_the_exact_fourier_coefficients_of_the_periodic_linear_interpolant(phi0):
    template = _template(phi0)
    n_t = template.phi.size
    spectrum = TemplateSpectrum(template)
    g, w = np.polynomial.legendre.leggauss(24)  # exact for each linear piece times e^{-i m phi}, m < 60
    left = template.phi[:, None] + np.pi / n_t * (g[None, :] + 1)  # nodes inside each interval
    frac = (left - template.phi[:, None]) / (2 * np.pi / n_t)
    m = np.arange(60)
    for row in range(3):
        d = template.delta[row]
        values = (1 - frac) * d[:, None] + frac * np.roll(d, -1)[:, None]
        c_direct = ((values * (np.pi / n_t) * w[None, :]).ravel()[None, :]
                    * np.exp(-1j * np.outer(m, left.ravel()))).sum(axis=1) / (2 * np.pi)
        c = spectrum.coefficients(59)[row]
        assert np.max(np.abs(c - c_direct)) < 1e-12 * np.max(np.abs(c_direct))
    # rows(n) is the band-limited series |m| < n / 2 sampled at 2 pi j / n
    n = 90
    m = np.arange(-(n // 2) + 1, n // 2)
    c = spectrum.coefficients(n // 2)
    full = np.concatenate([np.conj(c[:, 1:][:, ::-1])[:, -(n // 2 - 1):], c[:, : n // 2]], axis=1)
    direct = (full[:, None, :] * np.exp(1j * np.outer(2 * np.pi * np.arange(n) / n, m))[None]).sum(-1).real
    np.testing.assert_allclose(spectrum.rows(n), direct, atol=1e-12)


def test_bessel_tail_and_its_limit():
    for z, m0 in [(10.0, 20), (100.0, 130), (300.0, 340)]:
        direct = np.sum(np.abs(jv(np.arange(m0, m0 + 400), z)))
        assert bessel_tail(z, m0) == pytest.approx(direct, rel=1e-12, abs=1e-300)
    for m0 in (45, 180, 405):
        z = bessel_tail_limit(m0, 1e-13)
        assert bessel_tail(z, m0) <= 1e-13 < bessel_tail(z * 1.001, m0)


def test_angular_count_is_the_smallest_multiple_within_tolerance():
    for z in (3.0, 60.0, 250.0):
        n, tail = angular_count(z, 90, 1e-12)
        assert n % 90 == 0 and tail <= 1e-12
        assert n == 90 or 4 * bessel_tail(z, (n - 90) // 2) > 1e-12
