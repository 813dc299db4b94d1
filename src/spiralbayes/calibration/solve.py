"""Antenna-based complex gains solved against a model of the sky: :func:`solve_gains` and :class:`GainSolution`.

In the package's convention (:mod:`spiralbayes.simulate.gains`) a row of
:class:`~spiralbayes.visibilities.Visibilities` is observed as ``V = g[antenna2] conj(g[antenna1]) V_sky``,
which is CASA's ``V_pq = g_p conj(g_q) V_sky`` with ``p = ANTENNA1`` once written by
:func:`spiralbayes.io.write_ms`; the gains solved here are therefore the corrupting gains of CASA's
gain tables (``gaincal``), and :meth:`GainSolution.apply` divides them out as ``applycal`` does:
``V / (g[antenna2] conj(g[antenna1]))`` with the weights multiplied by ``|g[antenna1] g[antenna2]|^2``.

The solve is weighted linear least squares per interval (:mod:`.leastsquares`), iterated to convergence
of the phases (and amplitudes), then Gauss-Newton steps on the complex residual: the maximum-likelihood
gains of ``sum w |V - g_p conj(g_q) M|^2``, as CASA's gaincal finds them. A phase common to every
antenna of an interval cannot be measured: the phase of the reference antenna (``refant``, else the
lowest-indexed antenna solved in the interval) is set to zero.

With ``keep_position`` (the default) the image shift that the phases imply on average over the
observation (phases linear in the antennas' uv positions) is removed from them: a shift constant in time
is the sky's (the geometry's ``dRA``, ``dDec``), and it is the part of an asymmetric structure such as a
spiral (its centroid offset) that antenna phases absorb most readily; a calibration error of that form
stays in the data as an offset of the disc, which the geometry alternative of test 3 and its refit
describe. Antennas without a solution in an interval (all their baselines below ``min_snr``, or
absent) have ``NaN`` gains there and their rows are left uncorrected by :meth:`GainSolution.apply`
(weak rows carry little of the model and little of its error).

Units: phases [deg]; amplitudes fractional (1 = no error); times [s].
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..exceptions import InputError
from ..results import ResultMixin
from ..settings import with_overrides
from ..visibilities import Visibilities
from .leastsquares import interval_labels, model_visibilities, solve_groups
from .settings import CalibrationSettings

__all__ = ["GainSolution", "solve_gains"]

log = logging.getLogger(__name__)

SOLVING_MODES = ("phase", "amplitude+phase")
ML_ITERATIONS = 4
"""Gauss-Newton phase steps on the complex residual after the wrapped-angle ones (:func:`.solve_groups`):
the solution is then the maximum-likelihood one, as CASA's gaincal finds."""


