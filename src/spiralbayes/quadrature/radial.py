"""The radial part of the product rule: bases that interpolate the Fourier kernel ``e^{i k x}``
along a ray, with their error bounds (:mod:`spiralbayes.quadrature`)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from math import lgamma, log, sqrt

import numpy as np

from ..units import TWO_PI

__all__ = ["GaussPanels", "KERNEL_TOLERANCE", "SINC_HALF_WIDTH", "SINC_OVERSAMPLE", "SincGrid",
           "choose_radial_basis", "gauss_interpolation_bound", "sinc_interpolation_error"]

KERNEL_TOLERANCE = 1e-11
"""Target of the radial kernel interpolation's error bound (Gauss panels)."""
SINC_HALF_WIDTH = 16
"""Samples on each side of the windowed sinc."""
SINC_OVERSAMPLE = 2.0
"""Uniform radial nodes at this multiple of the Nyquist rate of the longest baseline's kernel."""


# --- radial bases -------------------------------------------------------------------------------------
def gauss_interpolation_bound(p: int, phase: float) -> float:
    """Bound on ``|e^{i k x} - (Lagrange interpolant at p Gauss-Legendre nodes)|`` on a panel with
    ``|k| * width <= phase``: ``sqrt(2) phase^p p! / (2p)!``.

    From the interpolation remainder ``f^(p)(xi) / p! * prod (x - x_i)``, ``|f^(p)| <= |k|^p`` for
    each of the real and imaginary parts, and the monic Legendre polynomial's maximum
    ``2^p (p!)^2 / (2p)!`` on [-1, 1].
    """
    if phase <= 0:
        return 0.0
    return sqrt(2.0) * np.exp(p * log(phase) + lgamma(p + 1) - lgamma(2 * p + 1))


def _gauss_panel_width(p: int, tolerance: float) -> float:
    """Largest phase width of a ``p``-node panel whose bound is ``tolerance``."""
    return float(np.exp((log(tolerance / sqrt(2.0)) - lgamma(p + 1) + lgamma(2 * p + 1)) / p))


def _legendre_nodes(p: int) -> np.ndarray:
    from scipy.special import roots_legendre

    return roots_legendre(p)[0]


