"""Nested test 3: the spiral fitted jointly with the competing asymmetries (small, reduced data)."""

import dataclasses

import numpy as np
import pytest

from spiralbayes import DiscGeometry, GainErrors
from spiralbayes.calibration import diagnose_calibration
from spiralbayes.inference.detection import detect_with_planet_peak, fit_alternatives
from spiralbayes.inference.detection.nested import HYPOTHESES, _Spiral, nested_test
from spiralbayes.inference.scan.engine import ScanContext
from spiralbayes.inference.scan.run import scan
from spiralbayes.model import perturbation_visibilities
from spiralbayes.simulate import DiscModel, simulate_observation
from spiralbayes.simulate.asymmetric import ExactAxisymmetric, vortex_arc

GEOMETRY = DiscGeometry(30.0, 60.0)
DISTANCE = 140.0
DISC = DiscModel(distance=DISTANCE, tau_ref=3.0)
WAVELENGTH = 0.87e-3
R_GRID = np.linspace(0.04, 0.52, 13)
R_PLANET = 50 / DISTANCE


@pytest.fixture(scope="module")
def pair():
    from spiralbayes.templates import make_template

    right = make_template(1.0, 3.0, 10.0, "R", n_x=160, n_phi=360)
    return [right, right.mirror()]


def _reduced(delta=None, **kwargs):
    vis = simulate_observation("fiducial", DISC, GEOMETRY, delta, **kwargs)
    return vis.subset(np.arange(0, vis.V.size, 4))


def _verdict(vis, axisym, templates, **detect_kwargs):
    result = scan(vis, axisym, templates, GEOMETRY, r_p=R_GRID, distance=DISTANCE, progress=False)
    alts = fit_alternatives(vis, axisym, GEOMETRY, n_starts=1)
    return result, alts, detect_with_planet_peak(result, vis, axisym, templates, GEOMETRY, alternatives=alts,
                                                 **detect_kwargs)


def test_linear_part_matches_non_negative_least_squares():
    """The spiral's amplitudes for a fixed residual: scipy's NNLS on the stacked real system."""
    from scipy.optimize import nnls

    rng = np.random.default_rng(3)
    n = 400
    S = rng.normal(size=n) + 1j * rng.normal(size=n)
    P = rng.normal(size=n) + 1j * rng.normal(size=n)
    w = rng.uniform(0.5, 2.0, n)
    res = 0.7 * S - 0.4 * P + 0.3 * (rng.normal(size=n) + 1j * rng.normal(size=n))
    sp = _Spiral(S, P, w, 0.3, 0.0)
    sw = np.sqrt(w)
    for hypothesis, (fixed, peak, _) in HYPOTHESES.items():
        target = res - S if fixed else res
        cols = ([P] if peak else []) if fixed else ([S, P] if peak else [S])
        chi2_0 = np.sum(w * np.abs(res) ** 2)
        if cols:
            A = np.stack([np.concatenate([(sw * c).real, (sw * c).imag]) for c in cols], axis=1)
            b = np.concatenate([(sw * target).real, (sw * target).imag])
            chi2_ref = nnls(A, b)[1] ** 2
        else:
            chi2_ref = np.sum(w * np.abs(target) ** 2)
        gain = sp.solve(res, hypothesis)[0]
        assert gain == pytest.approx(chi2_0 - chi2_ref, rel=1e-9), hypothesis


def test_planet_beside_a_vortex_is_detected_and_the_vortex_named(pair):
    """A planet and an unrelated bright arc: the single-model comparison may prefer either, the
    nested test finds the spiral in addition to the arc, and the verdict names both."""
    delta = vortex_arc(DISC.profile(WAVELENGTH), 0.25, 3.0, 0.03, 0.35, 0.3)
    axisym = ExactAxisymmetric(DISC, WAVELENGTH, GEOMETRY, delta)
    # the arc disc observed, plus the planet's spiral visibilities
    base = _reduced(delta, seed=1)
    ctx = ScanContext.build(base, axisym, GEOMETRY, [R_PLANET], 8)
    planet = perturbation_visibilities(base.u, base.v, GEOMETRY, ctx.profile, pair[0], R_PLANET, 0.0,
                                       quad=ctx.quadrature(pair[0], R_PLANET))
    vis = dataclasses.replace(base, V=base.V + planet)
    _, alts, verdict = _verdict(vis, axisym, pair)
    assert alts.fits["arc"].params["r_c"] == pytest.approx(0.25, abs=0.02)
    assert verdict.test3_method == "nested" and verdict.detected
    assert verdict.r_p == pytest.approx(R_PLANET, abs=0.04)
    arc = next(f for f in verdict.nested if f["alternative"] == "arc")
    assert arc["survives"] and arc["delta_bic"] > verdict.nested_threshold
    assert verdict.also_present == "an arc/vortex elsewhere in the disc"
    assert "The data hold a spiral and an arc/vortex elsewhere in the disc" in verdict.summary()