@dataclass(repr=False)
class GainSolution(ResultMixin):
    """Antenna gains per solution interval, and how to remove them from the data.

    Attributes
    ----------
    mode : str
        ``"phase"`` (amplitudes fixed at 1) or ``"amplitude+phase"``.
    interval_s : float
        Solution interval [s] (data without times are one interval).
    time : ndarray, shape (n_interval,)
        Mean time of each interval's rows [s] (0 without times).
    time_range : ndarray, shape (n_interval, 2)
        First and last time of each interval's rows [s]; :meth:`apply` corrects a row whose time lies in it.
    antennas : ndarray of int, shape (n_antenna,)
        Antenna indices (the columns of ``gains``).
    gains : ndarray of complex, shape (n_interval, n_antenna)
        The corrupting gain ``g`` of each antenna (``V = g[antenna2] conj(g[antenna1]) V_sky``), phase zero
        for the reference antenna; NaN where not solved.
    reference : ndarray of int, shape (n_interval,)
        The reference antenna of each interval (-1: none solved).
    phase_sigma_deg : ndarray, shape (n_interval, n_antenna)
        Noise of each antenna's phase relative to the mean over the interval's antennas [deg] (the
        least-squares covariance); NaN where not solved.
    amp_sigma : ndarray, shape (n_interval, n_antenna)
        Noise of each fractional amplitude (the least-squares covariance); NaN where not solved or in
        ``"phase"`` mode.
    antenna_phase_rms_deg : ndarray, shape (n_antenna,)
        Rms over the intervals of each antenna's phase relative to the interval's antenna mean [deg].
    antenna_amp_rms : ndarray, shape (n_antenna,)
        Rms over the intervals of each antenna's ``|g| - 1``.
    phase_rms_deg, amp_rms : float
        The same over every antenna and interval.
    n_used : int
        Visibilities used in the solve (model S/N at least ``min_snr``).
    min_snr : float
    provenance : dict
        What the solution was solved from (the pipeline records the data's hash and the settings).
    """

    KIND = "gain_solution"
    WHAT = "gain solution"

    mode: str
    interval_s: float
    time: np.ndarray
    time_range: np.ndarray
    antennas: np.ndarray
    gains: np.ndarray
    reference: np.ndarray
    phase_sigma_deg: np.ndarray
    amp_sigma: np.ndarray
    antenna_phase_rms_deg: np.ndarray
    antenna_amp_rms: np.ndarray
    phase_rms_deg: float
    amp_rms: float
    n_used: int
    min_snr: float
    provenance: dict = field(default_factory=dict)

    @property
    def n_intervals(self) -> int:
        return int(self.time.size)

    @property
    def phases_deg(self) -> np.ndarray:
        """Antenna phases [deg] relative to each interval's reference antenna (NaN where not solved)."""
        return np.degrees(np.angle(self.gains))

    def row_gains(self, vis: Visibilities) -> tuple[np.ndarray, np.ndarray]:
        """``(g[antenna1], g[antenna2])`` of every row of ``vis`` (1 where no solution covers the row)."""
        if not vis.has_antennas:
            raise InputError("these visibilities record no antennas: a gain solution cannot be applied to them")
        assert vis.antenna1 is not None and vis.antenna2 is not None
        column = np.full(int(max(self.antennas.max(initial=0), vis.antenna1.max(), vis.antenna2.max())) + 1, -1)
        column[self.antennas] = np.arange(self.antennas.size)
        t = np.zeros(vis.n) if vis.time is None else np.asarray(vis.time, float)
        order = np.argsort(self.time_range[:, 0])
        k = np.searchsorted(self.time_range[order, 0], t, side="right") - 1
        inside = k >= 0
        k = order[np.clip(k, 0, None)]
        inside &= t <= self.time_range[k, 1]
        out = []
        for ant in (vis.antenna1, vis.antenna2):
            col = column[ant]
            g = np.ones(vis.n, dtype=complex)
            ok = inside & (col >= 0)
            g[ok] = self.gains[k[ok], col[ok]]
            g[~np.isfinite(g)] = 1.0
            out.append(g)
        return out[0], out[1]

    def apply(self, vis: Visibilities) -> Visibilities:
        """The data with the gains divided out: ``V / (g[antenna2] conj(g[antenna1]))`` and weights times
        ``|g[antenna1] g[antenna2]|^2`` (CASA's ``applycal``); rows without a solution are unchanged."""
        vis = vis.standardised()
        g1, g2 = self.row_gains(vis)
        corrected = vis.with_V(vis.V / (g2 * np.conj(g1)), f"antenna gains divided out ({self.describe()})")
        return corrected.with_weights(vis.weights * np.abs(g1 * g2) ** 2, f"scaled by |g1 g2|^2 ({self.mode} solve)")

    def describe(self) -> str:
        """``phase, 60 s intervals, 9.8 deg rms`` (and the amplitude rms when solved)."""
        interval = f"{self.interval_s:g} s intervals"
        amp = f", amplitude {100 * self.amp_rms:.2g} % rms" if self.mode != "phase" else ""
        return f"{self.mode}, {interval}, {self.phase_rms_deg:.2g} deg rms{amp}"

    def note(self) -> str:
        """The sentence a verdict or limits summary carries: ``antenna gains solved (...)``, and the spiral
        that was in the model solved against, if any."""
        c = (self.provenance or {}).get("candidate")
        spiral = "" if not c else (f"; against the disc plus the scan's best spiral, {c['template']} at r_p = "
                                   f"{c['r_p_arcsec']:.3g} arcsec, phi_p = {c['phi_p_deg']:.0f} deg, from "
                                   f"visibilities of model S/N >= {self.min_snr:g}")
        return f"antenna gains solved ({self.describe()}{spiral})"

    def summary(self) -> str:
        solved = np.isfinite(self.gains)
        return (f"Antenna gains solved ({self.describe()}): {self.n_intervals} intervals, {self.antennas.size} "
                f"antennas, {int(solved.sum())} solutions from {self.n_used} visibilities (model S/N >= "
                f"{self.min_snr:g}); median phase noise {np.nanmedian(self.phase_sigma_deg):.2g} deg.")


