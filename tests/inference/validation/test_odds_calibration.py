"""Posterior odds between a planet and an arc, small version (slow): planted FARGO3D planets that the data
show and simulated vortex arcs at τ0 0.3 (:mod:`tests.inference.validation.odds_calibration`). The full set
(30 and 30) is ``python -m tests.inference.validation.odds_calibration``; its table is in docs/verdict.md."""

import numpy as np
import pytest

from tests.inference.validation import odds_calibration as oc


@pytest.mark.slow
def test_planets_the_data_show_are_planets_and_arcs_are_arcs(tmp_path):
    planets, arcs = [], []
    index = 0
    while len(planets) < 3 and index < 40:  # the first planets whose own map gives Delta BIC > 30
        row = oc.evaluate("planet", index, tmp_path)
        # gas planets: a dust run's co-orbital clumps look like arcs (docs/verdict.md)
        if row["p"] is not None and "st0" not in row["case"]:
            planets.append(row)
        index += 1
    arcs = [oc.evaluate("arc", i, tmp_path) for i in range(3)]
    p_planet = np.array([r["p"]["planet"] for r in planets])
    p_arc = np.array([r["p"]["planet"] for r in arcs])
    assert len(planets) == 3 and p_planet.mean() >= 0.8, planets
    assert p_arc.mean() <= 0.2, arcs
    assert all(r["p"]["arc/vortex"] > r["p"]["planet"] for r in arcs), arcs
    assert all(sum(r["p"].values()) == pytest.approx(1.0) for r in planets + arcs)