def test_vortex_alone_fails_the_nested_test(pair):
    delta = vortex_arc(DISC.profile(WAVELENGTH), 0.35, 2.0, 0.03, 0.35, 0.15)
    vis = _reduced(delta, seed=4)
    axisym = ExactAxisymmetric(DISC, WAVELENGTH, GEOMETRY, delta)
    result = scan(vis, axisym, pair, GEOMETRY, r_p=R_GRID, distance=DISTANCE, progress=False)
    alts = fit_alternatives(vis, axisym, GEOMETRY, n_starts=1)
    fits = nested_test(result, vis, axisym, pair, alts, GEOMETRY, n_alternatives=2)
    assert [f.alternative for f in fits] == sorted(alts.fits, key=lambda k: -alts.delta_bic()[k])[:2]
    for f in fits:
        # nested: the joint model contains the alternative alone and the spiral alone
        assert f.delta_chi2_joint >= f.delta_chi2_alone - 1e-6
        assert f.delta_chi2_alone >= alts.fits[f.alternative].delta_chi2 - 1e-6
        ln_n = np.log(vis.V.size)
        assert f.delta_bic_joint == pytest.approx(f.delta_chi2_joint - f.delta_chi2_alone - f.n_spiral_params * ln_n)
        # the spiral alone at the same hypothesis and position is one of the models the statistic may use
        alone_bic = f.delta_chi2_alone - f.n_alt_params * ln_n
        assert f.delta_bic_spiral_alone >= f.delta_chi2_spiral_alone - f.n_spiral_params * ln_n - alone_bic - 1e-6
        assert f.delta_bic == max(f.delta_bic_joint, f.delta_bic_spiral_alone)
    assert max(f.delta_bic for f in fits) < 10


def test_gain_errors_are_named_as_the_explanation(pair):
    """Planet-free data with 20 deg antenna phase errors: no spiral is claimed, and the verdict names
    calibration (with what to do) rather than a disc asymmetry."""
    vis = _reduced(seed=7, gains=GainErrors(20.0, 0.05, 300.0, seed=7))
    axisym = ExactAxisymmetric(DISC, WAVELENGTH, GEOMETRY)
    calibration = diagnose_calibration(vis, axisym)
    assert calibration.warning is not None
    _, _, verdict = _verdict(vis, axisym, pair, calibration=calibration)
    assert not verdict.detected
    assert verdict.explanation == "calibration"
    text = verdict.summary()
    assert "antenna gain errors rather than a disc asymmetry" in text and "[calibration] solve" in text
    assert verdict.to_dict()["calibration"]["phase_rms_deg"] == pytest.approx(20.0, rel=0.5)
    # data that record their antennas are diagnosed by default (what `spiralbayes scan` gets), the same
    # numbers as the explicit diagnostic; calibration=False leaves it out
    result, alts, by_default = _verdict(vis, axisym, pair)
    assert by_default.to_dict() == verdict.to_dict()
    skipped = detect_with_planet_peak(result, vis, axisym, pair, GEOMETRY, alternatives=alts, calibration=False)
    assert skipped.calibration is None and skipped.explanation != "calibration"


