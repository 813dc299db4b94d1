"""The angular part of the product rule: the template's exact Fourier series in phi and the
Bessel tails that size the number of azimuths (:mod:`spiralbayes.quadrature`)."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

__all__ = ["PHI_TOLERANCE", "TemplateSpectrum", "angular_count", "bessel_tail", "bessel_tail_limit"]

PHI_TOLERANCE = 1e-12
"""Bound on the angular rule's error, relative to the L1 norm: ``4 sum_{m >= n_phi/2} |J_m(z_max)|``."""


# --- the template's exact angular series ----------------------------------------------------------
class TemplateSpectrum:
    """Exact Fourier coefficients in phi of each row of a template's periodic-linear interpolant.

    Parameters
    ----------
    template : SpiralTemplate
        Uniform azimuths ``phi_j = phi_0 + 2 pi j / n_t`` (any ``phi_0``), rows at ``template.x``.
    """

    def __init__(self, template):
        delta = np.asarray(template.delta, dtype=float)
        self.n_t = delta.shape[1]
        self.phi0 = float(np.asarray(template.phi, dtype=float)[0])
        self.x = np.asarray(template.x, dtype=float)
        self._dft = np.fft.rfft(delta, axis=1)  # m = 0 .. n_t / 2; other m by periodicity and symmetry
        self.abs_mean = np.mean(np.abs(delta), axis=1)  # >= (1 / 2 pi) int |row| dphi
        self._rows: dict[int, np.ndarray] = {}
        self._abs_means: dict[int, np.ndarray] = {}

    def coefficients(self, m_max: int) -> np.ndarray:
        """``c_m`` for ``m = 0 .. m_max`` (shape ``(n_x, m_max + 1)``); ``c_{-m} = conj(c_m)``."""
        m = np.arange(m_max + 1)
        k = m % self.n_t
        conj = k > self.n_t // 2
        k = np.where(conj, self.n_t - k, k)
        F = self._dft[:, k]
        F = np.where(conj[None, :], np.conj(F), F)
        window = np.sinc(m / self.n_t) ** 2 / self.n_t * np.exp(-1j * m * self.phi0)
        return F * window[None, :]

    def rows(self, n_phi: int) -> np.ndarray:
        """``delta~`` of every row at ``phi = 2 pi j / n_phi``, shape ``(n_x, n_phi)`` (cached).

        The band-limited series of the rows: modes ``|m| < n_phi / 2``, the Nyquist mode left out
        (it would multiply ``J_{n_phi/2}``, which the rule counts as error anyway).
        """
        if n_phi not in self._rows:
            c = self.coefficients(n_phi // 2) * n_phi
            if n_phi % 2 == 0:
                c[:, -1] = 0.0
            self._rows[n_phi] = np.fft.irfft(c, n=n_phi, axis=1)
        return self._rows[n_phi]

    def rows_abs_mean(self, n_phi: int) -> np.ndarray:
        """Mean ``|delta~|`` over the ``n_phi`` samples of each row (the L1 estimate of the series; cached)."""
        if n_phi not in self._abs_means:
            self._abs_means[n_phi] = np.mean(np.abs(self.rows(n_phi)), axis=1)
        return self._abs_means[n_phi]


# --- angular rule -----------------------------------------------------------------------------------
def bessel_tail(z: float, m0: int) -> float:
    """``sum_{m >= m0} |J_m(z)|`` (the angular rule's error per unit L1 norm is 4 times this)."""
    from scipy.special import jv

    m0 = max(int(m0), 0)
    m = np.arange(m0, max(m0, int(z)) + 60 + int(6 * max(z, 1.0) ** (1 / 3)))  # J_m(z) < 1e-30 beyond
    return float(np.sum(np.abs(jv(m, z))))


@lru_cache(maxsize=4096)
def bessel_tail_limit(m0: int, tolerance: float) -> float:
    """The largest ``z`` with ``sum_{m >= m0} |J_m(z)| <= tolerance`` (bisection; the tail grows with
    ``z`` below its turning point near ``m0``), cached: rule sizes for many radii cost one lookup each."""
    if bessel_tail(0.0, m0) > tolerance:
        return -1.0  # m0 = 0: J_0(0) = 1
    lo, hi = max(0.0, m0 - 12.0 * m0 ** (1 / 3) - 12.0), float(m0) + 1.0
    if bessel_tail(lo, m0) > tolerance:
        lo = 0.0
    while hi - lo > 1e-4 * hi:  # the bracket's left end always satisfies the tolerance
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if bessel_tail(mid, m0) <= tolerance else (lo, mid)
    return lo


def angular_count(z_max: float, multiple: int, tolerance: float = PHI_TOLERANCE) -> tuple[int, float]:
    """Smallest multiple ``n`` of ``multiple`` with ``4 sum_{m >= n/2} |J_m(z_max)| <= tolerance``.

    Returns ``n`` and that bound.
    """
    n = _angular_n(z_max, multiple, tolerance)
    return n, 4 * bessel_tail(z_max, n // 2)


def _angular_n(z_max: float, multiple: int, tolerance: float) -> int:
    n = int(multiple)
    while z_max > bessel_tail_limit(n // 2, tolerance / 4):
        n += int(multiple)
    return n
