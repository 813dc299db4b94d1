"""Calibration checks on visibilities: how much antenna-based gain error the residuals show.

:func:`diagnose_calibration` takes the data and an axisymmetric model of them and measures the
residual per-antenna phase and amplitude scatter (where the data record their antennas and
times) and the reduced chi-squared of the residuals against the weights; the
:class:`CalibrationDiagnostic` it returns says whether to self-calibrate before a spiral search.
"""

from .diagnostics import CalibrationDiagnostic, diagnose_calibration

__all__ = ["CalibrationDiagnostic", "diagnose_calibration"]
