"""The verdict on synthetic fiducial observations of impostors and planets (issue 13's checks).

Planet-free discs with a vortex-like arc, a lopsided disc, an eccentric ring or a phase-centre
error must not give a detection and test 3 must name the right alternative; with a planet the
spiral must win; and a planet hidden behind the false peak of a 10 mas phase-centre error must be
found after the geometry alternative is refitted. The default run uses the exact axisymmetric part
of the simulated disc (what a perfect frank fit would give) and a coarse scan; the ``slow`` table
repeats every case with frank, as a user would run it (``docs/verdict.md``).
"""

import warnings

import numpy as np
import pytest

from spiralbayes.inference.detection.alternatives import fit_alternatives
from spiralbayes.inference.detection.verdict import detect_with_planet_peak
from spiralbayes.inference.detection.verdict import detect
from spiralbayes.inference.detection.follow_up import rescan_at_fitted_geometry
from spiralbayes.inference.scan.run import scan
from spiralbayes.simulate import DiscModel, simulate_observation
from spiralbayes.simulate.asymmetric import ExactAxisymmetric, eccentric_ring, lopsided_disc, vortex_arc
from tests._support.helpers import DISTANCE, GEOMETRY, R_P_TRUE

WAVELENGTH = 0.87e-3  # the fiducial preset's
DISC = DiscModel(distance=DISTANCE, tau_ref=3.0)
R_GRID = np.linspace(0.04, 0.52, 13)  # holds the planet's 0.36" (50 au)


def impostors():
    """name -> (true geometry, perturbation delta(r, phi) or None, expected alternative)."""
    profile = DISC.profile(WAVELENGTH)
    return {
        "vortex arc": (GEOMETRY, vortex_arc(profile, 0.35, 2.0, 0.03, 0.35, 0.15), "arc"),
        "lopsided disc": (GEOMETRY, lopsided_disc(0.01, -1.0), "lopsided"),
        "eccentric ring": (GEOMETRY, eccentric_ring(0.4, 0.025, 0.05, 1.0, 0.3), "eccentric_ring"),
        "5 mas phase-centre error": (GEOMETRY.replace(dRA=0.005), None, "geometry"),
        "10 mas phase-centre error": (GEOMETRY.replace(dDec=-0.010), None, "geometry"),
    }


@pytest.fixture(scope="module")
def coarse_pair():
    from spiralbayes.templates import make_template

    right = make_template(1.0, 3.0, 10.0, "R", n_x=160, n_phi=360)
    return [right, right.mirror()]


def exact_model(delta=None):
    return lambda geometry: ExactAxisymmetric(DISC, WAVELENGTH, geometry, delta)


def verdict_for(vis, axisym, templates, **alt_kwargs):
    result = scan(vis, axisym, templates, GEOMETRY, r_p=R_GRID, distance=DISTANCE, progress=False)
    alternatives = fit_alternatives(vis, axisym, GEOMETRY, **alt_kwargs)
    # what spiralbayes scan decides with: test 3 scores spiral + the planet's compact peak against the arc
    verdict = detect_with_planet_peak(result, vis, axisym, templates, GEOMETRY, alternatives=alternatives)
    return result, alternatives, verdict


def test_vortex_arc_is_named_and_not_detected(coarse_pair):
    geometry, delta, expected = impostors()["vortex arc"]
    vis = simulate_observation("fiducial", DISC, geometry, delta, seed=4)
    _, alternatives, verdict = verdict_for(vis, exact_model(delta)(GEOMETRY), coarse_pair, n_starts=1)
    assert not verdict.detected and verdict.test3_passed is False
    assert verdict.best_alternative == expected
    assert alternatives.fits["arc"].params["r_c"] == pytest.approx(0.35, abs=0.01)
    assert "arc/vortex model explains the data better" in verdict.summary()