def _lagrange_matrix(nodes: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Lagrange basis polynomials of ``nodes`` at ``t`` (barycentric form), shape ``(t.size, nodes.size)``."""
    diff = nodes[:, None] - nodes[None, :]
    np.fill_diagonal(diff, 1.0)
    bary = 1.0 / np.prod(diff, axis=1)
    d = t[:, None] - nodes[None, :]
    hit = d == 0
    d[hit] = 1.0
    terms = bary[None, :] / d
    L = terms / terms.sum(axis=1, keepdims=True)
    rows = np.flatnonzero(hit.any(axis=1))
    L[rows] = hit[rows].astype(float)
    return L


@dataclass(frozen=True)
class GaussPanels:
    """Lagrange polynomials on ``p`` Gauss-Legendre nodes per panel; panel edges ``edges`` (in x)."""

    edges: np.ndarray
    p: int

    @property
    def breakpoints(self) -> np.ndarray:
        return self.edges

    @property
    def fine_width(self) -> float:
        """Widest piece (in x) on which the fine rule integrates the basis accurately."""
        return float(np.min(np.diff(self.edges))) * 2.0 / self.p

    def nodes(self) -> np.ndarray:
        e = self.edges
        return (0.5 * (e[:-1, None] + e[1:, None]) + 0.5 * np.diff(e)[:, None] * _legendre_nodes(self.p)).ravel()

    def evaluate(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """First node index and the values ``(x.size, p)`` of the basis functions nonzero at ``x``."""
        e = self.edges
        panel = np.clip(np.searchsorted(e, x, side="right") - 1, 0, e.size - 2)
        values = np.empty((x.size, self.p))
        nodes = _legendre_nodes(self.p)
        for k in np.unique(panel):
            sel = panel == k
            values[sel] = _lagrange_matrix(nodes, (x[sel] - 0.5 * (e[k] + e[k + 1])) / (0.5 * (e[k + 1] - e[k])))
        return panel * self.p, values


@dataclass(frozen=True)
class SincGrid:
    """Kaiser-Bessel-windowed sinc on uniform nodes ``x_first + a step``, ``a < n``.

    Reproduces ``e^{i k x}`` for ``|k| <= pi / (oversample step)`` to
    :func:`sinc_interpolation_error` on ``[x_first + W step, x_first + (n - 1 - W) step]``.
    """

    x_first: float
    step: float
    n: int
    half_width: int = SINC_HALF_WIDTH
    oversample: float = SINC_OVERSAMPLE

    @property
    def breakpoints(self) -> np.ndarray:
        return np.array([])

    @property
    def fine_width(self) -> float:
        return self.step

    @property
    def beta(self) -> float:
        return _kaiser_beta(self.half_width, self.oversample)

    def nodes(self) -> np.ndarray:
        return self.x_first + self.step * np.arange(self.n)

    def evaluate(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        W = self.half_width
        f = (x - self.x_first) / self.step
        start = np.floor(f).astype(int) - W
        t = f[:, None] - (start[:, None] + np.arange(2 * W + 2)[None, :])
        return start, _windowed_sinc(t, W, self.beta)


def _kaiser_beta(half_width: int, oversample: float) -> float:
    return float(np.pi * half_width * (1.0 - 1.0 / oversample))


def _windowed_sinc(t: np.ndarray, half_width: int, beta: float) -> np.ndarray:
    from scipy.special import i0

    u = np.clip(1.0 - (t / half_width) ** 2, 0.0, None)
    return np.sinc(t) * np.where(np.abs(t) <= half_width, i0(beta * np.sqrt(u)) / i0(beta), 0.0)


@lru_cache(maxsize=8)
def sinc_interpolation_error(half_width: int = SINC_HALF_WIDTH, oversample: float = SINC_OVERSAMPLE) -> float:
    """Largest error of the windowed-sinc reconstruction of ``e^{i k x}`` over ``|k| <= kappa``.

    Poisson summation: sampling ``e^{i w n}`` (``w = k step``, ``|w| <= pi / oversample``) and
    interpolating with ``psi`` gives ``e^{i w t} sum_l psi_hat(w - 2 pi l) e^{-2 pi i l t}``, so the
    error is at most ``|psi_hat(w) - 1| + sum_{l != 0} |psi_hat(w - 2 pi l)|``. ``psi_hat`` is
    computed with 96-point Gauss-Legendre per unit of ``t`` (the integrand is smooth and
    compactly supported; the images ``|l| <= 6`` are summed, beyond which ``psi_hat`` is below
    1e-30) and the maximum taken over 120 values of ``w`` (it is smooth in ``w``).
    """
    from scipy.special import roots_legendre

    W = int(half_width)
    beta = _kaiser_beta(W, oversample)
    g, gw = roots_legendre(96)
    t = (np.arange(W)[:, None] + 0.5 + 0.5 * g[None, :]).ravel()
    wt = np.tile(0.5 * gw, W) * _windowed_sinc(t, W, beta)

    def psi_hat(w):
        return 2.0 * np.cos(np.outer(w, t)) @ wt

    w = np.linspace(0.0, np.pi / oversample, 120)
    err = np.abs(psi_hat(w) - 1.0)
    for ell in range(1, 7):
        err += np.abs(psi_hat(w - TWO_PI * ell)) + np.abs(psi_hat(w + TWO_PI * ell))
    return float(err.max())


def choose_radial_basis(x0: float, x1: float, kappa: float, radial: str, tolerance: float):
    """The basis with fewest nodes for phases up to ``kappa`` per unit x on ``[x0, x1]``, and its bound."""
    phase = max(kappa * (x1 - x0), 1e-300)
    options: list[tuple[GaussPanels | SincGrid, float]] = []
    if radial in ("auto", "gauss"):
        panels = [(max(1, int(np.ceil(phase / _gauss_panel_width(p, tolerance)))), p) for p in range(4, 65)]
        n_pan, p = min(panels, key=lambda c: c[0] * c[1])  # the fewest nodes; the lowest order among equals
        basis = GaussPanels(np.linspace(x0, x1, n_pan + 1), int(p))
        options.append((basis, gauss_interpolation_bound(p, phase / n_pan)))
    if radial in ("auto", "sinc"):
        step = np.pi / (SINC_OVERSAMPLE * max(kappa, 1e-300))
        W = SINC_HALF_WIDTH
        n = int(np.ceil((x1 - x0) / step)) + 2 * W + 2
        options.append((SincGrid(x0 - W * step, step, n), sinc_interpolation_error(W, SINC_OVERSAMPLE)))
    if not options:
        raise ValueError(f"radial = {radial!r}: use 'auto', 'gauss' or 'sinc'")
    return min(options, key=lambda o: o[0].nodes().size)
