"""How antenna gains are solved: :class:`CalibrationSettings`, the ``[calibration]`` section of the configuration."""

from __future__ import annotations

from dataclasses import dataclass

from ..exceptions import InputError
from ..settings import documented, is_finite_number, is_integer, option

__all__ = ["CalibrationSettings", "SOLVE_MODES"]

SOLVE_MODES = ("none", "phase", "amplitude+phase")
"""``[calibration] solve`` values: no solve, antenna phases, or antenna amplitudes and phases."""


@documented
@dataclass(frozen=True)
class CalibrationSettings:
    """Options of :func:`~spiralbayes.calibration.solve_gains` and :func:`~spiralbayes.calibration.selfcal`
    (TOML section ``[calibration]``).

    The default interval, 60 s, is one integration of time-averaged ALMA continuum data: residual
    atmospheric phases wander over minutes, and measured on the fiducial observation with 10 deg errors
    of 3-minute coherence, 60-s solutions leave 1.5 deg rms where 120 s leave 4.3 deg and 300 s 6.4 deg,
    while the fraction of a planted spiral's Δχ² that the solve absorbs is the same (2 %) for 60 to
    300 s: over a 10- to 30-minute track the baselines barely rotate, so a longer interval does not
    protect a spiral. What does is that the gains are antenna-based (N_ant - 1 phases against
    N_ant (N_ant - 1) / 2 baselines per integration), that image shifts are kept out of them
    (``keep_position``), and a candidate spiral in the model solved against (docs/calibration.md).
    """

    solve: str = option("none", "antenna gains to solve against the axisymmetric model before the scan: 'none', "
                                "'phase' or 'amplitude+phase' (needs data that record antennas and times: "
                                "Measurement Sets, spiralbayes HDF5 files)")
    interval_s: float = option(60.0, "solution interval [s]: one gain per antenna per interval (intervals restart "
                                      "after a gap in time longer than one interval)")
    min_snr: float = option(5.0, "visibilities whose model S/N abs(M) sqrt(w) is below this are not used in the solve")
    n_iterations: int = option(2, "self-calibration rounds: solve against the current frank fit, refit frank to the "
                                  "corrected data, repeat")
    refant: int | None = option(None, "reference antenna (index) whose phase is zero in every interval it is in; "
                                      "-1: the lowest-indexed antenna solved in each interval", toml=-1)
    keep_position: bool = option(True, "leave to the sky model the image shift that the solved phases imply on "
                                       "average over the observation (the disc's offset is the geometry's dRA, dDec; "
                                       "a spiral's centroid offset is not absorbed); shifts that vary between "
                                       "intervals stay in the gains")
    candidate_min_snr: float = option(1.0, "after a scan of the corrected data, solve again from the original data "
                                           "against the axisymmetric model plus that scan's best spiral (at its "
                                           "fitted amplitude), using visibilities down to this model S/N, and scan "
                                           "the data corrected so; 0: one solve only (spiralbayes scan)")
    amp_iterations: int = option(3, "amplitude iterations of each solve (1: the first-order estimate)", config=False)

    def __post_init__(self):
        if self.solve not in SOLVE_MODES:
            raise InputError(f"solve = {self.solve!r} must be one of {', '.join(repr(m) for m in SOLVE_MODES)}")
        if not (is_finite_number(self.interval_s) and self.interval_s > 0):
            raise InputError(f"interval_s = {self.interval_s!r} must be a positive time [s], e.g. 60")
        if not (is_finite_number(self.min_snr) and self.min_snr > 0):
            raise InputError(f"min_snr = {self.min_snr!r} must be a positive signal-to-noise ratio, e.g. 5")
        if not (is_finite_number(self.candidate_min_snr) and self.candidate_min_snr >= 0):
            raise InputError(f"candidate_min_snr = {self.candidate_min_snr!r} must be a signal-to-noise ratio >= 0 "
                             "(0: no second solve), e.g. 1")
        if not is_integer(self.n_iterations) or self.n_iterations < 1:
            raise InputError(f"n_iterations = {self.n_iterations!r} must be an integer >= 1")
        if self.refant is not None and (not is_integer(self.refant) or self.refant < 0):
            raise InputError(f"refant = {self.refant!r} must be an antenna index >= 0 (or -1 in a configuration "
                             "file: automatic)")
        if not is_integer(self.amp_iterations) or self.amp_iterations < 1:
            raise InputError(f"amp_iterations = {self.amp_iterations!r} must be an integer >= 1")

    @property
    def enabled(self) -> bool:
        """Whether any gains are solved."""
        return self.solve != "none"
