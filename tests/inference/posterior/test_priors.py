"""Posterior sampling: fast likelihood vs exact, planet recovery, resume, convergence policy, priors.

A synthetic observation (seeded): 3000 random baselines up to 2 Mlambda, a smooth exponential
disc, a strong right-handed 3 M_th template planted with the exact type-3 NUFFT
(:func:`spiralbayes.model.perturbation_visibilities`), Gaussian noise. The sampler starts from a
geometry off by 20 mas in RA and 2 deg in inclination (the "frank geometry" of the test)."""

from __future__ import annotations

import pytest

from spiralbayes.inference.posterior.priors import Priors
from spiralbayes.inference.posterior.sampler import (
    sample_posterior,
)


def test_bad_priors_raise_clear_errors(setup):
    with pytest.raises(ValueError, match="0 < r_min < r_max"):
        Priors((-0.1, 0.5), (40, 5), (70, 5), (0, 0.05), (0, 0.05))
    with pytest.raises(ValueError, match="0 < r_min < r_max"):
        Priors((0.5, 0.2), (40, 5), (70, 5), (0, 0.05), (0, 0.05))
    with pytest.raises(ValueError, match="width must be a positive"):
        Priors((0.1, 0.5), (40, -5), (70, 5), (0, 0.05), (0, 0.05))
    with pytest.raises(ValueError, match="width must be a positive"):
        Priors.default(setup["model"], widths={"dRA": -0.01})
    with pytest.raises(ValueError, match="unknown prior widths"):
        Priors.default(setup["model"], widths={"incl": 1.0})
    with pytest.raises(ValueError, match="beyond the disc model's extent"):
        Priors((0.1, 2.0), (40, 5), (70, 5), (0, 0.05), (0, 0.05)).check_data(setup["vis"], setup["model"])
    with pytest.raises(ValueError, match="n_walkers"):
        sample_posterior(setup["vis"], setup["model"], setup["template"], priors=setup["priors"], n_walkers=4)
