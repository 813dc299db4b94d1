"""Polar uv grids of the power term: weight coefficients and the power at every azimuth, by brute force."""

import numpy as np
import pytest

from spiralbayes.inference.scan.uv_levels import (
    build_level,
    lagrange_weights,
    power_all_phi,
    theta_count,
    uv_weight_coefficients,
)
from spiralbayes.units import ARCSEC


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(4)
    n = 2000
    rho = np.sort(np.concatenate([rng.uniform(0, 3e4, 20), 2e6 * np.sqrt(rng.uniform(1e-3, 1, n - 20))]))
    theta = rng.uniform(-np.pi, np.pi, n)
    weights = rng.uniform(0.5, 2.0, n)
    return rho, theta, weights


def test_weight_coefficients_are_the_lagrange_weighted_sums(data):
    rho, theta, weights = data
    d_rho, n_theta, points = 2e4, 64, 16
    rows = uv_weight_coefficients(rho, theta, weights, d_rho, n_theta, points)
    f = rho / d_rho
    j0 = np.floor(f).astype(int)
    lag = lagrange_weights(f - j0, points)
    offsets = np.arange(-points // 2 + 1, points // 2 + 1)
    m = np.fft.fftfreq(n_theta, 1.0 / n_theta)
    for j in (0, 1, 5, 40, len(rows) - 1):  # the first rings collect the folded nodes -j
        node = j0[None, :] + offsets[:, None]
        L = np.sum(np.where(np.abs(node) == j, lag, 0.0), axis=0)
        direct = (weights * L) @ np.exp(1j * np.outer(theta, m))
        np.testing.assert_allclose(rows[j], direct, atol=1e-10 * np.abs(direct).max())


def test_power_at_every_azimuth_matches_the_direct_sum(data):
    """A few point sources within r_out: G = |P_hat|^2 is known everywhere."""
    rho, theta, weights = data
    rng = np.random.default_rng(5)
    r_out = 0.4
    r = r_out * np.sqrt(rng.uniform(0, 1, 12)) * ARCSEC
    a = rng.uniform(0, 2 * np.pi, 12)
    src = np.stack([r * np.cos(a), r * np.sin(a)], -1)
    flux = rng.normal(size=12)
    n_phi_p = 30

    def p_hat(q):
        return np.exp(2j * np.pi * q @ src.T) @ flux

    for banded in (True, False):
        level = build_level(rho, theta, weights, r_out, n_phi_p, banded=banded)
        power = power_all_phi(level, p_hat(level.nodes()), n_phi_p)
        q = np.stack([rho * np.cos(theta), rho * np.sin(theta)], -1)
        for p in (0, 7, 22):
            phi = 2 * np.pi * p / n_phi_p
            c, s = np.cos(phi), np.sin(phi)
            rotated = q @ np.array([[c, -s], [s, c]])  # R(-phi) q
            direct = np.sum(weights * np.abs(p_hat(rotated)) ** 2)
            assert power[p] == pytest.approx(direct, rel=1e-7)
    banded_level = build_level(rho, theta, weights, r_out, n_phi_p)
    full_level = build_level(rho, theta, weights, r_out, n_phi_p, banded=False)
    assert banded_level.size < 0.75 * full_level.size and full_level.hat is not None


def test_theta_count_grows_with_the_source_and_the_baseline():
    counts = [theta_count(rho, 0.5, 90) for rho in (1e5, 1e6, 4e6)]
    assert counts == sorted(counts) and all(c % 90 == 0 for c in counts)
    assert theta_count(4e6, 0.25, 90) < counts[-1]
