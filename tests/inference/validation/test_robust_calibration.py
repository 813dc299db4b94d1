"""Leave-one-source-out calibration of the robust limits over morphology variants (issue 22;
docs/limits.md §4d). The machinery is in ``robust_calibration.py`` next to this file."""

import numpy as np
import pytest
from scipy.stats import norm

pytest.importorskip("h5py")

from tests.inference.validation import robust_calibration as RC
from tests.templates import fidelity as F
from tests.templates import variant_fit as VF

CASES = {c.label: c for c in F.acceptance_cases() + F.physics_cases()}


def test_truth_instance_rate_of_the_bank_template_is_the_nominal_one():
    """Closed form: one template planted as itself has A_up < 1 with probability Φ(−z_95) = 5 %;
    a template with half the overlap, P = Φ(−z − (Â − 1)/σ) with Â = 1/2 and σ = 1/√power."""
    g = {"SS": 1.0, "ST": 1.0, "SB": 0.0, "TT": 1.0, "BB": 1.0, "TB": 0.3}
    robust, single = RC.truth_instance_rates(g, [(1.0, 0.0)], power=100.0, n=40000, seed=3, control=True)
    assert robust == single and abs(single - 0.05) < 3 * np.sqrt(0.05 * 0.95 / 40000)
    half = dict(g, ST=0.5)
    expected = norm.cdf(-VF.Z95 + 0.5 * np.sqrt(100.0))
    _, single = RC.truth_instance_rates(half, [(1.0, 0.0)], power=100.0, n=40000, seed=4)
    assert abs(single - expected) < 4 * np.sqrt(expected * (1 - expected) / 40000)
    # two variants: excluded only where both exclude, so never more often than either alone
    robust, single = RC.truth_instance_rates(half, [(1.0, 0.0), (0.4, 0.0)], power=100.0, n=40000, seed=4)
    assert robust <= single and robust < 0.01


def test_held_out_hydro_run_is_not_wrongly_excluded_in_the_fiducial_set_up():
    """Variants fitted to the library's four H/r 0.07 isothermal maps at τ0 0.3 only; the older
    FARGO3D 1 M_th run planted (τ0 0.3, bank power 400): the compromise alone excludes it in 100 %
    of the realisations, the variants in <= 5 % (binomial; measured 0.25 %: Â 1.14 for the hydro variant)."""
    fit_rows = [(CASES[c], 0.3, VF.case_gram(CASES[c], 0.3))
                for c in ("fargo3dlib:h0.07_mu0.1", "fargo3dlib:h0.07_mu0.3", "fargo3dlib:h0.07_mu1",
                          "fargo3dlib:h0.07_mu3")]
    fits = VF.fit_variants(fit_rows)
    case = CASES["fargo3d:h0.07_mu1"]
    g = VF.case_gram(case, 0.3)
    amps = [(1.0, 0.0)] + [VF.fitted_amplitudes(f, case.mu) for f in fits.values()]
    robust, single = RC.truth_instance_rates(g, amps, power=400.0, n=400, seed=11)
    assert single > 0.9
    assert robust <= RC.allowed_wrong(400), robust


@pytest.mark.slow
@pytest.mark.parametrize("source", VF.SOURCES + VF.HELD_OUT_SOURCES)
def test_leave_one_source_out_calibration(source):
    """Every map of ``source`` (τ0 0.3 and 3), bank power 100 and 400, 1000 realisations each: the
    robust limit of the variants refitted without ``source`` wrongly excludes <= 5 % (binomial);
    the control (the bank's template planted) stays at or below nominal."""
    rows = RC.loso_table(n=1000, sources=(source,))
    for r in rows:
        print(f"{r['case']:34s} tau0 {r['tau0']:g} power {r['power']:g}: robust {r['robust']:.3f} "
              f"(compromise alone {r['single']:.3f}); control {r['control_robust']:.3f} / {r['control_single']:.3f}")
    assert rows
    assert all(r["control_robust"] <= RC.allowed_wrong(r["n"]) for r in rows)
    assert all(r["control_single"] <= RC.allowed_wrong(r["n"]) for r in rows)
    bad = [(r["case"], r["tau0"], r["power"], r["robust"]) for r in rows if r["robust"] > RC.allowed_wrong(r["n"])]
    assert not bad, bad


GAPPED_FAILURES = {
    "dust2": "the 200-orbit St 0.1 map in its disc with a dust ring 12x the initial density at 1.3 r_p: the "
             "templates' power doubles on the ring while the map's falls 45x, A_hat -0.3 to -0.1; 100 % wrongly "
             "excluded at tau0 0.3",
}
"""Sources whose maps, planted in discs holding their runs' gaps, the shipped variants (fitted to maps
planted in the unperturbed disc) wrongly exclude, as measured (docs/limits.md §4d)."""


@pytest.mark.slow
@pytest.mark.parametrize("source", [pytest.param(s, marks=[pytest.mark.xfail(reason=GAPPED_FAILURES[s], strict=True)])
                                    if s in GAPPED_FAILURES else s for s in VF.SOURCES + VF.HELD_OUT_SOURCES])
def test_leave_one_source_out_calibration_in_gapped_discs(source):
    """As :func:`test_leave_one_source_out_calibration`, with every map planted in a disc holding its
    run's gap (:class:`tests.templates.fidelity.GappedDisc`, the detection table's planting)."""
    rows = RC.loso_table(n=1000, sources=(source,), gap=True)
    assert rows
    assert all(r["control_robust"] <= RC.allowed_wrong(r["n"]) for r in rows)
    bad = [(r["case"], r["tau0"], r["power"], r["robust"]) for r in rows if r["robust"] > RC.allowed_wrong(r["n"])]
    assert not bad, bad


