"""The planet's optimum: the best of two modes is found, and a pool (forked workers or threads)
finds the same optimum, bit for bit.

Reference: an analytic posterior with two modes in ``(r_p, phi_p)`` whose heights and positions are
known, optimised without a pool.
"""

import numpy as np

from spiralbayes.inference.posterior import Priors, walker_pool
from spiralbayes.inference.posterior.optimise import find_map

PRIORS = Priors((0.1, 0.6), (30.0, 1.0), (60.0, 1.0), (0.0, 0.01), (0.0, 0.01))
BEST = np.array([0.42, 2.0, 30.3, 59.8, 0.002, -0.001])
OTHER = np.array([0.2, 5.0, 30.0, 60.0, 0.0, 0.0])
WIDTH = np.array([0.01, 0.1, 0.3, 0.3, 0.003, 0.003])


def log_post(theta):
    """Two Gaussian modes, the one at BEST 5 higher in ln p; the blob as the sampled likelihood's."""
    theta = np.asarray(theta, float)
    lp = []
    for centre, height in ((BEST, 5.0), (OTHER, 0.0)):
        z = (theta - centre) / WIDTH
        z[1] = (np.angle(np.exp(1j * (theta[1] - centre[1])))) / WIDTH[1]
        lp.append(height - 0.5 * float(z @ z))
    return float(np.logaddexp(*lp)), 0.0, 0.0


def test_find_map_finds_the_higher_mode_and_a_pool_gives_the_same_optimum():
    geometry, sigma = np.array([30.0, 60.0, 0.0, 0.0]), WIDTH[2:]
    serial = find_map(log_post, PRIORS, None, "t", geometry, sigma)
    assert np.all(np.abs(serial - BEST) < 0.05 * WIDTH), serial - BEST  # the higher mode, to 5 % of its width
    for processes, threads in ((2, 1), (1, 2)):
        with walker_pool(None, processes, log_post, threads) as walkers:
            assert walkers.pool is not None
            pooled = find_map(log_post, PRIORS, None, "t", geometry, sigma, pool_map=walkers.map,
                              pool_log_prob=walkers.log_prob)
        np.testing.assert_array_equal(pooled, serial)
