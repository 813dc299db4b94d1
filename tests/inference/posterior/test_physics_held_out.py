"""Hydrodynamic planets the learned model never saw: H/r and mass in the physics posterior's 95 % intervals.

Reference: every run of the FARGO3D ``physics`` set (tests/data/references/physics: Σ ∝ r^-0.5 and r^-1.5,
α 2e-4 and 2e-2, 0.5 M_th at H/r 0.06, 2 M_th at H/r 0.08, the 1 M_th planet after 500 orbits) at τ0 0.3
and 3 — each run's own reduced map planted with the exact type-3 transform in the weak observation's
disc (1500 baselines, the planet alone at χ² = 400). The learned model is fitted without that run;
:func:`~spiralbayes.inference.posterior.physics.physics_posterior` scans H/r 0.05–0.11 every 0.005,
the learned bank's three slopes and viscosities, six masses and both hands (1404 templates), with the
default template-mismatch scatter. About 5–10 minutes a case on 2 cores.
"""

from __future__ import annotations

import warnings

import h5py
import numpy as np
import pytest

from spiralbayes.axisymmetric import AxisymmetricModel
from spiralbayes.inference.posterior import MassPrior, Priors
from spiralbayes.inference.posterior.physics import physics_posterior
from spiralbayes.templates import SpiralTemplate
from spiralbayes.templates.learned import LearnedTemplateModel, read_training_runs, reference_files
from tests._support.mass_setup import plant
from tests._support.posterior_setup import R_RANGE, TRUE_GEOMETRY, profile

pytestmark = pytest.mark.slow

RUNS = ("physics:h0.06_mu0.5", "physics:h0.07_mu1_nu1e-04", "physics:h0.07_mu1_nu1e-06", "physics:h0.07_mu1_orbits500",
        "physics:h0.07_mu1_slope0.5", "physics:h0.07_mu1_slope1.5", "physics:h0.08_mu2")
H_P = np.round(np.arange(0.05, 0.1101, 0.005), 4)


def _planted(run, tau0: float):
    with h5py.File(run.file, "r") as f:
        delta = f[f"{run.group}/delta_tau{tau0:g}"][()].astype(float)
    return plant(SpiralTemplate(x=run.x, phi=run.phi, delta=delta, mass=run.mass, tau0=tau0, beta=0.0, h_p=run.h_p,
                                name="held_out"))


@pytest.mark.parametrize("tau0", [0.3, 3.0])
@pytest.mark.parametrize("held_out", RUNS)
def test_held_out_planets_aspect_ratio_and_mass_lie_in_the_95_percent_intervals(held_out, tau0, tmp_path):
    runs = read_training_runs(reference_files())
    run = next(r for r in runs if r.name == held_out)
    model = LearnedTemplateModel.fit([r for r in runs if r.name != held_out])
    axisym = AxisymmetricModel.from_profile(profile, TRUE_GEOMETRY, N=80)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        post = physics_posterior(_planted(run, tau0), axisym, model, tau0, h_p=H_P, masses=np.geomspace(0.3, 3.0, 6),
                                 priors=Priors.default(axisym, r_p=R_RANGE), mass_prior=MassPrior(),
                                 r_p=np.linspace(0.25, 0.45, 41), cache_dir=tmp_path, progress=False)
    ci = post.intervals(0.95)
    print(f"{held_out} tau0 {tau0}: truth M_p {run.mass:g}, H/r {run.h_p:g}\n{post.summary()}")
    assert post.position_resolved() is True
    assert post.marginal("hand")["R"] > 0.95
    assert ci["h_p"]["lo"] <= run.h_p <= ci["h_p"]["hi"], ci["h_p"]
    assert ci["M_p"]["lo"] <= run.mass <= ci["M_p"]["hi"], ci["M_p"]
