"""Where each kind of template puts the planet (inference/detection/kinds.py), on hand-built scans."""

import numpy as np
import pytest

from spiralbayes import DiscGeometry
from spiralbayes.inference.detection import best_by_kind, detect
from spiralbayes.inference.scan.run import ScanResult

N_DATA = 36_000
OFFSET = 6 * np.log(N_DATA)  # Δχ² at ΔBIC = 0 (the scan's six parameters)


def _scan(peaks, n_r=6, n_phi=12):
    """Template k has Δχ² ``value`` at ``(i_rp, i_phi)`` and 0 elsewhere; ``peaks``: ``(name, kind, i_rp,
    i_phi, value)`` with kind "generator" or "simulation" (how template_metadata marks a map)."""
    cross = np.zeros((len(peaks), n_r, n_phi))
    meta = []
    for k, (name, kind, i, j, value) in enumerate(peaks):
        cross[k, i, j] = value / 2  # power 0: Δχ² = 2 cross
        meta.append({"name": name, "hand": "R", **({"kind": "simulation"} if kind == "simulation" else {})})
    return ScanResult(meta, np.linspace(0.1, 0.6, n_r), 2 * np.pi * np.arange(n_phi) / n_phi, cross,
                      np.zeros_like(cross), 1e5, N_DATA, DiscGeometry(30.0, 60.0), distance=140.0)


def test_a_scan_of_one_kind_has_no_positions_by_kind():
    assert best_by_kind(_scan([("a", "generator", 2, 5, 300.0), ("b", "generator", 3, 5, 200.0)])) is None
    verdict = detect(_scan([("a", "generator", 2, 5, 300.0)]))
    assert verdict.best_by_kind is None and "peaks elsewhere" not in verdict.summary()


def test_each_kind_reports_its_best_and_its_distance_from_the_verdicts_place():
    result = _scan([("gen_a", "generator", 2, 5, 300.0), ("gen_b", "generator", 1, 1, 250.0),
                    ("map_a", "simulation", 4, 7, 400.0), ("map_b", "simulation", 0, 11, 100.0)])
    kinds = best_by_kind(result)
    assert kinds["simulation"]["template"] == "map_a" and kinds["simulation"]["steps_from_best"] == [0, 0]
    assert kinds["generator"]["template"] == "gen_a" and kinds["generator"]["steps_from_best"] == [2, 2]
    assert kinds["generator"]["delta_bic"] == pytest.approx(300.0 - OFFSET)
    assert kinds["generator"]["r_p"] == pytest.approx(result.r_p[2])
    assert kinds["generator"]["phi_p_deg"] == pytest.approx(150.0)
    verdict = detect(result)
    assert verdict.template == "map_a" and verdict.best_by_kind == kinds
    text = verdict.summary()
    assert "The best generator template (its bank spans H/r), gen_a, peaks elsewhere" in text
    assert "2 radius and 2 azimuth steps from the best simulated map" in text


@pytest.mark.parametrize("where, value", [
    ((4, 8), 300.0),     # one azimuth step: the same place on this grid
    ((2, 5), 70.0),      # elsewhere, but Delta BIC below test 1's 10
    ((2, 5), 220.0),     # elsewhere and significant, but under half the verdict's Delta BIC (157 < 168)
])
def test_no_sentence_when_the_other_kind_agrees_or_is_not_significant(where, value):
    result = _scan([("gen_a", "generator", *where, value), ("map_a", "simulation", 4, 7, 400.0)])
    assert detect(result).best_by_kind is not None
    assert "peaks elsewhere" not in detect(result).summary()


def test_the_azimuth_distance_wraps_around():
    result = _scan([("gen_a", "generator", 3, 11, 300.0), ("map_a", "simulation", 3, 0, 400.0)])
    assert best_by_kind(result)["generator"]["steps_from_best"] == [0, 1]


def test_no_sentence_without_a_significant_spiral():
    result = _scan([("gen_a", "generator", 0, 0, 70.0), ("map_a", "simulation", 4, 7, 60.0)])
    verdict = detect(result)
    assert not verdict.test1_passed and "peaks elsewhere" not in verdict.summary()
