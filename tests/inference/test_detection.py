"""The grid scan: exactness, injection-recovery, null and phase-centre-error cases, resume, Dask."""

import warnings

import numpy as np
import pytest

from spiralbayes.inference.detection import detect, one_sidedness
from spiralbayes.inference.scan import scan
from tests.helpers import DISTANCE, GEOMETRY, R_P_TRUE, SCAN_RP


def test_injected_planet_is_recovered(planet_scan):
    best = planet_scan.best(0)
    assert abs(best["r_p"] - R_P_TRUE) <= SCAN_RP[1] - SCAN_RP[0]
    assert np.degrees(abs(np.angle(np.exp(1j * best["phi_p"])))) <= 4.0
    assert planet_scan.delta_bic()[0] > 10
    assert planet_scan.best(1)["delta_chi2"] < 0.2 * best["delta_chi2"]  # left hand clearly lower
    verdict = detect(planet_scan)
    assert verdict.detected and verdict.template == "wake_m1_tau3_b10_h0.07_R"
    assert verdict.r_p_au == pytest.approx(50.0, abs=7)
    assert "detected" in verdict.summary()


def _observe_and_scan(small_bank, true_geometry, seed):
    from spiralbayes.axisymmetric import fit_axisymmetric
    from spiralbayes.simulate import DiscModel, simulate_observation

    vis = simulate_observation("fiducial", DiscModel(distance=DISTANCE, tau_ref=3.0), true_geometry, seed=seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        axisym = fit_axisymmetric(vis, GEOMETRY, progress=False)
    return scan(vis, axisym, small_bank, GEOMETRY, r_p=np.linspace(0.02, 0.5, 13), progress=False)


def test_planet_free_disc_gives_negative_delta_bic(small_bank):
    result = _observe_and_scan(small_bank, GEOMETRY, seed=2)
    assert np.all(result.delta_bic() < 0)
    assert not detect(result).detected


def test_phase_centre_error_gives_one_sided_false_fit_that_fails_handedness(small_bank):
    """Stevenson et al. (2024) App. A: a 10 mas phase-centre error fakes a one-sided spiral fit,
    but both hands fit alike, so test 2 rejects it."""
    result = _observe_and_scan(small_bank, GEOMETRY.replace(dRA=0.01), seed=3)
    verdict = detect(result)
    assert verdict.test1_passed  # a large, spurious improvement
    assert not verdict.test2_passed and not verdict.detected
    assert verdict.handedness_ratio > 0.5
    best = result.best()
    assert one_sidedness(result, best["template_index"]) > 0.5
