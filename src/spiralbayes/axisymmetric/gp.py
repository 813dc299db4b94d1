"""frank's Gaussian-process prior on the brightness profile, and the normal equations it needs.

frank (Jennings et al. 2020, MNRAS 495, 3209) models the brightness at its ``N`` collocation
radii, ``I = (I(r_1), ..., I(r_N))`` [Jy/sr], as a Gaussian process whose covariance is set by a
power spectrum ``p`` [Jy^2] on the conjugate collocation frequencies ``q_k``:

    I ~ N(0, S),    S^-1 = Y^T diag(1 / p) Y,

with ``Y`` the discrete Hankel transform at the ``q_k`` (frank's
``DiscreteHankelTransform.coefficients()``; ``GaussianModel`` builds ``S^-1`` the same way).
The visibilities of an optically thick disc are ``V(q) = cos i H(q) I`` with ``H(q)`` the DHT
coefficients at deprojected baseline ``q``. For fixed geometry the data are linear in ``I``, so
with weights ``w`` the posterior of ``I`` is Gaussian with precision ``K = M + S^-1`` and mean
``K^-1 j``, where

    M = cos^2 i sum_k w_k H(q_k)^T H(q_k),    j = cos i sum_k w_k Re(V_k) H(q_k)^T

are frank's "design matrix" and "information source" (``VisibilityMapping.map_visibilities``),
and ``I`` integrates out of the likelihood analytically (frank's ``log_likelihood()`` without
an argument). :mod:`spiralbayes.inference.posterior.likelihood` uses these pieces at every sampled
geometry.

:class:`ProfilePrior` holds ``p`` and ``S^-1``. The power spectrum is the one frank found
(``AxisymmetricModel.power_spectrum``: frank's MAP spectrum, empirical Bayes); for models not
fitted by frank (``AxisymmetricModel.from_profile``) the profile's own power, ``p_k =
max((Y I)_k^2, p0)``, stands in for it (documented fallback).

:class:`QGridProjector` computes ``M`` and ``j`` for ~1e5 visibilities in milliseconds: the
rows ``H(q)`` are smooth, band-limited functions of ``q`` (``J0(2 pi q r_k)``, ``r_k < Rmax``),
so ``H(q_k)`` is replaced by its ``order``-point Lagrange interpolant on a uniform ``q`` grid
``g_a``, ``H(q_k) ~ sum_a c_a(q_k) H(g_a)``. The data are "spread" onto that grid once
(``rho_a = sum_k w_k c_a(q_k)``, a few ``bincount`` calls) and

    M ~ cos^2 i sum_a rho_a H(g_a)^T H(g_a),    j ~ cos i sum_a (sum_k w_k Re V_k c_a(q_k)) H(g_a)^T,

a product of size ``n_grid x N^2`` instead of ``n_data x N^2`` — frank's own deprojected
binning, made exact to the interpolation error. The products ``H_l H_m`` oscillate at most
like ``cos(4 pi Rmax q)``, whose ``order``-point interpolation errs by at most
``C_order (4 pi Rmax dq)^order`` (``C_8 = 1.1e-3``); the grid step follows from the requested
``tolerance`` (default 1e-9 of ``max |H|^2``), and
:meth:`QGridProjector.max_error` measures it against frank's coefficients at the data.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..exceptions import InputError
from ..units import ARCSEC, TWO_PI

__all__ = ["DEFAULT_ORDER", "STENCIL_TO_GRID_COST", "ProfilePrior", "QGridProjector"]

PROFILE_POWER_FLOOR = 1e-15
"""Floor [Jy^2] of the fallback power spectrum (frank's default p0)."""


@dataclass
class ProfilePrior:
    """frank's Gaussian-process prior on the profile: ``I ~ N(0, S)``, ``S^-1 = Y^T diag(1/p) Y``.

    Parameters
    ----------
    Rmax : float
        Outer radius of the Fourier–Bessel series [arcsec].
    power : ndarray, shape (N,)
        Power spectrum ``p_k`` [Jy^2] at frank's collocation frequencies; positive.
    source : str
        Where ``power`` came from ("frank" or "profile power").
    """

    Rmax: float
    power: np.ndarray
    source: str = "frank"

    def __post_init__(self):
        self.power = np.asarray(self.power, dtype=float).ravel()
        if self.power.size < 2 or not np.all(np.isfinite(self.power)) or np.any(self.power <= 0):
            raise InputError("ProfilePrior.power must hold N >= 2 positive, finite values [Jy^2] "
                             "(frank's power spectrum)")
        if not (np.isfinite(self.Rmax) and self.Rmax > 0):
            raise InputError(f"ProfilePrior.Rmax = {self.Rmax!r} arcsec must be positive")

    @property
    def N(self) -> int:
        return self.power.size

    @cached_property
    def dht(self):
        from frank.hankel import DiscreteHankelTransform

        return DiscreteHankelTransform(self.Rmax * ARCSEC, self.N)

    @cached_property
    def precision(self) -> np.ndarray:
        """``S^-1`` [(Jy/sr)^-2], (N, N)."""
        Y = self.dht.coefficients()
        return (Y.T / self.power) @ Y

    @cached_property
    def logdet_covariance(self) -> float:
        """``ln det S``."""
        sign, logdet = np.linalg.slogdet(self.precision)
        return float(-logdet)

    def coefficients(self, q) -> np.ndarray:
        """frank's forward DHT coefficients ``H(q)`` [Jy per Jy/sr], shape (len(q), N), face on."""
        return self.dht.coefficients(np.abs(np.asarray(q, dtype=float)), direction="forward")

    @classmethod
    def from_model(cls, axisymmetric, *, floor: float = PROFILE_POWER_FLOOR) -> ProfilePrior:
        """The prior of a frank fit (its MAP power spectrum), else the profile's own power.

        Parameters
        ----------
        axisymmetric : AxisymmetricModel
            ``power_spectrum`` (saved with frank fits) or ``frank_solution.power_spectrum`` is
            used when present; otherwise ``p_k = max((Y I)_k^2, floor)``: a prior that lets each
            Fourier–Bessel mode vary by about its own amplitude in the given profile.
        """
        power = getattr(axisymmetric, "power_spectrum", None)
        if power is None:
            sol = getattr(axisymmetric, "frank_solution", None)
            power = getattr(sol, "power_spectrum", None) if sol is not None else None
        if power is not None:
            return cls(float(axisymmetric.Rmax), np.asarray(power, dtype=float), "frank")
        prior = cls(float(axisymmetric.Rmax), np.ones(axisymmetric.N), "profile power")
        vq = prior.dht.coefficients() @ np.asarray(axisymmetric.I, dtype=float)
        return cls(float(axisymmetric.Rmax), np.maximum(vq ** 2, floor), "profile power")


# ---------------------------------------------------------------------------------------------
_INVERSE_DENOMINATORS: dict = {}
DEFAULT_ORDER = 8
"""Points of the Lagrange stencil when the number of data is not known."""
STENCIL_TO_GRID_COST = 4.2e-3
"""Cost of one grid point in the normal matrix per ``N^2``, in units of one visibility's work per
stencil point (stencil weights, three spreads, one interpolation). Measured with
``benchmarks/bench_sample.py`` (N = 200, 36,000 and 100,000 visibilities to 3.7 Mlambda; orders 6 and
8): 8.6e-6 ms per visibility and stencil point, 3.6e-8 ms per grid point and ``N^2``. Only the
choice of order depends on it, never the accuracy."""
_LAGRANGE_CONSTANT = {4: 0.0234, 6: 4.88e-3, 8: 1.06e-3, 10: 2.2e-4}
"""max_t |prod_m (t - x_m)| / order! on the central interval, nodes x_m = -order/2+1 .. order/2."""


@dataclass
class QGridProjector:
    """Spread data onto a uniform grid in deprojected baseline length ``q`` (see module docs).

    Attributes
    ----------
    step : float
        Grid step [lambda].
    order : int
        Points of the Lagrange stencil (even).
    offset : int
        Index of ``q = 0`` on the grid (the grid starts ``offset`` steps below 0, where
        ``H(-q) = H(q)``).
    H : ndarray, shape (n_grid, N)
        ``H(g_a)`` (face on).
    """

    step: float
    order: int
    offset: int
    H: np.ndarray
    stats: dict = field(default_factory=dict)

    @classmethod
    def build(cls, prior: ProfilePrior, q_max: float, *, tolerance: float = 1e-9, order: int | None = DEFAULT_ORDER,
              n_data: int | None = None) -> QGridProjector:
        """A grid up to ``q_max`` [lambda] whose interpolation error is about ``tolerance``.

        ``order=None`` takes :meth:`cheapest_order` for ``n_data`` visibilities.
        """
        if order is None:
            if n_data is None:
                raise InputError("order=None needs n_data, the number of visibilities the grid will serve")
            order = cls.cheapest_order(prior, q_max, n_data, tolerance)
        if order not in _LAGRANGE_CONSTANT:
            raise InputError(f"order = {order}: use one of {sorted(_LAGRANGE_CONSTANT)}")
        step = cls._step(prior, tolerance, order)
        offset = order // 2
        n = cls._n_grid(q_max, step, order)
        g = (np.arange(n) - offset) * step
        return cls(float(step), int(order), offset, prior.coefficients(g))

    @staticmethod
    def _step(prior: ProfilePrior, tolerance: float, order: int) -> float:
        omega = 2 * TWO_PI * prior.Rmax * ARCSEC  # fastest oscillation of H_l H_m [rad / lambda]
        return (tolerance / _LAGRANGE_CONSTANT[order]) ** (1.0 / order) / omega

    @staticmethod
    def _n_grid(q_max: float, step: float, order: int) -> int:
        return int(np.ceil(q_max * 1.0001 / step)) + 2 * (order // 2) + 1

    @classmethod
    def cheapest_order(cls, prior: ProfilePrior, q_max: float, n_data: int, tolerance: float = 1e-9) -> int:
        """The stencil order with the least work per likelihood call at the same ``tolerance``.

        Per call the data cost ``n_data x order`` (stencil, spreads) and the grid
        ``n_grid x N^2`` (the normal matrix); a longer stencil allows a coarser grid. Few data
        over long baselines favour long stencils, many data short ones
        (:data:`STENCIL_TO_GRID_COST`).
        """
        def cost(order: int) -> float:
            n_grid = cls._n_grid(q_max, cls._step(prior, tolerance, order), order)
            return n_data * order + STENCIL_TO_GRID_COST * n_grid * prior.N ** 2

        return min(_LAGRANGE_CONSTANT, key=cost)

    @property
    def n_grid(self) -> int:
        return self.H.shape[0]

    def stencil(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """First grid index of each point's stencil (n,) and the Lagrange weights (order, n)."""
        p = self.order
        f = np.asarray(q, dtype=float) * (1.0 / self.step)
        base = np.floor(f)
        t = f - base
        first = base.astype(np.intp) + (self.offset - p // 2 + 1)
        if first.size and (first.min() < 0 or first.max() + p > self.n_grid):
            raise InputError(f"deprojected baselines up to {float(np.max(q)):.4g} lambda exceed the q grid "
                             f"({(self.n_grid - self.offset - p) * self.step:.4g} lambda)")
        # w_s = prod_{m != s} (t - x_m) / (x_s - x_m) = c_s P(t) / (t - x_s), P = prod_m (t - x_m); t is
        # kept off the node t = 0 (by 1e-12 of a step: an error far below the interpolation's)
        np.maximum(t, 1e-12, out=t)
        nodes = np.arange(p) - (p // 2 - 1)  # stencil positions relative to floor(f)
        diff = t[None, :] - nodes[:, None]  # (p, n), rows contiguous
        prod = diff[0].copy()
        for s in range(1, p):
            prod *= diff[s]
        weights = np.divide(prod[None, :], diff, out=diff)
        weights *= self._inverse_denominators(p)[:, None]
        return first, weights

    @staticmethod
    def _inverse_denominators(p: int) -> np.ndarray:
        if p not in _INVERSE_DENOMINATORS:
            nodes = np.arange(p) - (p // 2 - 1)
            _INVERSE_DENOMINATORS[p] = np.array([1.0 / np.prod([nodes[s] - nodes[m] for m in range(p) if m != s])
                                                 for s in range(p)])
        return _INVERSE_DENOMINATORS[p]

    def spread(self, first: np.ndarray, weights: np.ndarray, values: np.ndarray) -> np.ndarray:
        """``rho_a = sum_k values_k c_a(q_k)`` on the grid (the adjoint of :meth:`interpolate`)."""
        out = np.bincount(first, weights[0] * values, minlength=self.n_grid)
        for s in range(1, self.order):
            out[s:] += np.bincount(first, weights[s] * values, minlength=self.n_grid - s)[: self.n_grid - s]
        return out

    def interpolate(self, first: np.ndarray, weights: np.ndarray, table: np.ndarray) -> np.ndarray:
        """``sum_a c_a(q_k) table_a`` at the data (e.g. ``table = H(g) I``: the visibility curve)."""
        out = weights[0] * np.take(table, first)
        for s in range(1, self.order):
            out += weights[s] * np.take(table, first + s)
        return out

    def normal_matrix(self, rho: np.ndarray) -> np.ndarray:
        """``sum_a rho_a H(g_a)^T H(g_a)`` (N, N), symmetric.

        Two symmetric rank-k updates (BLAS ``syrk``, half the work of a general product): one
        for the grid points where ``rho`` is positive, one subtracting those where the Lagrange
        weights made it negative.
        """
        from scipy.linalg.blas import dsyrk

        scale = np.sqrt(np.abs(rho))
        negative = rho < 0
        # rows scaled in C order, handed to BLAS transposed (Fortran order: no copy)
        A = np.multiply(self.H, scale[:, None], order="C")
        A[negative] = 0.0
        M = dsyrk(1.0, A.T, trans=0, lower=0)
        if negative.any():
            B = np.multiply(self.H[negative], scale[negative, None], order="C")
            M = dsyrk(-1.0, B.T, trans=0, beta=1.0, c=M, overwrite_c=1, lower=0)
        M += np.triu(M, 1).T  # syrk leaves the lower triangle at zero
        return M

    def project(self, rho: np.ndarray) -> np.ndarray:
        """``sum_a rho_a H(g_a)`` (N,)."""
        return rho @ self.H

    def max_error(self, prior: ProfilePrior, q: np.ndarray) -> float:
        """Largest ``|interpolated - exact|`` of ``H`` at ``q``, relative to ``max |H|``."""
        q = np.asarray(q, dtype=float)
        first, weights = self.stencil(q)
        approx = sum(weights[s][:, None] * self.H[first + s] for s in range(self.order))
        exact = prior.coefficients(q)
        return float(np.max(np.abs(approx - exact)) / np.max(np.abs(self.H)))
