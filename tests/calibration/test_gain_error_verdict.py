"""``spiralbayes scan`` with ``[calibration] solve = "phase"`` on the fiducial observation with 30 deg rms
antenna phase errors (3-minute coherence) and 5 % amplitudes (slow, ~4 min): the set-up of
``tools/calibration_table.py`` and of docs/calibration.md ("The second solve"). A 1 M_th planet (compromise
template τ0 3, β 10, 50 au, φ_p 0) is claimed after the geometry refit, at the right mass and place; the
same observation without the planet claims nothing. With one solve (``candidate_min_snr = 0``) the planet
was lost (docs/calibration.md, "One solve only")."""

import numpy as np
import pytest

from spiralbayes.config import merge_config
from spiralbayes.io import save_visibilities
from spiralbayes.pipeline import run_scan
from spiralbayes.simulate import GainErrors, simulate_observation
from spiralbayes.templates import make_template

DISTANCE, R_P_AU = 140.0, 50.0


def _run(tmp_path, planet: bool):
    template = make_template(1.0, 3.0, 10.0, "R") if planet else None
    vis = simulate_observation("fiducial", perturbation=template, r_p=R_P_AU / DISTANCE if planet else None,
                               phi_p=0.0 if planet else None, seed=1,
                               gains=GainErrors(30.0, 0.05, coherence_s=180.0, amp_coherence_s=600.0, seed=1))
    name = "planet" if planet else "free"
    data = save_visibilities(vis, tmp_path / f"{name}.h5")
    config = merge_config({"data": {"path": str(data)}, "geometry": {"inc": 30.0, "PA": 60.0, "distance": DISTANCE},
                           "calibration": {"solve": "phase"}, "templates": {"tau0": [3.0]},
                           "output": {"dir": str(tmp_path / name), "plots": False}})
    return run_scan(config, progress=False)


@pytest.mark.slow
def test_a_planet_under_30_deg_phase_errors_is_found_and_a_planet_free_disc_gives_nothing(tmp_path):
    run = _run(tmp_path, planet=True)
    verdict = run.follow_up.verdict if run.follow_up is not None else run.verdict
    assert verdict.detected, verdict.summary()
    best = run.scan.templates[run.scan.template_index(verdict.template)]
    step = float(np.median(np.diff(run.scan.r_p)))
    assert float(best["mass"]) == 1.0
    assert abs(verdict.r_p - R_P_AU / DISTANCE) <= step + 1e-9
    assert abs((verdict.phi_p_deg + 180.0) % 360.0 - 180.0) <= 4.0 + 1e-9
    assert "the scan's best spiral" in (verdict.gains_solved or "")
    free = _run(tmp_path, planet=False)
    assert not free.verdict.detected
    assert free.follow_up is None or not free.follow_up.verdict.detected
