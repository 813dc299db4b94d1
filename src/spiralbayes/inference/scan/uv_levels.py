"""Polar uv grids for the scan's power term ``sum_k w_k |ΔV_k|^2`` at every planet azimuth.

With the baselines in polar form ``(rho_k, theta_k)`` in the disc frame and ``G = |P_hat|^2`` the
perturbation's power spectrum for ``phi_p = 0``,

    power(phi_p) = cos^2 i sum_k w_k G(rho_k, theta_k - phi_p).

``G`` is computed exactly at the nodes of a polar uv grid (one type-3 NUFFT per template and
radius) and interpolated: with Lagrange polynomials of ``RHO_POINTS`` nodes in ``rho`` (spacing
``d_rho = 1 / (RHO_OVERSAMPLE 4 r_out)``, a third of the Nyquist step of ``G``, whose ``rho``
bandwidth is the perturbation's diameter ``2 r_out``) and exactly in ``theta`` (``G`` is
band-limited there: its angular harmonics stop where ``J_m(2 pi rho r_out)`` does, and
:func:`theta_count` samples enough azimuths to leave ``sum_{m >= m0} |J_m| <= THETA_TOLERANCE``).
The data enter only through the angular Fourier coefficients of their interpolation weights,
``W[j, m] = sum_k w_k L_j(rho_k) exp(i m theta_k)`` (one 1-D type-1 NUFFT per ring, computed once),
and all ``phi_p`` then come from one FFT (:func:`power_all_phi`). ``P`` is real, so ``G`` has period
pi in ``theta``: only its even harmonics enter, and only half the azimuths are computed.

Levels: a perturbation of radius ``r`` needs ``d_rho ∝ 1 / r`` and ``n_theta ∝ r``, so each radius
uses the smallest of a ladder of grids (``r_out`` halving from the largest radius down) that holds
it: small radii cost a quarter, a sixteenth, ... of the largest one's grid.

Accuracy: cubic Lagrange at 4x oversampling in single precision (``epsilon = 1e-5``)
erred by up to 1.8e-5 of the power, dominated by the cubic interpolation in ``rho``;
16 points at 3x oversampling in double precision gave <= 3e-8 in every case measured. The
interpolation error is not bounded a priori (it depends on how much of ``G``'s ``rho`` bandwidth the
perturbation uses), so the scan measures it against exact sums for its first template
(:func:`spiralbayes.inference.scan.accuracy.check_terms`) and adds it to its error estimate.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...quadrature import bessel_tail_limit
from ...units import ARCSEC, TWO_PI

__all__ = ["UVLevel", "build_level", "level_radii", "power_all_phi", "theta_count", "uv_weight_coefficients"]

RHO_OVERSAMPLE = 3.0
"""Radial uv nodes per Nyquist step of G (whose rho bandwidth is the perturbation's diameter)."""
RHO_POINTS = 16
"""Lagrange interpolation points in rho (4: cubic, the earlier default)."""
THETA_TOLERANCE = 1e-12
"""Angular Bessel tail left out of G's harmonics."""


@dataclass
class UVBand:
    """Rings ``start:stop`` of a level, sampled at ``n_theta`` azimuths over 2 pi.

    ``even`` holds the weights' coefficients ``W[j, 2 m']`` for ``m' = 0 .. n_theta // 4`` (what
    the power needs; ``G`` has period pi in theta).
    """

    start: int
    stop: int
    n_theta: int
    even: np.ndarray = field(repr=False)

    @property
    def size(self) -> int:
        return (self.stop - self.start) * (self.n_theta // 2)


@dataclass
class UVLevel:
    """A polar uv grid for perturbations within radius ``r_out`` and the data's weights on it.

    Rings ``rho_j = j d_rho`` (``j < n_rho``) come in bands of equal azimuth count: a ring needs
    only as many azimuths as ``G``'s angular bandwidth at its own ``rho``, so inner rings carry
    fewer nodes (about half the nodes of a grid sized for the longest baseline).

    Attributes
    ----------
    r_out : float
        Largest perturbation radius served [arcsec].
    d_rho : float
        Radial node spacing [lambda].
    n_rho : int
        Number of rings.
    bands : list of UVBand
    hat : ndarray or None
        ``W[j, m]`` for every ring and every ``m`` (FFT order), kept when the level is one band
        (``banded=False``), for code that works with the whole angular spectrum.
    """

    r_out: float
    d_rho: float
    n_rho: int
    bands: list = field(repr=False)
    points: int = RHO_POINTS
    hat: np.ndarray | None = field(default=None, repr=False)

    @property
    def n_theta(self) -> int:
        """The largest azimuth count (the outermost band's)."""
        return max(b.n_theta for b in self.bands)

    @property
    def reach(self) -> float:
        """The longest baseline [lambda] at which G is sampled."""
        return (self.n_rho - 1) * self.d_rho

    @property
    def size(self) -> int:
        """Number of uv nodes where G is computed (half the azimuths of each ring)."""
        return sum(b.size for b in self.bands)

    def nodes(self) -> np.ndarray:
        """``(rho_j cos theta_l, rho_j sin theta_l)`` for ``theta_l < pi`` [lambda], band after band,
        ring-major within a band."""
        parts = []
        for b in self.bands:
            rho = np.arange(b.start, b.stop) * self.d_rho
            theta = TWO_PI * np.arange(b.n_theta // 2) / b.n_theta
            parts.append(np.stack([np.outer(rho, np.cos(theta)).ravel(), np.outer(rho, np.sin(theta)).ravel()], -1))
        return np.concatenate(parts)


def level_radii(radii, multilevel: bool = True) -> list[float]:
    """``r_out`` of the ladder [arcsec]: the largest radius, then halving while a radius fits."""
    radii = np.asarray(radii, dtype=float)
    out = [float(radii.max())]
    while multilevel and radii.min() <= out[-1] / 2:
        out.append(out[-1] / 2)
    return out


def theta_count(rho_max: float, r_out: float, multiple: int, tolerance: float = THETA_TOLERANCE) -> int:
    """Azimuths over 2 pi for G at baselines up to ``rho_max`` [lambda] of a source within ``r_out``
    [arcsec]: ``P_hat``'s harmonics stop at ``m0`` (Bessel tail ``sum_{m >= m0} |J_m(2 pi rho_max
    r_out)|`` below ``tolerance``), G's at ``2 m0``, so ``n_theta >= 4 m0 + 2``; a multiple of
    ``multiple`` and of 2."""
    multiple = int(np.lcm(int(multiple), 2))
    z = TWO_PI * rho_max * r_out * ARCSEC
    n = multiple
    while n < 6 or z > bessel_tail_limit((n - 2) // 4, tolerance):
        n += multiple
    return n


def lagrange_weights(t: np.ndarray, points: int) -> np.ndarray:
    """Weights of the nodes ``-points/2 + 1 .. points/2`` at fractional offsets ``t`` in [0, 1),
    shape ``(points, t.size)`` (the node polynomial times barycentric weights; exact at the nodes)."""
    nodes = np.arange(-points // 2 + 1, points // 2 + 1, dtype=float)
    bary = np.array([1.0 / np.prod([a - b for b in nodes if b != a]) for a in nodes])
    diff = t[None, :] - nodes[:, None]
    hit = diff == 0.0
    diff[hit] = 1.0
    out = np.prod(diff, axis=0)[None, :] * (bary[:, None] / diff)
    columns = np.flatnonzero(hit.any(axis=0))
    out[:, columns] = hit[:, columns]
    return out


def _ring_sources(j: int, j0, lag, weights, theta, offsets):
    """Weights ``w_k L_j(rho_k)`` and angles of the baselines whose stencil touches ring ``j``
    (node ``-j`` folds onto ring ``j``: G is even)."""
    values, angles = [], []
    for node in {j, -j}:
        lo = np.searchsorted(j0, node - offsets[-1], side="left")
        hi = np.searchsorted(j0, node - offsets[0], side="right")
        if hi > lo:
            values.append(weights[lo:hi] * lag[node - j0[lo:hi] - offsets[0], np.arange(lo, hi)])
            angles.append(theta[lo:hi])
    if not values:
        return None, None
    return np.concatenate(values), np.concatenate(angles)


def uv_weight_coefficients(rho, theta, weights, d_rho: float, n_theta, points: int = RHO_POINTS,
                           nthreads: int = 1) -> list[np.ndarray]:
    """``W[j, m] = sum_k w_k L_j(rho_k) exp(i m theta_k)`` per ring ``j``, ``m`` in FFT order; ``rho`` sorted.

    ``L_j`` are the Lagrange weights of the radial nodes ``rho_j = j d_rho`` (``points`` nodes
    around each baseline). ``n_theta`` is one azimuth count for every ring, or a callable giving
    ring ``j``'s. One ring at a time (a 1-D type-1 NUFFT), so memory stays at O(N).
    """
    import ducc0

    f = rho / d_rho
    j0 = np.floor(f).astype(np.int64)
    lag = lagrange_weights(f - j0, points)  # (points, N)
    offsets = np.arange(-points // 2 + 1, points // 2 + 1)
    n_rho = int(j0[-1]) + points // 2 + 1
    count = n_theta if callable(n_theta) else (lambda j: int(n_theta))
    out = []
    for j in range(n_rho):
        n = count(j)
        values, angles = _ring_sources(j, j0, lag, weights, theta, offsets)
        if values is None:
            out.append(np.zeros(n, dtype=complex))
            continue
        out.append(ducc0.nufft.nu2u(points=values.astype(complex), coord=angles[:, None], out=np.empty(n, complex),
                                    forward=False, epsilon=1e-11, nthreads=nthreads, fft_order=True))
    return out


def build_level(rho_sorted, theta_sorted, weights_sorted, r_out: float, n_phi_p: int, *, points: int = RHO_POINTS,
                oversample: float = RHO_OVERSAMPLE, theta_tolerance: float = THETA_TOLERANCE, banded: bool = True,
                nthreads: int = 1) -> UVLevel:
    """The uv grid and the data's weight coefficients for perturbations within ``r_out`` [arcsec]."""
    d_rho = 1.0 / (oversample * 4 * r_out * ARCSEC)
    reach = float(rho_sorted[-1]) + (points // 2 + 1) * d_rho  # the last node a stencil touches
    n_rho = int(np.floor(rho_sorted[-1] / d_rho)) + points // 2 + 1
    if banded:
        counts = [theta_count(j * d_rho, r_out, n_phi_p, theta_tolerance) for j in range(n_rho)]
    else:
        counts = [theta_count(reach, r_out, n_phi_p, theta_tolerance)] * n_rho
    rows = uv_weight_coefficients(rho_sorted, theta_sorted, weights_sorted, d_rho, lambda j: counts[j], points,
                                  nthreads)
    bands, start = [], 0
    for j in range(1, n_rho + 1):
        if j == n_rho or counts[j] != counts[start]:
            n = counts[start]
            hat = np.array(rows[start:j])
            bands.append(UVBand(start, j, n, np.ascontiguousarray(hat[:, 0: 2 * (n // 4) + 1: 2])))
            start = j
    return UVLevel(float(r_out), float(d_rho), int(n_rho), bands, int(points),
                   None if banded else np.array(rows))


def power_all_phi(level: UVLevel, p_hat: np.ndarray, n_phi_p: int, other: np.ndarray | None = None) -> np.ndarray:
    """``sum_k w_k G(rho_k, theta_k - phi_p)`` at the scan's azimuths ``phi_p = 2 pi p / n_phi_p``.

    ``p_hat``: ``P_hat`` at :meth:`UVLevel.nodes`; with ``other`` (a second perturbation's
    ``P_hat`` on the same nodes) ``G = Re(P_hat conj(other))``, the cross power
    ``Re sum_k w_k ΔV_k conj(ΔV'_k)`` of two perturbations placed together (``G`` is linear in
    it, so the power of ``s P + a P'`` is ``s^2 G_PP + 2 s a G_PP' + a^2 G_P'P'``, exactly as
    the interpolation is linear in ``G``). Per band, with ``g_{j, m'}`` the coefficients of
    ``G(rho_j, .)`` at harmonic ``2 m'``, the power is ``sum_{m'} S_{m'} e^{-2 i m' phi}`` with
    ``S_{m'} = sum_j g_{j, m'} W[j, 2 m']`` and ``S_{-m'} = conj S_{m'}``: one inverse FFT, sampled at
    the scan's azimuths (period pi).
    """
    out = np.zeros(n_phi_p)
    offset = 0
    for band in level.bands:
        n_half = band.n_theta // 2
        p = p_hat[offset: offset + band.size]
        offset += band.size
        if other is None:
            g = (p.real ** 2 + p.imag ** 2).reshape(band.stop - band.start, n_half)
        else:
            q = other[offset - band.size: offset]
            g = (p.real * q.real + p.imag * q.imag).reshape(band.stop - band.start, n_half)
        S = np.einsum("jm,jm->m", np.fft.rfft(g, axis=1), band.even) / n_half
        power = np.fft.irfft(np.conj(S), n=n_half) * n_half
        out += power[(np.arange(n_phi_p) * (band.n_theta // n_phi_p)) % n_half]
    return out
