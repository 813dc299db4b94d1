"""An emcee move for parameters on a circle: differential evolution with wrapped differences.

Differential evolution (ter Braak 2006; Nelson et al. 2014, as emcee's ``DEMove``) proposes
``x' = x + gamma (x_a - x_b)`` from two other walkers ``a, b``. For the planet azimuth
``phi_p`` the difference is taken the short way round the circle (in ``(-pi, pi]``) and ``x'`` is
wrapped into ``[0, 2 pi)``. The proposal stays symmetric — the pair ``(b, a)`` is as likely as
``(a, b)`` and gives the opposite difference — so this is a valid Metropolis move on the circle
for any target that is ``2 pi``-periodic in ``phi_p``. Walkers can no longer drift without bound
along a flat ``phi_p`` (planet-free data, where unwrapped walkers reached 1e29 rad), and the
chain's ``phi_p`` is always in ``[0, 2 pi)``.
"""

from __future__ import annotations

import numpy as np
from emcee.moves.red_blue import RedBlueMove

from ...units import wrap_angle

__all__ = ["WrappedDEMove", "default_moves"]


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
    """

    def __init__(self, periodic=(1,), gamma0: float | None = None, sigma: float = 1e-5, **kwargs):
        self.periodic = np.asarray(periodic, dtype=int)
        self.gamma0 = gamma0
        self.sigma = sigma
        super().__init__(**kwargs)

    def setup(self, coords):
        self.g0 = self.gamma0 if self.gamma0 is not None else 2.38 / np.sqrt(2 * coords.shape[1])

    def get_proposal(self, s, c, random):
        others = np.concatenate(c, axis=0)
        ns, nc = s.shape[0], others.shape[0]
        a = random.randint(nc, size=ns)
        b = (a + 1 + random.randint(nc - 1, size=ns)) % nc  # a different walker, uniformly
        diffs = others[a] - others[b]
        p = self.periodic
        diffs[:, p] = wrap_angle(diffs[:, p])
        gamma = self.g0 * (1.0 + self.sigma * random.randn(ns, 1))
        q = s + gamma * diffs
        q[:, p] = wrap_angle(q[:, p], 0.0)
        return q, np.zeros(ns)


def default_moves(periodic=(1,)):
    """90 % wrapped DE at the usual scale, 10 % with ``gamma = 1`` (mode jumps)."""
    return [(WrappedDEMove(periodic), 0.9), (WrappedDEMove(periodic, gamma0=1.0), 0.1)]
