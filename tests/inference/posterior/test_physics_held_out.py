"""Hydrodynamic planets the learned model never saw: H/r and mass in the physics posterior's 95 % intervals.

Reference: every run of the FARGO3D ``physics`` set at τ0 0.3 and 3, planted in the weak observation,
the learned model fitted without it (``tests/_support/physics_setup.py``). About 10 minutes a case on
2 cores; ``tools/physics_held_out.py`` runs the same cases into a table.
"""

from __future__ import annotations

import pytest

from tests._support.physics_setup import RUNS, TAUS, held_out_posterior

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("held_out, tau0", [(run, tau0) for run in RUNS for tau0 in TAUS])
def test_held_out_planets_aspect_ratio_and_mass_lie_in_the_95_percent_intervals(held_out, tau0, tmp_path):
    run, post = held_out_posterior(held_out, tau0, tmp_path)
    ci = post.intervals(0.95)
    print(f"{held_out} tau0 {tau0}: truth M_p {run.mass:g}, H/r {run.h_p:g}\n{post.summary()}")
    assert post.position_resolved() is True
    assert ci["h_p"]["lo"] <= run.h_p <= ci["h_p"]["hi"], ci["h_p"]
    assert ci["M_p"]["lo"] <= run.mass <= ci["M_p"]["hi"], ci["M_p"]
