"""The candidate outcome (inference.detection.candidate): which verdicts name a compact source, where, with
what flux and explanations; the flux against the arc alternative's own field."""

from dataclasses import replace

import numpy as np
import pytest

from spiralbayes.alternatives import DiscGrid
from spiralbayes.alternatives.fields import FIELD_MODELS, ProfileContext
from spiralbayes.axisymmetric import AxisymmetricModel
from spiralbayes.geometry import DiscGeometry
from spiralbayes.inference.detection import DetectionSettings, detect
from spiralbayes.inference.detection.candidate import arc_excess_flux, compact_source, deeper_time_factor
from spiralbayes.units import ARCSEC
from tests.inference.detection.test_mass_range import scan_of

ARC = {"label": "arc/vortex", "delta_bic": 40.0,
       "params": {"contrast": 0.3, "r_c": 0.36, "phi_c_deg": 42.0, "sigma_r": 0.015, "sigma_phi_deg": 12.0}}
RING = {"label": "eccentric ring", "delta_bic": 20.0, "params": {"e": 0.02, "omega_deg": 10.0, "r_c": 0.3,
                                                                 "sigma_r": 0.05}}


def _profile(r):
    r = np.asarray(r, dtype=float)
    return 3e10 * np.exp(-r / 0.3) * (r < 1.0)


@pytest.fixture(scope="module")
def model():
    return AxisymmetricModel.from_profile(_profile, DiscGeometry(30.0, 60.0), N=120, Rmax=1.2)


def _nested(stat, alternative="arc", survives=False):
    return [{"alternative": alternative, "label": {"arc": "arc/vortex", "geometry": "geometry error"}[alternative],
             "delta_bic": stat, "delta_bic_joint": stat, "delta_bic_spiral_alone": stat - 5,
             "hypothesis": "spiral + peak",
             "n_spiral_params": 7, "peak_flux": 2e-4, "survives": survives, "alternative_delta_bic": 40.0,
             "alternative_delta_bic_given_spiral": 5.0}]


def _failed_test3(stat=5.0, **fields):
    v = detect(scan_of())
    return replace(v, detected=False, test3_passed=False, test3_method="nested", nested_delta_bic=stat,
                   nested_threshold=30.0, nested=_nested(stat), alternatives={"arc": ARC, "eccentric_ring": RING},
                   **fields)


def test_a_spiral_that_fails_only_test_3_is_a_named_candidate(model):
    v = _failed_test3()
    c = compact_source(v, model)
    assert c["origin"] == "spiral" and (c["r"], c["phi_deg"]) == (v.r_p, v.phi_p_deg)
    assert c["explained_by"] == ["a planet's spiral with its near-planet peak", "arc/vortex"]
    assert c["r_au"] == pytest.approx(v.r_p * v.distance) and c["nested_delta_bic"] == 5.0
    v = replace(v, compact_source=c)
    assert v.outcome == "candidate" and v.to_dict()["outcome"] == "candidate"
    text = v.summary()
    assert "No planet-driven spiral is claimed. Candidate: a compact source at" in text
    assert "sb.sample_posterior" in text and "P(planet)" in text
    # far below the candidate threshold, or explained by calibration, or a geometry error beside it: nothing
    assert compact_source(replace(_failed_test3(-35.0), alternatives={"eccentric_ring": RING}), model) is None
    assert compact_source(replace(v, calibration={"explains": True}), model) is None
    assert compact_source(replace(v, nested=_nested(5.0, "geometry", survives=True)), model) is None
    assert compact_source(replace(v, detected=True), model) is None
    # above the statistic, the spiral route names nothing and the compact arc beside it is named instead
    assert compact_source(v, model, DetectionSettings(candidate_threshold=10.0))["origin"] == "arc"


def test_an_arc_names_a_candidate_when_no_spiral_passes(model):
    v = replace(detect(scan_of()), detected=False, test1_passed=False,
                alternatives={"arc": ARC, "eccentric_ring": RING})
    c = compact_source(v, model)
    assert c["origin"] == "arc" and (c["r"], c["phi_deg"]) == (0.36, 42.0) and c["nested_delta_bic"] is None
    assert c["explained_by"][0] == "an arc/vortex" and c["deeper_time_factor"] is None
    flux = arc_excess_flux(ARC["params"], model.brightness, model.geometry.cos_inc)
    assert c["flux_mJy"] == pytest.approx(1e3 * flux)
    wide = {**ARC, "params": {**ARC["params"], "sigma_phi_deg": 60.0}}
    assert compact_source(replace(v, alternatives={"arc": wide}), model) is None
    beaten = {"arc": ARC, "eccentric_ring": {**RING, "delta_bic": 55.0}}
    assert compact_source(replace(v, alternatives=beaten), model) is None
    weak = {"arc": {**ARC, "delta_bic": 8.0}}
    assert compact_source(replace(v, alternatives=weak), model) is None


def test_the_arc_flux_is_the_alternatives_field_positive_excess(model):
    p = ARC["params"]
    grid = DiscGrid(1.0, 2000, 4096)
    ctx = ProfileContext.build(model.brightness, grid)
    theta = [p["contrast"], p["r_c"], np.radians(p["phi_c_deg"]), p["sigma_r"], np.radians(p["sigma_phi_deg"])]
    field = FIELD_MODELS["arc"].field(theta, ctx)
    area = grid.r[:, None] * grid.dr * (2 * np.pi / grid.n_phi) * ARCSEC ** 2
    expected = np.sum(np.clip(field, 0, None) * area) * model.geometry.cos_inc
    assert arc_excess_flux(p, model.brightness, model.geometry.cos_inc) == pytest.approx(expected, rel=5e-3)


def test_the_deeper_time_factor_solves_for_the_threshold():
    v = _failed_test3(12.0)
    f = deeper_time_factor(v, 30.0)
    n = np.exp(v.threshold_6lnN / 6)
    gain = 12.0 + 7 * np.log(n)
    assert f > 1 and f * gain - 7 * np.log(f * n) == pytest.approx(30.0, abs=1e-6)
    assert deeper_time_factor(_failed_test3(-1e6), 30.0) is None  # no gain: deeper data do not help


def test_settings_refuse_bad_candidate_options():
    from spiralbayes.exceptions import InputError

    with pytest.raises(InputError, match="compact_arc_width"):
        DetectionSettings(compact_arc_width=0.0)
    with pytest.raises(InputError, match="candidate_threshold"):
        DetectionSettings(candidate_threshold=float("nan"))
