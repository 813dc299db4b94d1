"""The radial bases of the product rule: their kernel-interpolation bounds hold (brute force)."""

import numpy as np
import pytest

from spiralbayes.quadrature import GaussPanels, SincGrid, gauss_interpolation_bound, sinc_interpolation_error


def _worst_error(basis, x, ks):
    start, values = basis.evaluate(x)
    nodes = basis.nodes()
    idx = start[:, None] + np.arange(values.shape[1])[None, :]
    inside = (idx >= 0) & (idx < nodes.size)
    worst = 0.0
    for k in ks:
        samples = np.where(inside, np.exp(1j * k * nodes[np.clip(idx, 0, nodes.size - 1)]), 0.0)
        approx = np.sum(samples * values, axis=1)
        worst = max(worst, float(np.max(np.abs(approx - np.exp(1j * k * x)))))
    return worst


@pytest.mark.parametrize("p,phase", [(8, 2.0), (16, 5.0), (32, 20.0)])
def test_gauss_panel_interpolation_obeys_its_bound(p, phase):
    kappa, x0, x1 = 40.0, 0.2, 2.2
    n_pan = int(np.ceil(kappa * (x1 - x0) / phase))
    basis = GaussPanels(np.linspace(x0, x1, n_pan + 1), p)
    x = np.linspace(x0, x1, 3001)
    err = _worst_error(basis, x, np.linspace(-kappa, kappa, 41))
    bound = gauss_interpolation_bound(p, kappa * (x1 - x0) / n_pan)
    assert err <= bound
    assert err > 1e-4 * bound or err < 1e-13  # the bound is not vacuous (up to rounding)


def test_windowed_sinc_error_is_what_the_poisson_sum_says():
    bound = sinc_interpolation_error()
    assert 1e-12 < bound < 1e-11  # 16 samples each side at 2x oversampling
    kappa = 60.0
    step = np.pi / (2.0 * kappa)
    basis = SincGrid(0.2 - 16 * step, step, int(np.ceil(2.0 / step)) + 34)
    x = np.linspace(0.2, 2.2, 4001)
    err = _worst_error(basis, x, np.linspace(-kappa, kappa, 61))
    assert err <= bound * 1.05  # rounding of the sums
    assert err > 0.05 * bound  # and it is attained (the bound is not loose)
