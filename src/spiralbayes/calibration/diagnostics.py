"""Residual antenna-based gain errors measured from the residuals of an axisymmetric fit.

Gain errors multiply a visibility row of ``antenna1 = q``, ``antenna2 = p`` (baseline
``position[p] - position[q]``, CASA's ``ANTENNA1 = p``) by ``g_p conj(g_q)``
(:mod:`spiralbayes.simulate.gains`); an axisymmetric model ``M`` fitted to the data leaves the
ratio ``r = V_obs / M = a_p a_q exp(i (phi_p - phi_q))`` plus noise. Where the visibilities record
their antennas and times, the phases and the amplitudes of ``r`` are solved per solution
interval by weighted linear least squares (:mod:`.leastsquares`, shared with :func:`.solve_gains`):

* phase: ``arg r_pq = phi_p - phi_q`` (antenna 0 of each interval as the reference), iterated
  on the wrapped residual so that tens of degrees are solved in full;
* amplitude: ``Re(r_pq exp(-i (phi_p - phi_q))) - 1 = alpha_p + alpha_q`` to first order in the
  fractional amplitude errors ``alpha`` (the real part of the phase-corrected ratio has unbiased
  noise, unlike ``|r|``).

The weight of a row is ``|M|^2 w``, the inverse variance of each of Re r and Im r (and of the
phase of ``r`` when ``|M| sqrt(w) >> 1``); rows with ``|M| sqrt(w) < min_snr`` are left out. As a phase
common to all antennas cannot be measured, each interval's solutions are centred on their mean
over the antennas; the mean square of the centred values, corrected for centring (``n / (n - 1)``)
and for the noise of the solutions (their least-squares covariance, subtracted), each weighted
down where its noise exceeds the warning level, estimates the rms gain error of
one antenna. A model error common to every antenna (an overall flux scale) is thereby not counted
as a gain error. A warning needs the estimate above its level and significant
(:data:`SIGNIFICANCE_WARN` standard deviations of its noise).

Without antennas only the residuals' reduced chi-squared ``sum w |V_obs - M|^2 / (2 N)`` can be
given (1 for pure thermal noise with correct weights), overall and in annuli of baseline length.

Units: phases [deg]; amplitudes fractional; times [s]; baselines [lambda].
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from ..exceptions import InputError
from ..visibilities import Visibilities
from .leastsquares import model_visibilities, solve_groups
from .settings import CalibrationSettings

__all__ = ["CalibrationDiagnostic", "diagnose_calibration", "PHASE_WARN_DEG", "AMP_WARN", "CHI2_WARN",
           "SIGNIFICANCE_WARN", "exceeds_warning"]

log = logging.getLogger(__name__)

PHASE_WARN_DEG = 5.0
"""Residual antenna phase rms [deg] above which a diagnostic warns."""

AMP_WARN = 0.03
"""Residual fractional antenna amplitude rms above which a diagnostic warns (on the fiducial planet-free
data, 4-5 % amplitude errors leave an m = 2 pattern significant against the disc, 2-3 % do not)."""

SIGNIFICANCE_WARN = 3.0
"""A scatter above its warning level warns only when measured at this many standard deviations of
its noise: where few baselines constrain the antennas the estimate scatters by several per cent."""

CHI2_WARN = 1.2
"""Reduced chi-squared of the residuals above which a diagnostic without antennas warns."""



def exceeds_warning(value: float | None, significance: float | None, level: float) -> bool:
    """Is a measured scatter above its warning ``level`` and significant (None: not measured)?"""
    return (value is not None and bool(value > level)
            and (significance is None or bool(significance > SIGNIFICANCE_WARN)))


_FIX = "self-calibrate before a spiral search, or set [calibration] solve"
_FIX_AMPLITUDE = ('self-calibrate the amplitudes too before a spiral search, or set [calibration] solve = '
                  '"amplitude+phase"')


@dataclass
class CalibrationDiagnostic:
    """What the residuals of an axisymmetric fit say about the calibration.

    Attributes
    ----------
    phase_rms_deg : float or None
        Estimated rms phase error of one antenna [deg] (None without antennas).
    amp_rms : float or None
        Estimated rms fractional amplitude error of one antenna (None without antennas).
    antenna_phase_rms_deg : dict
        Rms [deg] of each antenna's centred phase solutions (noise included), by antenna index.
    n_intervals : int
        Solution intervals solved.
    n_used : int
        Visibilities used in the solutions (S/N above ``min_snr``).
    reduced_chi2 : float
        ``sum w |V_obs - M|^2 / (2 N)`` over all visibilities.
    chi2_bins : dict
        ``q_low``, ``q_high`` [lambda] and ``reduced_chi2`` of equal-count annuli of baseline
        length (lists).
    warning : str or None
        What to do, when the residuals show non-thermal structure.
    phase_significance, amp_significance : float or None
        The noise-subtracted sum of squares of the centred solutions in units of its standard
        deviation without gain errors (about 0 ± 1 for gains that are right; None without antennas).
    """

    phase_rms_deg: float | None
    amp_rms: float | None
    antenna_phase_rms_deg: dict = field(default_factory=dict)
    n_intervals: int = 0
    n_used: int = 0
    reduced_chi2: float = float("nan")
    chi2_bins: dict = field(default_factory=dict)
    warning: str | None = None
    phase_significance: float | None = None
    amp_significance: float | None = None

    def summary(self) -> str:
        """One line: the measured phase and amplitude scatter (or the reduced chi-squared)."""
        chi2 = f"residual reduced chi2 {self.reduced_chi2:.3g}"
        if self.phase_rms_deg is None or self.amp_rms is None:
            text = f"calibration: no antennas recorded; {chi2}"
        else:
            text = (f"calibration: antenna phase rms {self.phase_rms_deg:.3g} deg, amplitude rms "
                    f"{100 * self.amp_rms:.3g} % ({self.n_intervals} intervals, {self.n_used} visibilities); {chi2}")
        return text + (f" -- {self.warning}" if self.warning else "")

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def diagnose_calibration(vis: Visibilities, model, *, interval_s: float | None = None,
                         min_snr: float = CalibrationSettings.min_snr,
                         n_bins: int = 10) -> CalibrationDiagnostic:
    """Measure residual antenna-based gain errors from the residuals ``V_obs - model``.

    Parameters
    ----------
    vis : Visibilities
        The data (used in the frank/galario convention).
    model : ndarray of complex, shape (N,), or object with ``visibilities(u, v)``
        The axisymmetric model's visibilities [Jy] at the data's baselines, or the model
        itself (e.g. an :class:`spiralbayes.axisymmetric.AxisymmetricModel`).
    interval_s : float, optional
        Solution interval [s]; default one interval per distinct time (one integration).
        Intervals start afresh after any gap in time longer than one interval.
        Data without times are solved as one interval. Antennas of an interval that share no
        baseline (e.g. two configurations) are solved as separate sets.
    min_snr : float
        Rows whose model S/N ``|M| sqrt(w)`` is below this are not used in the solutions.
    n_bins : int
        Number of equal-count annuli of baseline length for the reduced chi-squared.

    Returns
    -------
    CalibrationDiagnostic
    """
    vis = vis.standardised()
    M = model_visibilities(vis, model)
    if not (np.isfinite(min_snr) and min_snr > 0):
        raise InputError(f"min_snr must be a positive signal-to-noise ratio, got {min_snr!r}")
    if interval_s is not None and not (np.isfinite(interval_s) and interval_s > 0):
        raise InputError(f"interval_s must be a positive time [s], got {interval_s!r}")
    chi2, bins = _reduced_chi2(vis, M, n_bins)
    if not vis.has_antennas:
        warning = None
        if chi2 > CHI2_WARN:
            warning = (f"residuals of the axisymmetric fit have reduced chi2 {chi2:.3g} (no antennas recorded to "
                       f"attribute it): non-thermal structure or wrong weights; {_FIX}")
        return CalibrationDiagnostic(None, None, reduced_chi2=chi2, chi2_bins=bins, warning=warning)
    phase, amp, z_phase, z_amp, per_antenna, n_int, n_used = _solve_gains(vis, M, interval_s, min_snr)
    warnings = []
    phase_warns, amp_warns = exceeds_warning(phase, z_phase, PHASE_WARN_DEG), exceeds_warning(amp, z_amp, AMP_WARN)
    if phase_warns:
        warnings.append(f"residual antenna-based phase errors of ~{phase:.2g} deg rms")
    if amp_warns:
        warnings.append(f"residual antenna-based amplitude errors of ~{100 * amp:.2g} % rms")
    fix = _FIX_AMPLITUDE if amp_warns and not phase_warns else _FIX
    warning = f"{' and '.join(warnings)}: {fix}" if warnings else None
    result = CalibrationDiagnostic(phase, amp, per_antenna, n_int, n_used, chi2, bins, warning, z_phase, z_amp)
    log.info("%s", result.summary())
    return result


def _reduced_chi2(vis: Visibilities, M: np.ndarray, n_bins: int) -> tuple[float, dict]:
    if int(n_bins) < 1:
        raise InputError(f"n_bins must be a positive number of annuli, got {n_bins!r}")
    terms = vis.weights * np.abs(vis.V - M) ** 2 / 2.0
    q = vis.uv_distance
    order = np.argsort(q, kind="stable")
    chunks = [c for c in np.array_split(order, min(int(n_bins), vis.n)) if c.size]
    bins = {"q_low": [float(q[c].min()) for c in chunks], "q_high": [float(q[c].max()) for c in chunks],
            "reduced_chi2": [float(terms[c].mean()) for c in chunks]}
    return float(terms.mean()), bins


class _Scatter:
    """Weighted method-of-moments estimate of the rms of one antenna's gain error from centred solutions.

    Each centred solution ``c_i`` has ``E[c_i^2] = (1 - 1/n) s^2 + v_i`` (``v_i`` its noise variance);
    the estimate is ``sum w_i (c_i^2 - v_i) / sum w_i (1 - 1/n)`` with ``w_i = 1 / (v_i + s0^2)^2``, so
    that solutions much noisier than the level of interest ``s0`` (an antenna on one or two baselines,
    whose amplitude is barely constrained) do not swamp it. Its standard deviation without gain
    errors, ``sqrt(2 sum_ij w_i w_j N_ij^2) / sum w_i (1 - 1/n)`` (``N`` the centred covariance), makes
    the significance.
    """

    def __init__(self, s0: float):
        self.s0_sq, self.num, self.den, self.var = s0 ** 2, 0.0, 0.0, 0.0

    def add(self, c: np.ndarray, noise: np.ndarray) -> None:
        v = np.diag(noise)
        w = 1.0 / (v + self.s0_sq) ** 2
        self.num += float(np.sum(w * (c ** 2 - v)))
        self.den += float(np.sum(w)) * (1.0 - 1.0 / c.size)
        self.var += 2.0 * float(np.sum((w[:, None] * noise * w[None, :]) * noise))

    def rms(self) -> float:
        return float(np.sqrt(max(self.num, 0.0) / self.den)) if self.den > 0 else float("nan")

    def significance(self) -> float:
        return float(self.num / np.sqrt(self.var)) if self.var > 0 else float("nan")


def _solve_gains(vis: Visibilities, M: np.ndarray, interval_s, min_snr: float):
    groups, use = solve_groups(vis, M, interval_s, min_snr, amplitude=True, amp_iterations=1)
    phase, amp = _Scatter(np.radians(PHASE_WARN_DEG)), _Scatter(AMP_WARN)
    per_antenna: dict[int, list] = {}
    for g in groups:
        assert g.amp is not None and g.cov_amp is not None  # solved with amplitude=True
        n_ant = g.antennas.size
        centre = np.eye(n_ant) - 1.0 / n_ant
        c_phi = centre @ g.phase
        phase.add(c_phi, centre @ g.cov_phase @ centre)
        amp.add(centre @ (g.amp - 1.0), centre @ g.cov_amp @ centre)
        for a, value in zip(g.antennas, c_phi):
            per_antenna.setdefault(int(a), []).append(value)
    rms = {a: float(np.degrees(np.sqrt(np.mean(np.square(v))))) for a, v in sorted(per_antenna.items())}
    return (float(np.degrees(phase.rms())), amp.rms(), phase.significance(), amp.significance(), rms, len(groups),
            int(use.sum()))
