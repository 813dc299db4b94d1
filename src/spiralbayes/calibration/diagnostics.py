"""Residual antenna-based gain errors measured from the residuals of an axisymmetric fit.

Gain errors multiply a visibility row of ``antenna1 = q``, ``antenna2 = p`` (baseline
``position[p] - position[q]``, CASA's ``ANTENNA1 = p``) by ``g_p conj(g_q)``
(:mod:`spiralbayes.simulate.gains`); an axisymmetric model ``M`` fitted to the data leaves the
ratio ``r = V_obs / M = a_p a_q exp(i (phi_p - phi_q))`` plus noise. Where the visibilities record
their antennas and times, the phases and the log amplitudes of ``r`` are solved per solution
interval by weighted linear least squares:

* phase: ``arg r_pq = phi_p - phi_q`` (antenna 0 of each interval as the reference), iterated
  on the wrapped residual so that tens of degrees are solved in full;
* amplitude: ``Re(r_pq exp(-i (phi_p - phi_q))) - 1 = alpha_p + alpha_q`` to first order in the
  fractional amplitude errors ``alpha`` (the real part of the phase-corrected ratio has unbiased
  noise, unlike ``|r|``).

The weight of a row is ``|M|^2 w``, the inverse variance of each of Re r and Im r (and of the
phase of ``r`` when ``|M| sqrt(w) >> 1``); rows with ``|M| sqrt(w) < min_snr`` are left out. As a phase
common to all antennas cannot be measured, each interval's solutions are centred on their mean
over the antennas; the rms of the centred values, corrected for centring (``n / (n - 1)``) and
for the noise of the solutions (their least-squares covariance, subtracted in quadrature),
estimates the rms gain error of one antenna. A model error common to every antenna (an
overall flux scale) is thereby not counted as a gain error.

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

__all__ = ["CalibrationDiagnostic", "diagnose_calibration", "PHASE_WARN_DEG", "AMP_WARN", "CHI2_WARN"]

log = logging.getLogger(__name__)

PHASE_WARN_DEG = 5.0
"""Residual antenna phase rms [deg] above which a diagnostic warns."""

AMP_WARN = 0.05
"""Residual fractional antenna amplitude rms above which a diagnostic warns."""

CHI2_WARN = 1.2
"""Reduced chi-squared of the residuals above which a diagnostic without antennas warns."""

_FIX = "self-calibrate before a spiral search, or set [calibration] solve"


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
    """

    phase_rms_deg: float | None
    amp_rms: float | None
    antenna_phase_rms_deg: dict = field(default_factory=dict)
    n_intervals: int = 0
    n_used: int = 0
    reduced_chi2: float = float("nan")
    chi2_bins: dict = field(default_factory=dict)
    warning: str | None = None

    def summary(self) -> str:
        """One line: the measured phase and amplitude scatter (or the reduced chi-squared)."""
        chi2 = f"residual reduced chi2 {self.reduced_chi2:.3g}"
        if self.phase_rms_deg is None:
            text = f"calibration: no antennas recorded; {chi2}"
        else:
            text = (f"calibration: antenna phase rms {self.phase_rms_deg:.3g} deg, amplitude rms "
                    f"{100 * self.amp_rms:.3g} % ({self.n_intervals} intervals, {self.n_used} visibilities); {chi2}")
        return text + (f" -- {self.warning}" if self.warning else "")

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def diagnose_calibration(vis: Visibilities, model, *, interval_s: float | None = None, min_snr: float = 5.0,
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
    M = _model_visibilities(vis, model)
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
    phase, amp, per_antenna, n_int, n_used = _solve_gains(vis, M, interval_s, min_snr)
    warnings = []
    if phase > PHASE_WARN_DEG:
        warnings.append(f"residual antenna-based phase errors of ~{phase:.2g} deg rms")
    if amp > AMP_WARN:
        warnings.append(f"residual antenna-based amplitude errors of ~{100 * amp:.2g} % rms")
    warning = f"{' and '.join(warnings)}: {_FIX}" if warnings else None
    result = CalibrationDiagnostic(phase, amp, per_antenna, n_int, n_used, chi2, bins, warning)
    log.info("%s", result.summary())
    return result


def _model_visibilities(vis: Visibilities, model) -> np.ndarray:
    M = model.visibilities(vis.u, vis.v) if hasattr(model, "visibilities") else model
    M = np.asarray(M, dtype=complex).ravel()
    if M.shape != (vis.n,):
        raise InputError(f"model has {M.size} visibilities for {vis.n} data points: give the model at the data's "
                         "baselines (model.visibilities(vis.u, vis.v)) or the model object")
    return M


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


def _intervals(vis: Visibilities, interval_s: float | None) -> np.ndarray:
    if vis.time is None:
        return np.zeros(vis.n, dtype=np.int64)
    if interval_s is None:
        return np.unique(vis.time, return_inverse=True)[1].ravel()
    # intervals restart after each gap longer than an interval (a new block of the observation)
    times, row = np.unique(vis.time, return_inverse=True)
    block = np.concatenate([[0], np.cumsum(np.diff(times) > interval_s)])
    start = times[np.searchsorted(block, block)]  # first time of each time's block
    label = np.unique(np.column_stack([block, np.floor((times - start) / interval_s)]), axis=0,
                      return_inverse=True)[1].ravel()
    return label[row.ravel()]


def _solve_gains(vis: Visibilities, M: np.ndarray, interval_s, min_snr: float):
    snr = np.abs(M) * np.sqrt(vis.weights)
    use = snr >= min_snr
    if use.sum() < 3:
        raise InputError(f"only {int(use.sum())} visibilities have model S/N >= min_snr = {min_snr}: "
                         "lower min_snr or check that the model matches the data")
    ratio = vis.V[use] / M[use]
    wt = snr[use] ** 2
    a1, a2 = vis.antenna1[use], vis.antenna2[use]
    interval = _intervals(vis, interval_s)[use]
    sq_phase, sq_amp, n_values = 0.0, 0.0, 0
    per_antenna: dict[int, list] = {}
    n_int = 0
    for rows in _solution_groups(interval, a1, a2):
        ants, idx = np.unique(np.concatenate([a1[rows], a2[rows]]), return_inverse=True)
        n_ant = ants.size
        if n_ant < 3:
            continue
        q, p = idx[: rows.size], idx[rows.size:]  # p = antenna2 carries g, q = antenna1 conj(g)
        phi, cov_phi = _solve_phase(ratio[rows], wt[rows], p, q, n_ant)
        if phi is None:
            continue
        alpha, cov_alpha = _solve_amp(ratio[rows] * np.exp(-1j * (phi[p] - phi[q])), wt[rows], p, q, n_ant)
        if alpha is None:
            continue
        centre = np.eye(n_ant) - 1.0 / n_ant
        c_phi, c_alpha = centre @ phi, centre @ alpha
        # mean square of the centred solutions minus their noise, per antenna
        sq_phase += np.sum(c_phi ** 2) - np.trace(centre @ cov_phi @ centre)
        sq_amp += np.sum(c_alpha ** 2) - np.trace(centre @ cov_alpha @ centre)
        n_values += n_ant - 1  # centring removes one degree of freedom
        n_int += 1
        for a, value in zip(ants, c_phi):
            per_antenna.setdefault(int(a), []).append(value)
    if n_int == 0:
        raise InputError("no solution interval has three or more antennas with enough S/N: "
                         "lengthen interval_s or lower min_snr")
    phase = float(np.degrees(np.sqrt(max(sq_phase, 0.0) / n_values)))
    amp = float(np.sqrt(max(sq_amp, 0.0) / n_values))
    rms = {a: float(np.degrees(np.sqrt(np.mean(np.square(v))))) for a, v in sorted(per_antenna.items())}
    return phase, amp, rms, n_int, int(use.sum())


def _solution_groups(interval: np.ndarray, a1: np.ndarray, a2: np.ndarray):
    """Row indices of each interval's connected sets of antennas (each needs its own reference)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    order = np.argsort(interval, kind="stable")
    starts = np.flatnonzero(np.diff(interval[order])) + 1
    for rows in np.split(order, starts):
        ants, idx = np.unique(np.concatenate([a1[rows], a2[rows]]), return_inverse=True)
        graph = coo_matrix((np.ones(rows.size), (idx[: rows.size], idx[rows.size:])), shape=(ants.size,) * 2)
        n_comp, label = connected_components(graph, directed=False)
        if n_comp == 1:
            yield rows
            continue
        row_label = label[idx[: rows.size]]
        for c in range(n_comp):
            yield rows[row_label == c]


def _design(p, q, n_ant: int, sign: float) -> np.ndarray:
    A = np.zeros((p.size, n_ant))
    np.add.at(A, (np.arange(p.size), p), 1.0)
    np.add.at(A, (np.arange(p.size), q), sign)
    return A


MAX_CONDITION = 1e10
"""Normal matrices worse conditioned than this are singular: e.g. the amplitude equations
``alpha_p + alpha_q`` of a set of baselines whose antenna graph is bipartite (a tree, an even ring)
leave ``+x`` on one side and ``-x`` on the other undetermined, which sparse subsets of the data
(a few rows per integration) often are."""


def _weighted_solve(A, y, wt):
    """Least-squares solution and its covariance, or (None, None) when singular."""
    normal = A.T @ (wt[:, None] * A)
    if not np.linalg.cond(normal) < MAX_CONDITION:
        return None, None
    try:
        cov = np.linalg.inv(normal)
    except np.linalg.LinAlgError:
        return None, None
    return cov @ (A.T @ (wt * y)), cov


def _solve_phase(ratio, wt, p, q, n_ant: int, n_iter: int = 4):
    """Antenna phases [rad] (antenna 0 of the interval fixed at 0) and their covariance."""
    A = _design(p, q, n_ant, -1.0)[:, 1:]
    phi = np.zeros(n_ant - 1)
    cov = None
    for _ in range(n_iter):
        model = A @ phi
        resid = np.angle(ratio * np.exp(-1j * model))  # wrapped: solve the increment
        step, cov = _weighted_solve(A, resid, wt)
        if step is None:
            return None, None
        phi = phi + step
    full = np.zeros((n_ant, n_ant))
    full[1:, 1:] = cov
    return np.concatenate([[0.0], phi]), full


def _solve_amp(phased_ratio, wt, p, q, n_ant: int):
    """Fractional antenna amplitude errors and their covariance from the phase-corrected ratios."""
    return _weighted_solve(_design(p, q, n_ant, 1.0), phased_ratio.real - 1.0, wt)