MACHINERY_CASES = [("fargo3d:h0.07_mu1", 0.3), ("fargo3dlib:h0.07_mu1_beta10", 0.3),
                   ("fargo3dlib:h0.07_mu1_st0.03", 0.3), ("wakeflow:h0.07_mu1", 3.0),
                   ("fargo3dlib:h0.07_mu1_nu1e-04", 0.3)]


@pytest.mark.slow
@pytest.mark.parametrize("label,tau0", MACHINERY_CASES, ids=[f"{c}-tau{t:g}" for c, t in MACHINERY_CASES])
def test_limit_machinery_with_variants_held_out_source(label, tau0):
    """§4c's machinery (``planted_exclusion_rate``, robust over the variant families: M_lim over
    every azimuth and the neighbouring bank masses) in the resolved fiducial set-up, bank power 400,
    100 realisations, the variants refitted without the case's source (docs/limits.md §4d)."""
    case = CASES[label]
    variants = RC.loso_variants(VF.calibration_source(case))
    planted = RC.calibrate_fiducial(case, tau0, 400.0, variants, 100)
    control = RC.calibrate_fiducial(case, tau0, 400.0, variants, 100, control=True)
    print(planted.summary(), "compromise alone:", RC.single_rate(planted))
    print("control:", control.summary())
    assert planted.rate <= RC.allowed_wrong(planted.n)
    assert control.rate <= RC.allowed_wrong(control.n)


GAPPED_MACHINERY_CASES = MACHINERY_CASES + [
    ("fargo3dlib:h0.07_mu1_orbits200", 0.3),
    # the deep 3 M_th gaps after 200 orbits at H/r 0.07 and 0.05, each held out from a fit that has the other
    ("fargo3dlib:h0.07_mu3_orbits200", 3.0), ("fargo3dlib:h0.05_mu3_orbits200", 3.0),
    ("fargo3dlib:h0.05_mu3_orbits200", 0.3),
    pytest.param("fargo3dlib:h0.07_mu1_st0.1_orbits200", 0.3, marks=pytest.mark.xfail(
        strict=True, reason="wrongly excluded in 98 of 100 realisations in its disc with a 12x dust ring "
        "(docs/limits.md 4d)"))]


@pytest.mark.slow
@pytest.mark.parametrize("label,tau0", GAPPED_MACHINERY_CASES)
def test_limit_machinery_in_gapped_discs(label, tau0):
    """The machinery above with the map planted in a disc holding its run's gap."""
    case = CASES[label] if label in CASES else next(c for c in F.reference_cases() if c.label == label)
    planted = RC.calibrate_fiducial(case, tau0, 400.0, RC.loso_variants(VF.calibration_source(case)), 100, gap=True)
    print(planted.summary())
    assert planted.rate <= RC.allowed_wrong(planted.n)


BETWEEN_H_CASES = [("fargo3dlib:h0.08_mu2", 0.3, (0.07, 0.10)), ("fargo3dlib:h0.08_mu2", 3.0, (0.07, 0.10)),
                   ("fargo3dlib:h0.06_mu0.5", 0.3, (0.05, 0.07)),
                   pytest.param("fargo3dlib:h0.06_mu0.5", 3.0, (0.05, 0.07), marks=pytest.mark.xfail(
                       strict=True, reason="wrongly excluded in 22 of 100 realisations (0 of 100 with limit "
                       "families at its own H/r 0.06): the bank's aspect ratios miss the arms between them "
                       "(docs/limits.md 4d)"))]


@pytest.mark.slow
@pytest.mark.parametrize("label,tau0,h_ps", BETWEEN_H_CASES,
                         ids=["h0.08_mu2-tau0.3", "h0.08_mu2-tau3", "h0.06_mu0.5-tau0.3", "h0.06_mu0.5-tau3"])
def test_limit_machinery_between_the_banks_aspect_ratios(label, tau0, h_ps):
    """The physics run set's planets between the bank's masses and aspect ratios (never fitted by the
    variants), with the limit's families at the bank's neighbouring H/r, as ``compute_limits`` on the
    default bank sees them: bank power 400, 100 realisations, wrongly excluded <= 5 % (binomial)."""
    case = CASES[label]
    variants = RC.loso_variants(VF.calibration_source(case))
    planted = RC.calibrate_fiducial(case, tau0, 400.0, variants, 100, h_ps=h_ps)
    control = RC.calibrate_fiducial(case, tau0, 400.0, variants, 100, control=True, h_ps=h_ps)
    print(planted.summary())
    print("control:", control.summary())
    assert control.rate <= RC.allowed_wrong(control.n)
    assert planted.rate <= RC.allowed_wrong(planted.n)


@pytest.mark.slow
def test_inner_families_hold_between_the_banks_aspect_ratios():
    """The case above that the bank's aspect ratios wrongly exclude (22 of 100) is not excluded once
    every variant's family truncated to |x - 1| < 0.3 (``inner_template``) joins the robust set
    (measured: 0 of 100; docs/limits.md 4d)."""
    planted = RC.calibrate_fiducial(CASES["fargo3dlib:h0.06_mu0.5"], 3.0, 400.0, RC.loso_variants("physics"), 100,
                                    h_ps=(0.05, 0.07), inner=0.3)
    assert planted.rate <= RC.allowed_wrong(planted.n)
