"""Completeness by injection–recovery: the fast path against brute-force re-scans, M_det, errors."""

import warnings

import numpy as np
import pytest

from spiralbayes.inference.limits.recovery import (
    CompletenessResult,
    completeness,
    completeness_brute_force,
    injection_plan,
)
from tests._support import limits_setup

SMALL_GRID = dict(masses=[0.3, 1.0], radii=[0.25, 0.45], n_azimuths=3)


def binomial_agreement(a, b, n):
    """|P_a - P_b| within 2 sigma (binomial, at least one trial's worth) per cell."""
    p = 0.5 * (a + b)
    return np.abs(a - b) <= 2 * np.sqrt(np.maximum(2 * p * (1 - p) / n, 1.0 / n ** 2)) + 1e-12


def test_fast_completeness_equals_brute_force_rescans(bright_case):
    vis, model, templates, result = bright_case
    fast = completeness(vis, model, templates, result, progress=False, **SMALL_GRID)
    brute = completeness_brute_force(vis, model, templates, result, **SMALL_GRID)
    np.testing.assert_allclose(fast.delta_bic, brute.delta_bic, atol=1e-3 * np.max(np.abs(brute.delta_bic)))
    assert np.all(binomial_agreement(fast.probability, brute.probability, fast.n_trials))
    assert (fast.recovered == brute.recovered).mean() >= 0.9
    # 1 M_th planets are found at 0.45 arcsec, 0.3 M_th ones nowhere (their Δχ² ~ 10-40 < 6 ln N + 10);
    # at 0.25 arcsec, inside C-4's ~0.3 arcsec beam, the hands are hard to tell apart and test 2
    # rejects some (all with the version-1 templates, 1 of 3 azimuths since the issue-9 calibration)
    assert fast.probability[1, 1] == 1.0 and fast.probability[1, 0] < 1.0 and fast.probability[0].max() == 0.0
    assert np.all(fast.delta_bic[0, 1] > 10)


def test_minimum_detectable_mass_interpolates_in_log_mass():
    fam = injection_plan_family()
    recovered = np.zeros((1, 3, 2, 4), bool)
    recovered[0, 1, 0, :2] = True   # 1 M_th: 50 % at the first radius
    recovered[0, 2, :, :] = True    # 3 M_th: always
    recovered[0, 1, 1, :] = True    # 1 M_th: always at the second radius
    comp = CompletenessResult(fam, ["R"], np.array([0.3, 1.0, 3.0]), np.array([0.2, 0.3]), np.zeros(4),
                              recovered, recovered, np.zeros(recovered.shape))
    np.testing.assert_allclose(comp.probability, [[0, 0], [0.5, 1], [1, 1]])
    m50, m90 = comp.m_det(0.5), comp.m_det(0.9)
    assert m50[0] == pytest.approx(1.0)
    assert m50[1] == pytest.approx(np.sqrt(0.3 * 1.0))  # halfway from P = 0 at 0.3 to P = 1 at 1 in ln M
    assert m90[0] == pytest.approx(np.exp(np.log(1.0) + 0.8 * np.log(3.0)))
    with pytest.raises(ValueError, match="completeness level"):
        comp.m_det(1.5)


def injection_plan_family():
    from spiralbayes.inference.limits.families import template_families

    meta = [{"name": f"m{m}{h}", "mass": m, "tau0": 0.3, "beta": 10.0, "hand": h}
            for m in (0.3, 1.0, 3.0) for h in "RL"]
    return template_families(meta)[0]


def test_save_load_round_trip(tmp_path, bright_case):
    vis, model, templates, result = bright_case
    comp = completeness(vis, model, templates, result, progress=False, masses=[1.0], radii=[0.35], n_azimuths=2)
    loaded = CompletenessResult.load(comp.save(tmp_path / "c.h5"))
    np.testing.assert_array_equal(loaded.recovered, comp.recovered)
    assert loaded.family.label == comp.family.label and loaded.criteria == comp.criteria


def test_grid_outside_the_scan_and_empty_family_are_refused(bright_case):
    vis, model, templates, result = bright_case
    with pytest.raises(ValueError, match="not on the scan's r_p grid"):
        injection_plan(result, radii=[0.3])
    with pytest.raises(ValueError, match="is empty"):
        injection_plan(result, family={"tau0": 3.0})
    with pytest.raises(ValueError, match="not in the family"):
        injection_plan(result, masses=[0.5])
    with pytest.raises(ValueError, match="n_azimuths"):
        injection_plan(result, n_azimuths=0)
    other = limits_setup.observation(35e-6, seed=99)
    with pytest.raises(ValueError, match="differ from the scan's"):
        completeness(other, model, templates, result, masses=[1.0], radii=[0.25], n_azimuths=1, progress=False)


@pytest.mark.slow
def test_fast_completeness_matches_brute_force_with_frank_refits(bright_case):
    """The fast path keeps the axisymmetric model; refitting frank on every injected dataset (what
    a user re-running the pipeline would do) changes the recovery rate only within binomial errors."""
    from spiralbayes.axisymmetric import fit_axisymmetric

    vis, model, templates, result = bright_case

    def refit(injected):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return fit_axisymmetric(injected, limits_setup.GEOMETRY, N=100, progress=False)

    grid = dict(masses=[0.3, 1.0, 3.0], radii=list(limits_setup.R_P), n_azimuths=4)
    fast = completeness(vis, model, templates, result, progress=False, **grid)
    brute = completeness_brute_force(vis, model, templates, result, refit=refit, **grid)
    assert np.all(binomial_agreement(fast.probability, brute.probability, fast.n_trials))
    assert abs(fast.probability.mean() - brute.probability.mean()) <= 0.1


def test_a_templates_limit_margin_scales_the_planted_planet_in_both_paths(bright_case):
    """A learned template's margin (metadata ``limit_margin``) plants the template scaled by it: the fast
    path against brute-force re-scans of data with the scaled planet added."""
    import copy

    vis, model, templates, result = bright_case
    grid = dict(masses=[1.0], radii=[0.45], n_azimuths=2)
    scaled = copy.deepcopy(result)
    for meta in scaled.templates:
        meta["limit_margin"] = 0.5
    full = completeness(vis, model, templates, result, progress=False, **grid)
    fast = completeness(vis, model, templates, scaled, progress=False, **grid)
    brute = completeness_brute_force(vis, model, templates, scaled, **grid)
    np.testing.assert_allclose(fast.delta_bic, brute.delta_bic, atol=1e-3 * np.max(np.abs(brute.delta_bic)))
    # half the planet: the scan's cross terms with it halve, so every ΔBIC falls
    assert np.all(fast.delta_bic < full.delta_bic - 1.0)
