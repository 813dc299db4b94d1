"""Posterior sampling: fast likelihood vs exact, planet recovery, resume, convergence policy, priors.

A synthetic observation (seeded): 3000 random baselines up to 2 Mlambda, a smooth exponential
disc, a strong right-handed 3 M_th template planted with the exact type-3 NUFFT
(:func:`spiralbayes.model.perturbation_visibilities`), Gaussian noise. The sampler starts from a
geometry off by 20 mas in RA and 2 deg in inclination (the "frank geometry" of the test)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from spiralbayes.exceptions import ConvergenceWarning
from spiralbayes.inference.likelihood import PARAMETER_NAMES
from spiralbayes.inference.priors import Priors
from spiralbayes.inference.sampler import (
    _initial_walkers,
    sample_posterior,
)
from tests.posterior_setup import R_RANGE, START_GEOMETRY, TRUTH


def test_posterior_recovers_planet_geometry_and_hand(setup, tmp_path):
    template = setup["template"]
    mirror = template.mirror()
    result = sample_posterior(setup["vis"], setup["model"], [template, mirror], priors=setup["priors"],
                              run_name="recover", chains_dir=tmp_path, n_walkers=24, n_steps=700,
                              mcmc_templates=[template.name], convergence="ignore", evidence_draws=600, seed=3)
    run = result.run(template.name)
    summary = run.summary()
    for j, name in enumerate(PARAMETER_NAMES):
        z = (TRUTH[j] - summary[name]["median"]) / summary[name]["std"]
        assert abs(z) < 2.0, (name, summary[name], TRUTH[j])
    # the start geometry (20 mas, 2 deg off) is excluded
    assert abs(summary["dRA"]["median"] - START_GEOMETRY.dRA) > 5 * summary["dRA"]["std"]
    assert abs(summary["inc"]["median"] - START_GEOMETRY.inc) > 3 * summary["inc"]["std"]
    assert result.p_right_handed > 0.99
    assert result.best.name == template.name
    marg = result.marginals()
    assert set(marg) == {"hand", "mass", "beta", "tau0", "h_p"}
    assert marg["mass"][3.0] == pytest.approx(1.0)
    assert marg["h_p"] == {template.h_p: pytest.approx(1.0)}
    # two evidence estimators agree for a well-sampled unimodal posterior
    assert abs(run.ln_evidence - run.ln_evidence_laplace) < 1.0
    assert run.diagnostics["tau_max"] > 0 and "arviz" in run.diagnostics
    assert run.diagnostics["arviz"]["r_p"]["r_hat"] < 1.1
    # plots and persistence
    from spiralbayes.plotting.posterior import (
        plot_corner,
        plot_template_probabilities,
        plot_trace,
    )

    fig = plot_corner(result, truths=dict(zip(PARAMETER_NAMES, TRUTH)))
    fig.savefig(tmp_path / "corner.png")
    assert plot_trace(result).axes and plot_template_probabilities(result).axes
    loaded = type(result).load(result.save(tmp_path / "posterior.h5"))
    assert loaded.template_probabilities == pytest.approx(result.template_probabilities)
    np.testing.assert_allclose(loaded.run(template.name).samples, run.samples)
    # the optional refit: frank again at the posterior geometry, same hyperparameters
    from spiralbayes.inference.sampler import refit_axisymmetric

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        refit = refit_axisymmetric(setup["vis"], setup["model"], result)
    assert refit.geometry.inc == pytest.approx(summary["inc"]["median"])
    assert refit.geometry.dRA == pytest.approx(summary["dRA"]["median"])
    assert refit.hyperparameters["N"] == 200 and refit.Rmax == 1.2


def test_resume_continues_the_same_chain_and_short_run_warns(setup, tmp_path):
    kwargs = dict(priors=setup["priors"], n_walkers=14, evidence_draws=50, seed=5)
    t = setup["template"]
    with pytest.warns(ConvergenceWarning, match="more steps"):
        full = sample_posterior(setup["vis"], setup["model"], t, run_name="full", chains_dir=tmp_path / "a",
                                n_steps=40, **kwargs)
    with pytest.warns(ConvergenceWarning):
        sample_posterior(setup["vis"], setup["model"], t, run_name="part", chains_dir=tmp_path / "b",
                         n_steps=20, **kwargs)  # "interrupted" after 20 steps
    with pytest.warns(ConvergenceWarning):
        resumed = sample_posterior(setup["vis"], setup["model"], t, run_name="part", chains_dir=tmp_path / "b",
                                   n_steps=40, **kwargs)  # asks for 40 in total: runs the remaining 20
    a, b = full.runs[0].chain(discard=0, thin=1), resumed.runs[0].chain(discard=0, thin=1)
    assert a.shape == b.shape == (40, 14, 6)
    np.testing.assert_allclose(a, b)  # identical to the uninterrupted run (same random stream)
    # different inputs refuse to resume
    other = Priors(R_RANGE, (41.0, 5.0), (70.0, 5.0), (0.025, 0.05), (-0.01, 0.05))
    with pytest.raises(ValueError, match="different inputs"):
        sample_posterior(setup["vis"], setup["model"], t, run_name="part", chains_dir=tmp_path / "b",
                         n_steps=60, **{**kwargs, "priors": other})


def test_walkers_never_start_at_minus_inf():
    priors = Priors(R_RANGE, (40, 5), (70, 5), (0, 0.05), (0, 0.05))

    def logpost(theta):
        return priors.log_prior(theta)

    rng = np.random.default_rng(0)
    centre = priors.centre
    cov = np.diag((priors.widths * 0.01) ** 2)
    p0 = _initial_walkers(logpost, centre, cov, priors, 12, rng)
    assert np.all(np.isfinite([logpost(p) for p in p0]))
    bad = np.tile(centre, (12, 1))
    bad[3, 0] = 5.0  # r_p outside the prior
    with pytest.raises(ValueError, match="walker 3"):
        _initial_walkers(logpost, centre, cov, priors, 12, rng, initial=bad)