def test_planet_spiral_beats_every_alternative(planet_scan, planet_alternatives):
    verdict = detect(planet_scan, alternatives=planet_alternatives)
    assert verdict.detected and verdict.test3_passed
    assert verdict.delta_bic_vs_alternative > 1000
    assert "the spiral is preferred over the best competing asymmetry model" in verdict.summary()


def test_planet_behind_a_phase_centre_false_peak_is_found_after_the_geometry_refit(planet_templates):
    """Issues 13 and 15: with a 10 mas error the global peak is a false, unhanded one; the planet is
    the reported candidate, test 3 names the geometry error, and the rescan at the fitted geometry
    detects the planet where it is."""
    pair = list(planet_templates)
    vis = simulate_observation("fiducial", DISC, GEOMETRY.replace(dRA=-0.010), pair[0], r_p=R_P_TRUE, phi_p=0.0,
                               seed=1)
    axisym = exact_model()(GEOMETRY)
    result, alternatives, verdict = verdict_for(vis, axisym, pair, models=["geometry", "arc"], n_starts=1)
    assert not verdict.detected and verdict.test3_passed is False
    assert abs(verdict.r_p - R_P_TRUE) > 0.05  # the global peak is a false one
    # With the version-1 templates the false peak failed test 2 and the planet was reported as the
    # best handed candidate; with the issue-9 calibration (a weaker 1 M_th template) the false peak
    # at 0.44" passes test 2 by chance and no separate candidate is reported; test 3 still names
    # the geometry error, and the rescan below finds the planet.
    if verdict.candidate is not None:
        assert verdict.candidate["r_p"] == pytest.approx(R_P_TRUE, abs=0.02)
    i_true = int(np.argmin(np.abs(result.r_p - R_P_TRUE)))
    planet_before = float(result.delta_chi2()[0, i_true].max())
    assert verdict.best_alternative == "geometry"
    assert alternatives.fits["geometry"].params["d_dRA_mas"] == pytest.approx(-10.0, abs=1.5)
    follow = rescan_at_fitted_geometry(vis, axisym, pair, alternatives, scan_result=result,
                                       refit=exact_model(), refit_alternatives=False)
    assert follow.verdict.detected and follow.verdict.template.endswith("_R")
    assert follow.verdict.r_p == pytest.approx(R_P_TRUE, abs=0.02)
    assert follow.verdict.delta_chi2 > 2 * planet_before


# --- the full table with frank (slow) --------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("case", list(impostors()))
def test_impostor_with_frank_is_named_and_not_detected(case, coarse_pair):
    from spiralbayes.axisymmetric import fit_axisymmetric

    geometry, delta, expected = impostors()[case]
    vis = simulate_observation("fiducial", DISC, geometry, delta, seed=4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        axisym = fit_axisymmetric(vis, GEOMETRY, progress=False)
    _, _, verdict = verdict_for(vis, axisym, coarse_pair)
    assert not verdict.detected
    assert verdict.best_alternative == expected, verdict.summary()


@pytest.mark.slow
def test_planet_behind_false_peak_with_frank_refit(planet_templates):
    from spiralbayes.axisymmetric import fit_axisymmetric

    pair = list(planet_templates)
    vis = simulate_observation("fiducial", DISC, GEOMETRY.replace(dRA=-0.010), pair[0], r_p=R_P_TRUE, phi_p=0.0,
                               seed=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        axisym = fit_axisymmetric(vis, GEOMETRY, progress=False)
        result, alternatives, verdict = verdict_for(vis, axisym, pair)
        assert not verdict.detected and verdict.best_alternative == "geometry" and verdict.test3_passed is False
        if verdict.candidate is not None:  # version-1 templates: the false peak failed test 2 (see above)
            assert verdict.candidate["r_p"] == pytest.approx(R_P_TRUE, abs=0.02)
        follow = rescan_at_fitted_geometry(vis, axisym, pair, alternatives, scan_result=result)
    assert follow.verdict.detected and follow.verdict.test3_passed
    assert follow.verdict.r_p == pytest.approx(R_P_TRUE, abs=0.02)
