"""Residual antenna-based gain errors: smooth random complex gains per antenna.

Real ALMA data keep, after calibration, per-antenna phase errors of a few to tens of degrees
that wander over minutes, and amplitude errors of a few per cent. In CASA's convention a
visibility of ``ANTENNA1 = p``, ``ANTENNA2 = q`` (baseline ``uvw(p) - uvw(q)``) becomes
``V'_pq = g_p conj(g_q) V_pq``, with ``g = a exp(i phi)``. A row of
:class:`~spiralbayes.visibilities.Visibilities` has the opposite baseline,
``position[antenna2] - position[antenna1]`` (:mod:`spiralbayes.layout`), so it is the CASA row
``p = antenna2``, ``q = antenna1`` and is corrupted as ``g[antenna2] conj(g[antenna1]) V``; written
with :func:`spiralbayes.io.write_ms`, the corrupted data obey CASA's equation.

Each antenna's phase ``phi(t)`` and fractional amplitude error ``a(t) - 1`` is a stationary
Gaussian Ornstein-Uhlenbeck process: zero mean, the stated rms, and the autocorrelation
``exp(-|dt| / tau)``, so it falls to ``1/e`` at the coherence time ``tau``. Sampled at the
sorted distinct times of the data it is the exact AR(1) recursion
``x_{k+1} = rho x_k + sqrt(1 - rho^2) sigma eps_k``, ``rho = exp(-(t_{k+1} - t_k) / tau)``;
rows sharing a time share the gains, and times far apart (configurations observed on
different days) are independent.

Units: phases [deg] at the API, radians inside; amplitudes fractional; times [s].
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..exceptions import InputError

__all__ = ["GainErrors", "antenna_gain_series"]

_GAIN_STREAM = 0x6A17
"""Second word of the gains' seed: the noise of the same integer seed is a different stream."""


@dataclass(frozen=True)
class GainErrors:
    """Random antenna-based complex gains to corrupt simulated visibilities with.

    Parameters
    ----------
    phase_rms_deg : float
        Rms of each antenna's phase error [deg].
    amp_rms : float
        Rms of each antenna's fractional amplitude error (0.05 = 5 %); below 0.3 so that the
        amplitudes stay positive.
    coherence_s : float
        Coherence time of the phases [s]: their autocorrelation is ``1/e`` after this lag.
    amp_coherence_s : float, optional
        Coherence time of the amplitudes [s]; default ``coherence_s``.
    seed : int
        The same seed gives the same gains; their random stream differs from that of
        thermal noise drawn with the same integer seed (:func:`.observe`).
    """

    phase_rms_deg: float = 10.0
    amp_rms: float = 0.0
    coherence_s: float = 300.0
    amp_coherence_s: float | None = None
    seed: int = 0

    def __post_init__(self):
        if not (np.isfinite(self.phase_rms_deg) and self.phase_rms_deg >= 0):
            raise InputError(f"phase_rms_deg must be >= 0 [deg], got {self.phase_rms_deg!r}")
        if not (np.isfinite(self.amp_rms) and 0 <= self.amp_rms < 0.3):
            raise InputError(f"amp_rms must be a fraction in [0, 0.3) (0.05 = 5 %), got {self.amp_rms!r}")
        for name in ("coherence_s", "amp_coherence_s"):
            value = getattr(self, name)
            if value is not None and not (np.isfinite(value) and value > 0):
                raise InputError(f"{name} must be a positive time [s], got {value!r}")

    def gains(self, antenna1, antenna2, time) -> tuple[np.ndarray, np.ndarray]:
        """Complex gains ``(g[antenna1], g[antenna2])`` of the two antennas of every row.

        Parameters
        ----------
        antenna1, antenna2 : ndarray of int, shape (N,)
        time : ndarray, shape (N,)
            [s].
        """
        a1 = np.asarray(antenna1, dtype=np.int64).ravel()
        a2 = np.asarray(antenna2, dtype=np.int64).ravel()
        t = np.asarray(time, dtype=float).ravel()
        if not (a1.size == a2.size == t.size):
            raise InputError(f"antenna1, antenna2 and time differ in length: {a1.size}, {a2.size}, {t.size}")
        times, row_time = np.unique(t, return_inverse=True)
        g = antenna_gain_series(self, times, int(max(a1.max(), a2.max())) + 1)
        row_time = row_time.ravel()
        return g[row_time, a1], g[row_time, a2]

    def corrupt(self, V, antenna1, antenna2, time) -> np.ndarray:
        """``g[antenna2] conj(g[antenna1]) V`` for every row [Jy] (see the module docstring)."""
        g1, g2 = self.gains(antenna1, antenna2, time)
        return np.asarray(V, dtype=complex) * g2 * np.conj(g1)

    def to_dict(self) -> dict:
        return asdict(self)


def antenna_gain_series(errors: GainErrors, times, n_antennas: int) -> np.ndarray:
    """Complex gains ``(n_times, n_antennas)`` at the sorted distinct ``times`` [s]."""
    times = np.asarray(times, dtype=float)
    rng = np.random.default_rng((errors.seed, _GAIN_STREAM))
    # both processes are always drawn, so the phases of a seed do not depend on amp_rms
    phase = _ou_series(rng, times, n_antennas, np.radians(errors.phase_rms_deg), errors.coherence_s)
    amp_tau = errors.coherence_s if errors.amp_coherence_s is None else errors.amp_coherence_s
    amp = 1.0 + _ou_series(rng, times, n_antennas, errors.amp_rms, amp_tau)
    return amp * np.exp(1j * phase)


def _ou_series(rng, times: np.ndarray, n: int, sigma: float, tau: float) -> np.ndarray:
    eps = rng.standard_normal((times.size, n))
    rho = np.exp(-np.diff(times) / tau)
    out = np.empty_like(eps)
    out[0] = eps[0]
    for k, r in enumerate(rho, start=1):
        out[k] = r * out[k - 1] + np.sqrt(1.0 - r * r) * eps[k]
    return sigma * out
