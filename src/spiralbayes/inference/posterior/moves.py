"""emcee moves for the posterior: differential evolution with ``phi_p`` wrapped, and independence
proposals from a normal distribution fitted to the other half of the ensemble.

**Wrapped differential evolution** (:class:`WrappedDEMove`). Differential evolution (ter Braak 2006;
Nelson et al. 2014, as emcee's ``DEMove``) proposes ``x' = x + gamma (x_a - x_b)`` from two other
walkers ``a, b``. For the planet azimuth ``phi_p`` the difference is taken the short way round the
circle (in ``(-pi, pi]``) and ``x'`` is wrapped into ``[0, 2 pi)``. The proposal stays symmetric —
the pair ``(b, a)`` is as likely as ``(a, b)`` and gives the opposite difference — so this is a
valid Metropolis move on the circle for any target that is ``2 pi``-periodic in ``phi_p``. Walkers
cannot drift without bound along a flat ``phi_p`` (planet-free data, where unwrapped walkers reach
1e29 rad), and the chain's ``phi_p`` is always in ``[0, 2 pi)``.

**Ensemble normal proposals** (:class:`EnsembleGaussianMove`). The walkers being updated draw new
positions, independently of where they are, from a normal distribution with the mean and
covariance of the complementary half of the ensemble, and accept them with the independence
sampler's Metropolis–Hastings ratio ``pi(x') q(x) / (pi(x) q(x'))``. The proposal depends only on
the complementary walkers, so emcee's red–blue split keeps the ensemble's target invariant (the
argument of emcee's ``KDEMove`` and of B. Farr and W. M. Farr's kombine sampler, whose proposal
is a clustered kernel density estimate where this one is a single normal). Where the posterior is
close to normal — the planet's position and the geometry around a detected planet — an accepted
proposal is an independent draw, so the chain decorrelates in a few steps whatever the dimension;
elsewhere the proposals are mostly rejected and the differential-evolution moves carry the chain.
A periodic coordinate is centred on the complementary walkers' circular mean, and ``q`` is the
wrapped normal density (the sum over whole turns).

A move may act on a block of the coordinates only (``block``): the other coordinates stay where
they are and the proposal is still a valid Metropolis–Hastings step. Block updates matter when a
posterior separates: on planet-free data ``(r_p, phi_p)`` fill their flat prior, and a joint
proposal that steps out of the prior in ``r_p`` is rejected together with its (good) geometry step;
the geometry-only move mixes the nuisances as in the no-planet run (Gibbs-like updates within
differential evolution, ter Braak 2006, section 3).
"""

from __future__ import annotations

import itertools

import numpy as np
from emcee.moves.red_blue import RedBlueMove
from scipy.special import logsumexp

from ...units import TWO_PI, wrap_angle

__all__ = ["DEFAULT_MOVES", "EnsembleGaussianMove", "WrappedDEMove", "default_moves"]


def _block(block, ndim: int, move: str):
    """``block`` as an index array checked against ``ndim`` coordinates (None: every coordinate)."""
    if block is None:
        return np.arange(ndim)
    if block.max() >= ndim or block.min() < 0:
        raise ValueError(f"{move}: block {block.tolist()} names coordinates outside the {ndim} of the walkers; "
                         f"give indices 0-{ndim - 1}")
    return block


class WrappedDEMove(RedBlueMove):
    """Differential evolution with the coordinates ``periodic`` living on ``[0, 2 pi)``.

    Parameters
    ----------
    periodic : sequence of int
        Indices of the periodic coordinates.
    gamma0 : float, optional
        Mean scale of the difference vector (default ``2.38 / sqrt(2 ndim)``; ``1`` makes
        jumps between modes, ter Braak 2006).
    sigma : float
        Relative spread of ``gamma``.
    block : sequence of int, optional
        Indices of the coordinates this move changes (default all); the default ``gamma0`` then
        follows the block's dimension.
    """

    def __init__(self, periodic=(1,), gamma0: float | None = None, sigma: float = 1e-5, block=None, **kwargs):
        self.periodic = np.asarray(periodic, dtype=int)
        self.gamma0 = gamma0
        self.sigma = sigma
        self.block = None if block is None else np.asarray(block, dtype=int)
        super().__init__(**kwargs)

    def setup(self, coords):
        moved = _block(self.block, coords.shape[1], "WrappedDEMove")
        self.g0 = self.gamma0 if self.gamma0 is not None else 2.38 / np.sqrt(2 * len(moved))
        self.frozen = None if self.block is None else np.setdiff1d(np.arange(coords.shape[1]), moved)

    def get_proposal(self, s, c, random):
        others = np.concatenate(c, axis=0)
        ns, nc = s.shape[0], others.shape[0]
        a = random.randint(nc, size=ns)
        b = (a + 1 + random.randint(nc - 1, size=ns)) % nc  # a different walker, uniformly
        diffs = others[a] - others[b]
        p = self.periodic
        diffs[:, p] = wrap_angle(diffs[:, p])
        if self.frozen is not None:
            diffs[:, self.frozen] = 0.0
        gamma = self.g0 * (1.0 + self.sigma * random.randn(ns, 1))
        q = s + gamma * diffs
        q[:, p] = wrap_angle(q[:, p], 0.0)
        return q, np.zeros(ns)


