"""Calibration harnesses and reference paths: run by tests and benchmarks, never imported by runtime code.

* :mod:`.sbc` — simulation-based calibration of the posterior (Talts et al. 2018);
* :mod:`.planted` — how often a planted planet is wrongly excluded by the limits.
"""

from .planted import PlantedExclusion, planted_exclusion_rate
from .sbc import CalibrationSetup, draw_truth, run_dataset, summarise

__all__ = [
    "CalibrationSetup",
    "PlantedExclusion",
    "draw_truth",
    "planted_exclusion_rate",
    "run_dataset",
    "summarise",
]
