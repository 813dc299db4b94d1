"""The grid scan: exactness, injection-recovery, null and phase-centre-error cases, resume, Dask."""

import warnings

import numpy as np
import pytest

from spiralbayes.inference.detection.verdict import detect, one_sidedness
from spiralbayes.inference.scan.run import scan
from tests._support.helpers import DISTANCE, GEOMETRY, R_P_TRUE, SCAN_RP


def test_injected_planet_is_recovered(planet_scan):
    best = planet_scan.peak(0)
    assert abs(best.r_p - R_P_TRUE) <= SCAN_RP[1] - SCAN_RP[0]
    assert np.degrees(abs(np.angle(np.exp(1j * best.phi_p)))) <= 4.0
    assert planet_scan.delta_bic()[0] > 10
    assert planet_scan.peak(1).delta_chi2 < 0.2 * best.delta_chi2  # left hand clearly lower
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
    best = result.best
    assert one_sidedness(result, best.template_index) > 0.5


# --- test 3 and the handed candidate, on scans and fits built by hand --------------------------
import json  # noqa: E402

from spiralbayes.alternatives import DiscGrid  # noqa: E402
from spiralbayes.exceptions import InputError  # noqa: E402
from spiralbayes.inference.detection.alternatives import AlternativeFit, AlternativesResult  # noqa: E402
from spiralbayes.inference.detection.verdict import best_handed_candidate, peak_region_fraction  # noqa: E402
from spiralbayes.inference.scan.run import ScanResult  # noqa: E402

N_DATA = 36_000
SIX_LN_N = 6 * np.log(N_DATA)


def fake_scan(right: np.ndarray, left: np.ndarray) -> ScanResult:
    """A scan of one R/L template pair whose Δχ² maps are ``right`` and ``left`` (power 0)."""
    templates = [{"name": f"wake_m1_tau3_b10_{h}", "mass": 1.0, "tau0": 3.0, "beta": 10.0, "hand": h} for h in "RL"]
    cross = np.stack([right, left]) / 2
    n_r, n_phi = right.shape
    return ScanResult(templates, np.linspace(0.02, 0.5, n_r), 2 * np.pi * np.arange(n_phi) / n_phi, cross,
                      np.zeros_like(cross), 1e5, N_DATA, GEOMETRY, DISTANCE)


def compact_peak(shape, i, j, value):
    out = np.zeros(shape)
    out[i, j] = value
    return out


def fake_alternatives(**dchi2) -> AlternativesResult:
    fits = {name: AlternativeFit(name, name.replace("_", " "), 4 if name != "arc" else 5, value, [0.0] * 4, {})
            for name, value in dchi2.items()}
    return AlternativesResult(fits, N_DATA, 1e5, GEOMETRY, DiscGrid(1.0, 4, 8))


def test_test3_prefers_the_spiral_only_by_more_than_the_threshold():
    shape = (13, 90)
    result = fake_scan(compact_peak(shape, 6, 10, 500.0), compact_peak(shape, 6, 80, 50.0))
    spiral_bic = 500.0 - SIX_LN_N
    cases = {"clear": (300.0, True), "close": (491.0 - np.log(N_DATA), False), "worse": (900.0, False)}
    for label, (alt_dchi2, expected) in cases.items():
        verdict = detect(result, alternatives=fake_alternatives(arc=alt_dchi2, geometry=10.0))
        alt_bic = alt_dchi2 - 5 * np.log(N_DATA)
        assert verdict.best_alternative == "arc", label
        assert verdict.alternative_delta_bic == pytest.approx(alt_bic)
        assert verdict.delta_bic_vs_alternative == pytest.approx(spiral_bic - alt_bic)
        assert verdict.test1_passed and verdict.test2_passed
        assert verdict.test3_passed is expected and verdict.detected is expected, label
        text = verdict.summary()
        assert "Test 3" in text and "arc" in text
        assert ("is detected" in text) is expected
        if label == "close":
            assert verdict.delta_bic_vs_alternative == pytest.approx(9.0)
            assert "not clearly preferred over the arc model" in text
    assert "explains the data better" in verdict.summary()
    stored = json.loads(json.dumps(verdict.to_dict()))["alternatives"]
    assert stored["arc"]["delta_chi2"] == 900.0
    assert stored["geometry"]["spiral_delta_bic_minus_this"] == pytest.approx(spiral_bic - (10.0 - 4 * np.log(N_DATA)))


def test_without_alternatives_test3_is_not_run_and_other_data_are_refused():
    shape = (13, 90)
    result = fake_scan(compact_peak(shape, 6, 10, 500.0), compact_peak(shape, 6, 80, 50.0))
    verdict = detect(result)
    assert verdict.test3_passed is None and verdict.detected
    assert "Test 3 (competing asymmetry models, sb.fit_alternatives) was not run" in verdict.summary()
    other = fake_alternatives(arc=10.0)
    other.n_data = N_DATA + 1
    with pytest.raises(InputError, match="other data"):
        detect(result, alternatives=other)


def test_geometry_alternative_points_to_the_refit():
    shape = (13, 90)
    result = fake_scan(compact_peak(shape, 6, 10, 500.0), compact_peak(shape, 6, 80, 50.0))
    verdict = detect(result, alternatives=fake_alternatives(geometry=5000.0, arc=100.0))
    assert verdict.best_alternative == "geometry" and not verdict.detected
    assert "sb.rescan_at_fitted_geometry" in verdict.summary()


def test_candidate_behind_an_unhanded_false_peak_is_reported():
    """A broad peak both hands share (fails test 2) hides a weaker compact, handed one."""
    shape = (13, 90)
    r_i, phi_j = np.meshgrid(np.arange(13), np.arange(90), indexing="ij")
    broad = 900.0 * np.exp(-0.5 * ((r_i - 3) / 1.0) ** 2 - 0.5 * ((phi_j - 45) / 6.0) ** 2)
    right = broad + compact_peak(shape, 9, 5, 400.0)
    left = broad + compact_peak(shape, 9, 60, 60.0)
    verdict = detect(fake_scan(right, left))
    assert not verdict.test2_passed and verdict.r_p == pytest.approx(0.02 + 3 * 0.04)
    c = verdict.candidate
    assert c["template"] == "wake_m1_tau3_b10_R"
    assert c["r_p"] == pytest.approx(0.02 + 9 * 0.04) and c["phi_p_deg"] == pytest.approx(20.0)
    assert c["delta_chi2"] == pytest.approx(400.0) and c["delta_bic"] == pytest.approx(400.0 - SIX_LN_N)
    assert c["handedness_ratio"] == pytest.approx(60.0 / 400.0)
    assert "best handed, compact candidate" in verdict.summary() and "sb.sample_posterior" in verdict.summary()
    # a handed global peak needs no candidate
    assert detect(fake_scan(right * (r_i > 6), left * (r_i > 6))).candidate is None


def test_peak_region_fraction_is_the_connected_area_above_half():
    values = np.zeros((5, 8))
    values[2, 7] = values[2, 0] = values[3, 0] = 10.0  # connected across phi = 0
    values[0, 3] = 9.0  # above half but not connected
    r_p = np.arange(1.0, 6.0)
    expected = (3 + 3 + 4) / (r_p.sum() * 8)
    assert peak_region_fraction(values, r_p, 2, 0) == pytest.approx(expected)
    assert best_handed_candidate(fake_scan(values, np.zeros_like(values))) is not None
    assert best_handed_candidate(fake_scan(values, np.zeros_like(values)), min_delta_bic=10.0) is None  # 10 < 6 ln N
