"""The wrapped differential-evolution move: phi stays on [0, 2 pi) and periodic targets come out right."""

import emcee
import numpy as np
import pytest
from scipy.special import i0, i1

from spiralbayes.inference.posterior.moves import WrappedDEMove, default_moves


def test_proposals_wrap_and_take_the_short_way_round():
    move = WrappedDEMove(periodic=(1,), gamma0=1.0, sigma=0.0)
    move.setup(np.zeros((4, 2)))
    s = np.array([[0.0, 6.2]])
    c = [np.array([[0.0, 0.05], [0.0, 6.25]])]  # two walkers either side of the seam, 0.083 rad apart
    q, _ = move.get_proposal(s, c, np.random.RandomState(0))
    assert 0 <= q[0, 1] < 2 * np.pi
    step = (q[0, 1] - 6.2 + np.pi) % (2 * np.pi) - np.pi
    assert abs(abs(step) - 0.0832) < 1e-3  # not 6.2 rad the long way


def test_a_block_move_changes_only_its_block():
    move = WrappedDEMove(periodic=(1,), block=(2, 3))
    rng = np.random.RandomState(1)
    walkers = rng.uniform(0, 1, (8, 4))
    move.setup(walkers)
    assert move.g0 == pytest.approx(2.38 / 2)  # the block's dimension, not the walkers'
    q, _ = move.get_proposal(walkers[:4], [walkers[4:]], rng)
    np.testing.assert_array_equal(q[:, :2], walkers[:4, :2])
    assert np.all(q[:, 2:] != walkers[:4, 2:])
    with pytest.raises(ValueError, match="block"):
        WrappedDEMove(block=(5,)).setup(walkers)


def _von_mises_sampler(kappa, mu, steps, seed=0, blocks=((0,), (1,))):
    def log_prob(x):  # vectorised over walkers
        return kappa * np.cos(x[:, 1] - mu) - 0.5 * (x[:, 0] / 0.3) ** 2

    sampler = emcee.EnsembleSampler(24, 2, log_prob, moves=default_moves((1,), blocks=blocks), vectorize=True)
    sampler.random_state = np.random.RandomState(seed).get_state()
    p0 = np.column_stack([np.random.default_rng(seed).normal(0, 0.1, 24),
                          np.random.default_rng(seed + 1).uniform(0, 2 * np.pi, 24)])
    sampler.run_mcmc(p0, steps, progress=False)
    return sampler.get_chain(discard=steps // 5, flat=True)


@pytest.mark.parametrize("blocks", [(), ((0,), (1,))], ids=["joint", "blocks"])
@pytest.mark.parametrize("kappa, mu", [(20.0, 0.05), (0.0, 0.0)])
def test_periodic_targets_are_sampled_correctly(kappa, mu, blocks):
    chain = _von_mises_sampler(kappa, mu, 1000, blocks=blocks)
    phi = chain[:, 1]
    assert phi.min() >= 0 and phi.max() < 2 * np.pi  # no drift along a flat direction either
    z = np.mean(np.exp(1j * phi))
    expected_r = i1(kappa) / i0(kappa) if kappa > 0 else 0.0
    assert abs(np.abs(z) - expected_r) < 0.03
    if kappa > 0:
        assert abs(np.angle(z) - mu) < 0.03  # the mode sits across the seam: still found
    else:
        from scipy.stats import kstest

        assert kstest(phi[::10] / (2 * np.pi), "uniform").pvalue > 1e-3
    assert np.std(chain[:, 0]) == pytest.approx(0.3, rel=0.15)


def test_block_moves_sample_a_correlated_target_with_a_flat_box():
    """A planet-free-like target: (x0, x1) uniform in a box, (x2, x3) a correlated Gaussian (rho 0.9):
    the mixture of joint and block moves returns the box's moments and the Gaussian's covariance."""
    cov = np.array([[1.0, 0.9], [0.9, 1.0]])
    icov = np.linalg.inv(cov)

    def log_prob(x):
        inside = np.all((x[:, :2] > 0) & (x[:, :2] < 1), axis=1)
        g = x[:, 2:]
        return np.where(inside, -0.5 * np.einsum("ni,ij,nj->n", g, icov, g), -np.inf)

    rng = np.random.default_rng(4)
    p0 = np.column_stack([rng.uniform(0, 1, (32, 2)), rng.normal(0, 0.1, (32, 2))])
    sampler = emcee.EnsembleSampler(32, 4, log_prob, vectorize=True,
                                    moves=default_moves((), blocks=((0, 1), (2, 3))))
    sampler.random_state = np.random.RandomState(4).get_state()
    sampler.run_mcmc(p0, 3000, progress=False)
    flat = sampler.get_chain(discard=500, flat=True)
    np.testing.assert_allclose(flat[:, :2].mean(axis=0), 0.5, atol=0.02)
    np.testing.assert_allclose(flat[:, :2].var(axis=0), 1 / 12, rtol=0.08)
    np.testing.assert_allclose(np.cov(flat[:, 2:], rowvar=False), cov, atol=0.08)