def test_a_spiral_in_data_with_antenna_phase_errors_is_not_claimed(pair):
    """A 1 M_th planet with 6 deg rms antenna phase errors (5-minute coherence): tests 1-3 pass at the
    right place, but phase errors remain with the spiral in the model, so it is not claimed and the
    verdict says to solve the gains; without gain errors the same planet is claimed."""
    axisym = ExactAxisymmetric(DISC, WAVELENGTH, GEOMETRY)

    def planted(gains):
        vis = simulate_observation("fiducial", DISC, GEOMETRY, perturbation=pair[0], r_p=R_PLANET, phi_p=0.0, seed=2,
                                   gains=gains)
        return vis.subset(np.arange(0, vis.V.size, 4))

    vis = planted(GainErrors(6.0, 0.0, 300.0, seed=2))
    result, alts, verdict = _verdict(vis, axisym, pair)
    unguarded = detect_with_planet_peak(result, vis, axisym, pair, GEOMETRY, alternatives=alts, calibration=False)
    assert unguarded.detected and unguarded.r_p == pytest.approx(R_PLANET, abs=0.04)
    assert not verdict.detected and verdict.test1_passed and verdict.test2_passed and verdict.test3_passed
    assert verdict.calibration["withheld"] and verdict.explanation == "calibration"
    assert verdict.calibration["with_alternative"]["model"] == "spiral"
    assert verdict.calibration["with_alternative"]["phase_rms_deg"] > 5.0
    assert "the spiral is not claimed" in verdict.summary() and "[calibration] solve" in verdict.summary()
    clean = _verdict(planted(None), axisym, pair)[2]
    assert clean.detected and not clean.calibration.get("withheld")


def test_templates_reaching_beyond_the_default_grid_are_fitted(pair):
    """A template out to 3 r_p (hydrodynamic maps reach that far; the generator's stop at 2.2): the
    nested fit builds its uv grid for the template's reach, and zeros beyond 2.2 r_p change nothing."""
    right = pair[0]
    step = np.log(right.x[-1] / right.x[-2])
    extra = right.x[-1] * np.exp(step * np.arange(1, int(np.ceil(np.log(3.0 / right.x[-1]) / step)) + 1))
    wide = dataclasses.replace(right, x=np.concatenate([right.x, extra]), name=right.name + "_wide", brightness=None,
                               delta=np.vstack([right.delta, np.zeros((extra.size, right.phi.size))]))
    assert wide.x[-1] >= 3.0
    axisym = ExactAxisymmetric(DISC, WAVELENGTH, GEOMETRY)
    base = _reduced(seed=2)
    ctx = ScanContext.build(base, axisym, GEOMETRY, [R_PLANET], 8)
    planet = perturbation_visibilities(base.u, base.v, GEOMETRY, ctx.profile, right, R_PLANET, 0.5,
                                       quad=ctx.quadrature(right, R_PLANET))
    vis = dataclasses.replace(base, V=base.V + planet)
    alts = fit_alternatives(vis, axisym, GEOMETRY, n_starts=1)
    stats, margins = [], []
    for templates in (pair, [wide, wide.mirror()]):
        result = scan(vis, axisym, templates, GEOMETRY, r_p=R_GRID, distance=DISTANCE, progress=False)
        stats.append(nested_test(result, vis, axisym, templates, alts, GEOMETRY, n_alternatives=1)[0].delta_bic)
        # the verdict's single-model comparison scores the spiral with its compact peak on the same grid
        verdict = detect_with_planet_peak(result, vis, axisym, templates, GEOMETRY, alternatives=alts)
        margins.append(verdict.delta_bic_vs_alternative)
    assert stats[0] > 30 and verdict.detected
    assert stats[1] == pytest.approx(stats[0], rel=1e-3)
    assert margins[1] == pytest.approx(margins[0], rel=1e-3)


# --- which templates test 3 tries -----------------------------------------------------------------
def _kind_scan(peaks):
    """A scan whose template k has Δχ² ``value`` at (i_rp, i_phi) and 0 elsewhere; ``peaks`` lists
    ``(name, provenance, i_rp, i_phi, value)``; returns the ScanResult and stand-in templates."""
    from types import SimpleNamespace

    from spiralbayes.inference.scan.run import ScanResult

    n_r, n_phi = 5, 12
    cross = np.zeros((len(peaks), n_r, n_phi))
    for k, (_, _, i, j, value) in enumerate(peaks):
        cross[k, i, j] = value / 2  # power 0: Δχ² = 2 cross
    result = ScanResult([{"name": p[0]} for p in peaks], np.linspace(0.1, 0.5, n_r),
                        2 * np.pi * np.arange(n_phi) / n_phi, cross, np.zeros_like(cross), 1e5, 36_000,
                        DiscGeometry(30.0, 60.0))
    return result, [SimpleNamespace(name=p[0], provenance=p[1]) for p in peaks]


