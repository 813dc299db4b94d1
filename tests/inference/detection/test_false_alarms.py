"""Nested test 3's threshold against look-elsewhere (slow): planet-free, impostor and gain-error data.

Seven kinds × :data:`~tests.inference.detection.false_alarms.N_PER_KIND` reduced fiducial datasets
(:mod:`tests.inference.detection.false_alarms`; 350 in all): no planet may be claimed, and the
nested ΔBIC of the scan's best peak must stay below the default threshold on every one (the
measured table is in docs/verdict.md).
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
    assert largest["nested_delta_bic"] <= DetectionSettings().nested_threshold, largest
