"""Posterior sampling: fast likelihood vs exact, planet recovery, resume, convergence policy, priors.

A synthetic observation (seeded): 3000 random baselines up to 2 Mlambda, a smooth exponential
disc, a strong right-handed 3 M_th template planted with the exact type-3 NUFFT
(:func:`spiralbayes.model.perturbation_visibilities`), Gaussian noise. The sampler starts from a
geometry off by 20 mas in RA and 2 deg in inclination (the "frank geometry" of the test)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from spiralbayes.exceptions import ConvergenceError, ConvergenceWarning
from spiralbayes.inference.posterior.diagnostics import _apply_policy, convergence_diagnostics


def test_convergence_diagnostics_and_policy():
    rng = np.random.default_rng(0)
    n, walkers = 4000, 16
    chain = np.zeros((n, walkers, 6))
    for t in range(1, n):  # AR(1) with tau = (1 + a) / (1 - a) = 19
        chain[t] = 0.9 * chain[t - 1] + rng.normal(size=(walkers, 6))
    d = convergence_diagnostics(chain)
    assert 12 < d["tau_max"] < 28 and d["converged"]
    short = convergence_diagnostics(chain[:300])
    assert not short["converged"] and short["more_steps"] > 0
    with pytest.raises(ConvergenceError, match="more steps"):
        _apply_policy("raise", "needs 5 more steps")
    with pytest.warns(ConvergenceWarning):
        _apply_policy("warn", "needs 5 more steps")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _apply_policy("ignore", "fine")
