"""Nested test 3's threshold against look-elsewhere (slow): planet-free, impostor and gain-error data.

Seven kinds × :data:`~tests.inference.detection.false_alarms.N_PER_KIND` reduced fiducial datasets
(:mod:`tests.inference.detection.false_alarms`; 350 in all): no planet may be claimed, and where
tests 1 and 2 pass (where test 3 decides) the nested ΔBIC of the scan's best peak must stay below
the default threshold. Not for gain errors: there it exceeded the threshold once in 50 (seed 11042,
3.2° rms, 64.3 against the geometry model), and the geometry rule (no claim while a geometry error
survives beside the spiral; the rescan at the fitted geometry then fails test 2) is what holds; the
measured table is in docs/verdict.md.
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
