"""The learned model's regression: the length-scale floor and the trends."""

import numpy as np
import pytest

from spiralbayes.templates.learned.regression import (MIN_LENGTH_SCALE, fit_hyperparameters, fit_trends,
                                                       gaussian_process, kernel)


def _wiggle(n=60, scale=0.03, seed=1):
    """Outputs that vary on ``scale`` box sides along the first input, densely sampled, so that the
    marginal likelihood alone prefers a length scale near ``scale``."""
    rng = np.random.default_rng(seed)
    z = rng.uniform(0, 1, (n, 2))
    y = np.sin(2 * np.pi * z[:, 0] / scale) + 0.01 * rng.normal(size=n)
    return z, y[:, None]


def test_length_scales_respect_the_floor():
    z, y = _wiggle()
    free = fit_hyperparameters(z, y, [np.array([0])], restarts=1, min_length_scale=1e-3)
    floored = fit_hyperparameters(z, y, [np.array([0])], restarts=1)
    # theta = ln(constant, length scales..., noise)
    assert np.exp(free[0, 1]) < 0.5 * MIN_LENGTH_SCALE  # the unconstrained optimum lies below the floor
    assert np.all(np.exp(floored[0, 1:3]) >= MIN_LENGTH_SCALE * (1 - 1e-6))


def test_kernel_bounds_and_fixed_theta():
    k = kernel(3, 0.2)
    rbf_bounds = np.exp(k.bounds[1:4])
    np.testing.assert_allclose(rbf_bounds[:, 0], 0.2)
    z, y = _wiggle(n=20, scale=0.5)
    theta = fit_hyperparameters(z, y, [np.array([0])], restarts=0)[0]
    gp = gaussian_process(2, theta).fit(z, y[:, 0])
    np.testing.assert_allclose(gp.kernel_.theta, theta)  # no optimisation with theta given


def test_trends_are_least_squares():
    rng = np.random.default_rng(3)
    z = rng.uniform(0, 1, (30, 2))
    targets = np.column_stack([1 + 2 * z[:, 0] - z[:, 1], 0.5 - 3 * z[:, 1]])
    trends = fit_trends(z, targets, "all", n_map=1, n_coefficients=1)
    np.testing.assert_allclose(trends, [[1, 2, -1], [0.5, 0, -3]], atol=1e-12)
    disc = fit_trends(z, targets, "disc", n_map=1, n_coefficients=1)
    # 'disc': the map's coefficient on the disc's inputs only (the last input is the age)
    assert disc[0, -1] == 0.0
    np.testing.assert_allclose(disc[1], [0.5, 0, -3], atol=1e-12)


@pytest.mark.parametrize("bad", [0.0, -1.0, np.nan, 200.0])
def test_fit_refuses_a_bad_floor(bad):
    from spiralbayes.exceptions import InputError
    from spiralbayes.templates.learned import LearnedTemplateModel

    with pytest.raises(InputError, match="min_length_scale"):
        LearnedTemplateModel.fit([object()] * 4, min_length_scale=bad)
