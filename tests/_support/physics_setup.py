"""A FARGO3D physics-set planet held out of the learned model, planted in the weak observation, and its physics
posterior — shared by ``tests/inference/posterior/test_physics_held_out.py`` and ``tools/physics_held_out.py``.

Each run's own reduced map is planted with the exact type-3 transform in the weak observation's disc
(1500 baselines, the planet alone at χ² = 400, ``mass_setup.plant``); the learned model is fitted without
that run; :func:`~spiralbayes.inference.posterior.physics.physics_posterior` scans :data:`H_P` (H/r
0.05–0.11 every 0.005), the learned bank's three slopes and viscosities, the ages :data:`ORBITS` (the
runs are 20 orbits old but one, 500), :data:`MASSES` and the planted hand (2106 templates) on 41 radii
over 0.25–0.45″ and 360 azimuths, with the default template-mismatch scatter.
"""

from __future__ import annotations

import warnings

import h5py
import numpy as np

from spiralbayes.axisymmetric import AxisymmetricModel
from spiralbayes.inference.posterior import MassPrior, Priors
from spiralbayes.inference.posterior.physics import DEFAULT_AGES, PhysicsPosterior, physics_posterior
from spiralbayes.templates import SpiralTemplate
from spiralbayes.templates.learned import LearnedTemplateModel, TrainingRun, read_training_runs, reference_files
from tests._support.mass_setup import plant
from tests._support.posterior_setup import R_RANGE, TRUE_GEOMETRY, profile

RUNS = ("physics:h0.06_mu0.5", "physics:h0.07_mu1_nu1e-04", "physics:h0.07_mu1_nu1e-06", "physics:h0.07_mu1_orbits500",
        "physics:h0.07_mu1_slope0.5", "physics:h0.07_mu1_slope1.5", "physics:h0.08_mu2")
"""The physics set's runs (Σ ∝ r^-0.5 and r^-1.5, α 2e-4 and 2e-2, 0.5 M_th at H/r 0.06, 2 M_th at H/r
0.08, the 1 M_th planet after 500 orbits)."""
TAUS = (0.3, 3.0)
H_P = np.round(np.arange(0.05, 0.1101, 0.005), 4)
MASSES = np.geomspace(0.3, 3.0, 6)
ORBITS = DEFAULT_AGES
R_P_GRID = np.linspace(0.25, 0.45, 41)


def planted(run: TrainingRun, tau0: float):
    """The weak observation with ``run``'s own map at ``tau0`` planted."""
    with h5py.File(run.file, "r") as f:
        delta = f[f"{run.group}/delta_tau{tau0:g}"][()].astype(float)
    return plant(SpiralTemplate(x=run.x, phi=run.phi, delta=delta, mass=run.mass, tau0=tau0, beta=0.0, h_p=run.h_p,
                                name="held_out"))


def held_out_posterior(name: str, tau0: float, cache_dir) -> tuple[TrainingRun, PhysicsPosterior]:
    """Run ``name`` (e.g. ``"physics:h0.08_mu2"``) and its physics posterior, the model fitted without it."""
    runs = read_training_runs(reference_files())
    run = next(r for r in runs if r.name == name)
    model = LearnedTemplateModel.fit([r for r in runs if r.name != name])
    axisym = AxisymmetricModel.from_profile(profile, TRUE_GEOMETRY, N=80)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        post = physics_posterior(planted(run, tau0), axisym, model, tau0, h_p=H_P, masses=MASSES, orbits=ORBITS,
                                 hands="R", priors=Priors.default(axisym, r_p=R_RANGE), mass_prior=MassPrior(),
                                 r_p=R_P_GRID, cache_dir=cache_dir, progress=False)
    return run, post