class EnsembleGaussianMove(RedBlueMove):
    """Independence proposals from a normal fitted to the complementary walkers (see the module docs).

    Parameters
    ----------
    periodic : sequence of int
        Indices of the periodic coordinates (period ``2 pi``).
    block : sequence of int, optional
        Indices of the coordinates this move changes (default all).
    scale : float
        Factor on the fitted standard deviations (``> 1`` gives heavier proposals than the ensemble).
    """

    def __init__(self, periodic=(1,), block=None, scale: float = 1.0, **kwargs):
        if not np.isfinite(scale) or scale <= 0:
            raise ValueError(f"EnsembleGaussianMove: scale = {scale!r} must be a positive number")
        self.periodic = np.asarray(periodic, dtype=int)
        self.block = None if block is None else np.asarray(block, dtype=int)
        self.scale = float(scale)
        super().__init__(**kwargs)

    def setup(self, coords):
        self.moved = _block(self.block, coords.shape[1], "EnsembleGaussianMove")
        self.angles = np.flatnonzero(np.isin(self.moved, self.periodic))  # positions within the block

    def get_proposal(self, s, c, random):
        x = np.concatenate(c, axis=0)[:, self.moved]
        n, d = x.shape
        centre = np.zeros(d)
        if self.angles.size:
            centre[self.angles] = np.angle(np.mean(np.exp(1j * x[:, self.angles]), axis=0))
            x = x - centre
            x[:, self.angles] = wrap_angle(x[:, self.angles])
        mean = x.mean(axis=0)
        cov = np.atleast_2d(np.cov(x, rowvar=False))
        if n <= d:  # too few walkers for a full covariance: the variances alone
            cov = np.diag(np.diag(cov))
        cov = cov * self.scale**2
        cov[np.diag_indices(d)] += 1e-12 * np.max(np.diag(cov))
        try:
            chol = np.linalg.cholesky(cov)
        except np.linalg.LinAlgError:  # the complementary walkers at one point: every proposal is refused
            return s.copy(), np.full(s.shape[0], -np.inf)
        draw = mean + random.randn(s.shape[0], d) @ chol.T
        new = draw + centre
        new[:, self.angles] = wrap_angle(new[:, self.angles], 0.0)
        q = s.copy()
        q[:, self.moved] = new
        return q, self._log_q(s[:, self.moved], centre, mean, chol) - self._log_q(new, centre, mean, chol)

    def _log_q(self, points, centre, mean, chol):
        """Log density of the proposal at ``points`` (up to the constant shared by every point): the
        normal summed over whole turns of the periodic coordinates."""
        z = points - centre - mean
        z[:, self.angles] = wrap_angle(z[:, self.angles])
        # turns out to 38 standard deviations: the terms left out are below double precision
        # (without periodic coordinates the product has one term, the normal itself)
        sd = np.sqrt(np.sum(chol[self.angles] ** 2, axis=1))
        turns = [np.arange(-k, k + 1) for k in np.ceil(38 * sd / TWO_PI).astype(int) + 1]
        terms = []
        for k in itertools.product(*turns):
            zk = z.copy()
            zk[:, self.angles] += TWO_PI * np.asarray(k)
            terms.append(-0.5 * np.sum(np.linalg.solve(chol, zk.T) ** 2, axis=0))
        return logsumexp(np.array(terms), axis=0)


DEFAULT_MOVES = "wrapped DE and ensemble normal proposals, joint and per block"
"""How a run's chain file records the default mixture (a chain written with other moves is not resumed with these)."""

PLANET_AND_GEOMETRY = ((0, 1), (2, 3, 4, 5))
"""The posterior's blocks: ``(r_p, phi_p)`` and ``(inc, PA, dRA, dDec)`` (:data:`.conditional.PARAMETER_NAMES`)."""


def default_moves(periodic=(1,), blocks=PLANET_AND_GEOMETRY, gaussian: bool = True):
    """The chains' move mixture (pairs of emcee move and probability).

    With ``gaussian`` (the default): 20 % joint wrapped DE at the usual scale, 10 % joint DE with
    ``gamma = 1`` (mode jumps), 10 % DE within the blocks (shared in proportion to their
    dimensions), 40 % ensemble normal proposals within the blocks (shared equally) and 20 % joint
    ones. ``blocks=()`` gives 60 % joint DE, 10 % mode jumps and 30 % joint normal proposals.
    ``gaussian=False`` leaves differential evolution alone: 30 % joint, 10 % mode jumps and 60 %
    within the blocks (``blocks=()``: 90 % joint, 10 % mode jumps).

    Measured on the fiducial observation (``benchmarks/bench_sample.py --mass``, 32 walkers, two
    processes): one template's largest tau 11.8 against 20.4 with differential evolution alone
    (1000 against 1100 steps to stop, the first check being at 1000), a continuous-mass family's
    14.4 against 25.3 (1000 against 1400 steps).

    Parameters
    ----------
    periodic : sequence of int
        Indices of the periodic coordinates.
    blocks : sequence of sequence of int
        Coordinate blocks that also get moves of their own; ``()`` for joint moves only.
    gaussian : bool
        Include the ensemble normal proposals.
    """
    jumps = [(WrappedDEMove(periodic, gamma0=1.0), 0.1)]
    sizes = np.array([len(b) for b in blocks], dtype=float)
    if not gaussian:
        if not blocks:
            return [(WrappedDEMove(periodic), 0.9), *jumps]
        return ([(WrappedDEMove(periodic), 0.3), *jumps]
                + [(WrappedDEMove(periodic, block=b), 0.6 * n / sizes.sum()) for b, n in zip(blocks, sizes)])
    if not blocks:
        return [(WrappedDEMove(periodic), 0.6), *jumps, (EnsembleGaussianMove(periodic), 0.3)]
    return ([(WrappedDEMove(periodic), 0.2), *jumps, (EnsembleGaussianMove(periodic), 0.2)]
            + [(WrappedDEMove(periodic, block=b), 0.1 * n / sizes.sum()) for b, n in zip(blocks, sizes)]
            + [(EnsembleGaussianMove(periodic, block=b), 0.4 / len(blocks)) for b in blocks])
