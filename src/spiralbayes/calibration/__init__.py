"""Antenna-based gain errors: measured from the residuals of an axisymmetric fit, and solved for.

:func:`diagnose_calibration` takes the data and an axisymmetric model of them and measures the
residual per-antenna phase and amplitude scatter (where the data record their antennas and
times) and the reduced chi-squared of the residuals against the weights; the
:class:`CalibrationDiagnostic` it returns says whether to self-calibrate before a spiral search.
:func:`solve_gains` solves per-interval antenna gains against a model (:class:`GainSolution`, which
divides them out of the data), and :func:`selfcal` alternates it with the frank fit. Both share one
least-squares implementation (:mod:`.leastsquares`); :class:`CalibrationSettings` is the
``[calibration]`` section of the configuration.
"""

from .diagnostics import CalibrationDiagnostic, diagnose_calibration
from .settings import SOLVE_MODES, CalibrationSettings
from .selfcal import SelfCalibration, selfcal
from .solve import GainSolution, solve_gains

__all__ = ["CalibrationDiagnostic", "CalibrationSettings", "GainSolution", "SOLVE_MODES", "SelfCalibration",
           "diagnose_calibration", "selfcal", "solve_gains"]
