"""The wrapped differential-evolution move: phi stays on [0, 2 pi) and periodic targets come out right."""

import emcee
import numpy as np
import pytest
from scipy.special import i0, i1
from scipy.stats import skew

from spiralbayes.inference.posterior.moves import EnsembleGaussianMove, WrappedDEMove, default_moves
from spiralbayes.units import wrap_angle


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


def _run(log_prob, p0, moves, steps, seed):
    sampler = emcee.EnsembleSampler(p0.shape[0], p0.shape[1], log_prob, moves=moves, vectorize=True)
    sampler.random_state = np.random.RandomState(seed).get_state()
    sampler.run_mcmc(p0, steps, progress=False)
    return sampler


def test_normal_proposals_alone_sample_a_skewed_target():
    """The independence move by itself (no differential evolution): a Gamma(3) coordinate correlated with a
    normal one comes out with the Gamma's mean, variance and skewness (a missing q(x)/q(x') would pull the
    chain towards the fitted normal: skewness 0)."""
    shape = 3.0

    def log_prob(x):
        g, y = x[:, 0], x[:, 1] - 0.5 * x[:, 0]
        return np.where(g > 0, (shape - 1) * np.log(np.where(g > 0, g, 1.0)) - g - 0.5 * y**2, -np.inf)

    rng = np.random.default_rng(2)
    p0 = np.column_stack([rng.gamma(shape, size=32), rng.normal(1.5, 1.0, 32)])
    sampler = _run(log_prob, p0, [(EnsembleGaussianMove(periodic=()), 1.0)], 3000, seed=2)
    assert 0.3 < np.mean(sampler.acceptance_fraction) < 0.95
    g = sampler.get_chain(discard=300, flat=True)[:, 0]
    assert np.mean(g) == pytest.approx(shape, rel=0.03)
    assert np.var(g) == pytest.approx(shape, rel=0.08)
    assert skew(g) == pytest.approx(2 / np.sqrt(shape), abs=0.12)


@pytest.mark.parametrize("kappa, mu", [(2.0, 0.05), (20.0, 6.2), (0.0, 0.0)])
def test_normal_proposals_alone_sample_an_angle_across_the_seam(kappa, mu):
    """A von Mises azimuth by the independence move alone: the wrapped normal's density (summed over whole
    turns) is what makes the circular mean resultant come out as I1/I0, for a broad, a narrow and a flat target."""

    def log_prob(x):
        return kappa * np.cos(x[:, 1] - mu) - 0.5 * (x[:, 0] / 0.3) ** 2

    rng = np.random.default_rng(3)
    p0 = np.column_stack([rng.normal(0, 0.1, 24), rng.uniform(0, 2 * np.pi, 24)])
    chain = _run(log_prob, p0, [(EnsembleGaussianMove(periodic=(1,)), 1.0)], 2000, seed=3).get_chain(
        discard=300, flat=True)
    phi = chain[:, 1]
    assert phi.min() >= 0 and phi.max() < 2 * np.pi
    z = np.mean(np.exp(1j * phi))
    assert abs(np.abs(z) - (i1(kappa) / i0(kappa) if kappa > 0 else 0.0)) < 0.03
    if kappa > 0:
        assert abs(np.angle(z * np.exp(-1j * mu))) < 0.03
    assert np.std(chain[:, 0]) == pytest.approx(0.3, rel=0.1)


def test_normal_proposals_move_only_their_block():
    move = EnsembleGaussianMove(periodic=(1,), block=(0, 1))
    rng = np.random.RandomState(5)
    walkers = np.column_stack([rng.normal(size=(16, 1)), rng.uniform(0, 2 * np.pi, (16, 1)), rng.normal(size=(16, 2))])
    move.setup(walkers)
    q, f = move.get_proposal(walkers[:8], [walkers[8:]], rng)
    np.testing.assert_array_equal(q[:, 2:], walkers[:8, 2:])
    assert np.all(q[:, :2] != walkers[:8, :2]) and np.all(np.isfinite(f))
    assert q[:, 1].min() >= 0 and q[:, 1].max() < 2 * np.pi
    with pytest.raises(ValueError, match="block"):
        EnsembleGaussianMove(block=(4,)).setup(walkers)
    with pytest.raises(ValueError, match="scale"):
        EnsembleGaussianMove(scale=0.0)


def test_normal_proposals_keep_a_collapsed_ensemble_where_it_is():
    """Complementary walkers all at one point: no proposal can be accepted (its factor is -inf)."""
    move = EnsembleGaussianMove(periodic=())
    walkers = np.ones((8, 3))
    move.setup(walkers)
    _, f = move.get_proposal(walkers[:4] + 0.5, [walkers[4:]], np.random.RandomState(0))
    assert np.all(f == -np.inf)


@pytest.mark.parametrize("blocks", [(), ((0, 1), (2, 3, 4, 5))], ids=["joint", "blocks"])
def test_default_mixture_is_a_distribution_over_moves(blocks):
    for gaussian in (True, False):
        mix = default_moves((1,), blocks=blocks, gaussian=gaussian)
        assert sum(w for _, w in mix) == pytest.approx(1.0)
        assert any(isinstance(m, EnsembleGaussianMove) for m, _ in mix) is gaussian


def test_normal_proposal_density_is_the_wrapped_normal():
    """The density the Metropolis-Hastings ratio uses against a histogram of the proposals themselves, for a
    broad ensemble (angle sd ~1.7 rad) whose normal reaches past +-pi: summing whole turns is what makes
    them agree."""
    rng = np.random.RandomState(7)
    others = np.column_stack([rng.normal(size=16), rng.uniform(0, 2 * np.pi, 16)])
    move = EnsembleGaussianMove(periodic=(1,), block=(1,))
    move.setup(others)
    q, _ = move.get_proposal(np.zeros((400_000, 2)), [others], rng)
    counts, edges = np.histogram(q[:, 1], bins=36, range=(0, 2 * np.pi))
    centres = 0.5 * (edges[1:] + edges[:-1])
    x = others[:, 1:]
    centre = np.angle(np.mean(np.exp(1j * x)))
    z = wrap_angle(x - centre)
    chol = np.linalg.cholesky(np.atleast_2d(np.var(z, ddof=1)))
    log_q = move._log_q(centres[:, None], np.array([centre]), z.mean(axis=0), chol)
    expected = np.exp(log_q) / np.sum(np.exp(log_q)) * q.shape[0]
    np.testing.assert_allclose(counts, expected, rtol=0.05)
