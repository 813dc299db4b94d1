"""The accuracy warning names what dominates the largest error estimate (scan results built by hand,
so the split follows from the inputs)."""

import warnings

import numpy as np
import pytest

from spiralbayes.exceptions import AccuracyWarning
from spiralbayes.inference.scan.accuracy import _power_path_share, warn_if_inaccurate
from spiralbayes.inference.scan.engine import CHECK_SAFETY
from spiralbayes.inference.scan.run import ScanResult
from tests._support.helpers import DISTANCE, GEOMETRY

CHI2_AO, POWER = 1e4, 100.0


def result(check: dict, estimate: float) -> ScanResult:
    shape = (1, 3, 4)
    meta = [{"name": "wake_m1_tau3_b0_h0.07_R", "mass": 1.0, "tau0": 3.0, "beta": 0.0, "hand": "R", "h_p": 0.07}]
    cross_error = np.zeros(shape)
    cross_error[0, 1, 2] = estimate / 2  # one instance far outside the tolerance
    return ScanResult(meta, np.array([0.2, 0.3, 0.4]), np.arange(4) * np.pi / 2, np.zeros(shape),
                      np.full(shape, POWER), CHI2_AO, 36_000, GEOMETRY, DISTANCE, provenance={"power_check": check},
                      cross_error=cross_error, power_error=np.zeros(shape))


def message(res) -> str:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        warn_if_inaccurate(res)
    assert len(caught) == 1 and issubclass(caught[0].category, AccuracyWarning)
    return str(caught[0].message)


def test_the_power_paths_share_is_its_measured_discrepancy_times_the_safety_factor():
    check = {"cross": 1e-5, "power": 1e-4}
    by_hand = CHECK_SAFETY * (2 * 1e-5 * np.sqrt(CHI2_AO * POWER) + 1e-4 * POWER)  # 3 (0.02 + 0.01) = 0.09
    assert _power_path_share(result(check, 2 * by_hand), (0, 1, 2)) == pytest.approx(0.5, rel=1e-12)
    assert _power_path_share(result({}, 3.0), (0, 1, 2)) == 0.0


def test_a_bound_the_quadrature_dominates_does_not_send_the_user_to_the_direct_power_path():
    text = message(result({"cross": 1e-9, "power": 1e-9}, 3.0))
    assert "1 of 12 instances (largest 3;" in text
    assert "quadrature's bound" in text and "power_path='direct'" not in text


def test_a_discrepancy_of_the_power_path_sends_the_user_to_the_direct_path():
    text = message(result({"cross": 1e-3, "power": 1e-2}, 3.0))  # its part alone: 3 (2 + 1) = 9 > 3
    assert "power_path='direct' can help" in text and "quadrature's bound" not in text