def solve_gains(vis: Visibilities, model, *, settings: CalibrationSettings | None = None, mode: str | None = None,
                **overrides) -> GainSolution:
    """Solve antenna-based complex gains per interval against a model of the data.

    Parameters
    ----------
    vis : Visibilities
        Data recording ``antenna1``, ``antenna2`` (and ``time``; without it one interval).
    model : ndarray of complex, shape (N,), or object with ``visibilities(u, v)``
        The model [Jy] at the data's baselines, e.g. an axisymmetric fit, or the axisymmetric fit plus a
        candidate spiral (so that the solve does not absorb it).
    settings : CalibrationSettings, optional
        ``interval_s``, ``min_snr``, ``refant``, ``amp_iterations``.
    mode : {"phase", "amplitude+phase"}, optional
        Default ``settings.solve``, or ``"phase"`` when that is ``"none"``.
    **overrides
        Fields of :class:`CalibrationSettings` (e.g. ``interval_s=60``).

    Returns
    -------
    GainSolution

    Raises
    ------
    InputError
        The data record no antennas, the mode is unknown, or no interval can be solved.
    """
    s = with_overrides(settings, CalibrationSettings, overrides, "solve_gains")
    mode = mode or (s.solve if s.enabled else "phase")
    if mode not in SOLVING_MODES:
        raise InputError(f"mode = {mode!r} must be 'phase' or 'amplitude+phase'")
    if not vis.has_antennas:
        raise InputError("[calibration] solve needs visibilities that record their antennas (ANTENNA1/ANTENNA2 of a "
                         "Measurement Set, a spiralbayes HDF5 file); these do not: set [calibration] solve = 'none' "
                         "and self-calibrate with CASA")
    vis = vis.standardised()
    M = model_visibilities(vis, model)
    groups, use = solve_groups(vis, M, s.interval_s, s.min_snr, amplitude=mode != "phase",
                               amp_iterations=s.amp_iterations, ml_iterations=ML_ITERATIONS,
                               keep_position=s.keep_position)
    antennas = np.unique(np.concatenate([vis.antenna1, vis.antenna2]))
    labels = interval_labels(vis.time, s.interval_s, vis.n)
    solved_labels = np.unique([g.interval for g in groups])
    row_of = {int(lab): i for i, lab in enumerate(solved_labels)}
    n_int, n_ant = solved_labels.size, antennas.size
    t = np.zeros(vis.n) if vis.time is None else np.asarray(vis.time, float)
    time = np.array([t[labels == lab].mean() for lab in solved_labels])
    time_range = np.array([[t[labels == lab].min(), t[labels == lab].max()] for lab in solved_labels])
    phase = np.full((n_int, n_ant), np.nan)
    amp = np.full((n_int, n_ant), np.nan)
    sigma = np.full((n_int, n_ant), np.nan)
    amp_sigma = np.full((n_int, n_ant), np.nan)
    centred = np.full((n_int, n_ant), np.nan)
    reference = np.full(n_int, -1, dtype=np.int64)
    for g in groups:
        i, cols = row_of[g.interval], np.searchsorted(antennas, g.antennas)
        n = g.antennas.size
        centre = np.eye(n) - 1.0 / n
        ref = int(np.flatnonzero(g.antennas == s.refant)[0]) if s.refant in g.antennas else 0
        phase[i, cols] = g.phase - g.phase[ref]
        amp[i, cols] = 1.0 if g.amp is None else g.amp
        sigma[i, cols] = np.sqrt(np.clip(np.diag(centre @ g.cov_phase @ centre), 0.0, None))
        centred[i, cols] = centre @ g.phase
        if g.cov_amp is not None:
            amp_sigma[i, cols] = np.sqrt(np.clip(np.diag(g.cov_amp), 0.0, None))
        if reference[i] < 0 or g.antennas[ref] == s.refant:
            reference[i] = g.antennas[ref]
    gains = amp * np.exp(1j * phase)
    with warnings.catch_warnings():  # antennas never solved: NaN, not a warning
        warnings.simplefilter("ignore", RuntimeWarning)
        ant_phase = np.degrees(np.sqrt(np.nanmean(centred ** 2, axis=0)))
        ant_amp = np.sqrt(np.nanmean((amp - 1.0) ** 2, axis=0))
    solution = GainSolution(
        mode=mode, interval_s=float(s.interval_s), time=time, time_range=time_range, antennas=antennas, gains=gains,
        reference=reference, phase_sigma_deg=np.degrees(sigma), amp_sigma=amp_sigma, antenna_phase_rms_deg=ant_phase,
        antenna_amp_rms=ant_amp, phase_rms_deg=float(np.degrees(np.sqrt(np.nanmean(centred ** 2)))),
        amp_rms=float(np.sqrt(np.nanmean((amp - 1.0) ** 2))), n_used=int(use.sum()), min_snr=float(s.min_snr))
    log.info("%s", solution.summary())
    return solution