GEN, SIM = {"generator": "spiralbayes.templates.generator"}, {"reader": "spiralbayes.templates.fargo3d"}


def test_template_kind_tells_the_generator_from_simulated_maps():
    from spiralbayes.templates.template import template_kind
    from spiralbayes.templates import make_template

    assert template_kind(make_template(1.0, 0.3, 0.0, "R")) == "generator"
    _, (sim,) = _kind_scan([("run", SIM, 0, 0, 1.0)])
    assert template_kind(sim) == "simulation"


@pytest.mark.parametrize("where, tried", [
    ((2, 5), ["gen_a", "sim_b"]),      # the same place
    ((3, 6), ["gen_a", "sim_b"]),      # one step in r_p and in φ_p
    ((2, 7), ["gen_a"]),               # two azimuth steps away: another position, not tried
    ((4, 5), ["gen_a"]),               # two radius steps away
])
def test_nested_candidates_add_the_best_of_the_other_kind_near_the_peak(where, tried):
    from spiralbayes.inference.detection.nested import nested_candidates

    result, templates = _kind_scan([("gen_a", GEN, 2, 5, 100.0), ("gen_b", GEN, 2, 5, 90.0),
                                    ("sim_a", SIM, 0, 0, 40.0), ("sim_b", SIM, *where, 80.0)])
    assert nested_candidates(result, templates, "gen_a") == tried


def test_nested_candidates_wrap_in_azimuth_and_need_two_kinds():
    from spiralbayes.inference.detection.nested import nested_candidates

    result, templates = _kind_scan([("sim", SIM, 1, 11, 100.0), ("gen", GEN, 1, 0, 50.0)])
    assert nested_candidates(result, templates, "sim") == ["sim", "gen"]  # 11 and 0 are neighbours of 12
    result, templates = _kind_scan([("gen_a", GEN, 1, 3, 100.0), ("gen_b", GEN, 1, 3, 90.0)])
    assert nested_candidates(result, templates, "gen_a") == ["gen_a"]  # one kind: the verdict's template alone


def test_test3_takes_the_candidate_with_the_larger_statistic(monkeypatch):
    from types import SimpleNamespace

    from spiralbayes.inference.detection import DetectionSettings, nested
    from spiralbayes.inference.detection.verdict import Verdict

    result, templates = _kind_scan([("gen", GEN, 2, 5, 100.0), ("sim", SIM, 2, 5, 120.0)])
    scores = {"sim": (5.0, -3.0), "gen": (44.0, 51.0)}  # per candidate, against the two alternatives

    def fake_nested_test(result, vis, axisym, templates, alternatives, geometry, *, template, n_alternatives):
        return [SimpleNamespace(delta_bic=d, alternative=a, alternative_delta_bic=0.0,
                                alternative_delta_bic_given_spiral=0.0, label=a,
                                to_dict=lambda d=d, a=a: {"delta_bic": d, "alternative": a, "label": a})
                for d, a in zip(scores[template], ("eccentric_ring", "arc"))]

    monkeypatch.setattr(nested, "nested_test", fake_nested_test)
    verdict = Verdict(detected=False, delta_bic=50.0, test1_passed=True, handedness_ratio=0.1, localisation=0.01,
                      test2_passed=True, template="sim", r_p=0.3, phi_p_deg=150.0, delta_chi2=100.0,
                      threshold_6lnN=50.0, distance=140.0)
    alternatives = SimpleNamespace(fits={"eccentric_ring": None, "arc": None})
    out = nested.apply_nested(verdict, result, None, None, templates, None, alternatives, DetectionSettings())
    # "sim" alone: min(5, -3) = -3, fails; "gen" at the same place: min(44, 51) = 44 > the threshold (10)
    assert out.nested_template == "gen" and out.nested_delta_bic == 44.0
    assert out.test3_passed and out.detected and out.template == "sim"
    scores["gen"] = (8.0, 51.0)
    out = nested.apply_nested(verdict, result, None, None, templates, None, alternatives, DetectionSettings())
    assert out.nested_template == "gen" and out.nested_delta_bic == 8.0 and not out.test3_passed
