"""Nested test 3's threshold against look-elsewhere (slow): planet-free, impostor and gain-error data.

Seven kinds × :data:`~tests.inference.detection.false_alarms.N_PER_KIND` reduced fiducial datasets
(:mod:`tests.inference.detection.false_alarms`; 350 in all): no planet may be claimed, and where
tests 1 and 2 pass (where test 3 decides) the nested ΔBIC of the scan's best peak must stay below
the default threshold; not for gain errors: there it exceeded the threshold in 50 (seed 11042,
3.2° rms, 64.3 against the geometry model; seed 11004, 20.6), and the geometry rule (no claim while a geometry error
survives beside the spiral; the rescan at the fitted geometry then fails test 2) is what holds; the
measured table is in docs/verdict.md. No candidate compact source is named on planet-free data, on
geometry or on gain errors, and a candidate on an arc or eccentric ring names that model among its
explanations.
"""

import logging

import pytest

from spiralbayes.inference.detection import DetectionSettings
from tests.inference.detection import false_alarms as fa

log = logging.getLogger(__name__)


@pytest.mark.slow
@pytest.mark.parametrize("kind", fa.KINDS)
def test_no_planet_is_claimed_on_planet_free_impostor_and_gain_error_data(kind):
    rows = [fa.evaluate(kind, seed) for seed in fa.seeds(kind)]
    largest = max(rows, key=lambda r: r["nested_delta_bic"])
    log.info("%s: largest nested Delta BIC %.1f (seed %d, vs %s)", kind, largest["nested_delta_bic"],
             largest["seed"], largest["nested_vs"])
    assert sum(r["detected"] for r in rows) == 0, [r for r in rows if r["detected"]]
    decided = [r for r in rows if r["test1"] and r["test2"]]
    if kind != "gains":
        assert all(r["nested_delta_bic"] <= DetectionSettings().nested_threshold for r in decided), decided
    sources = [r["compact_source"] for r in rows if r["compact_source"]]
    if kind in ("planet_free", "geometry", "gains"):  # nothing compact in the sky
        assert not sources, sources
    elif kind in ("arc", "eccentric_ring"):
        label = {"arc": "arc/vortex", "eccentric_ring": "eccentric ring"}[kind]
        assert all(any(label in x for x in s["explained_by"]) for s in sources), sources


@pytest.mark.parametrize("n", [pytest.param(10, id="10-per-kind"),
                               pytest.param(fa.N_PER_KIND, id="all", marks=pytest.mark.slow)])
def test_the_calibration_diagnostic_warns_on_gain_errors_only(n):
    """The diagnostic against the true disc: no warning on the planet-free and impostor datasets (the
    impostors leave no antenna-based residual), a warning on every gain-error dataset whose errors
    exceed the warning levels (phase 5 deg or amplitude 3 %, by more than the estimate's scatter)."""
    from spiralbayes.calibration.diagnostics import AMP_WARN, PHASE_WARN_DEG

    for kind in fa.KINDS:
        rows = [fa.diagnose(kind, seed) for seed in fa.seeds(kind, n)]
        if kind != "gains":
            assert not any(r["warns"] for r in rows), [r for r in rows if r["warns"]]
            continue
        for r in rows:
            clear = r["params"]["phase_rms_deg"] > 1.3 * PHASE_WARN_DEG or r["params"]["amp_rms"] > 1.3 * AMP_WARN
            if clear:
                assert r["warns"], r
