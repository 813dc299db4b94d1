"""What the learned model's tests share: the reference files it is fitted on and the runs' own maps."""

from __future__ import annotations

import h5py

from spiralbayes.templates import SpiralTemplate
from spiralbayes.templates.learned import TrainingRun

from .. import fidelity as F

FILES = (F.REF_DIR / "continuum" / "fargo3d_continuum.h5", F.REF_DIR / "fargo3d_library.h5", F.PHYSICS_FILE,
         F.REF_DIR / "fargo3d_isothermal.h5")
"""The continuum design, the library, the ``physics`` set and the two older runs."""


def run_named(runs, name) -> TrainingRun:
    return next(r for r in runs if r.name == name)


def reference(run: TrainingRun, tau0: float) -> SpiralTemplate:
    """The run's own reduced δ map at ``tau0`` (hand R)."""
    with h5py.File(run.file, "r") as f:
        delta = f[f"{run.group}/delta_tau{tau0:g}"][()]
    return SpiralTemplate(x=run.x, phi=run.phi, delta=delta, mass=run.mass, tau0=tau0, beta=0.0, h_p=run.h_p)
