"""Posterior sampling: fast likelihood vs exact, planet recovery, resume, convergence policy, priors.

A synthetic observation (seeded): 3000 random baselines up to 2 Mlambda, a smooth exponential
disc, a strong right-handed 3 M_th template planted with the exact type-3 NUFFT
(:func:`spiralbayes.model.perturbation_visibilities`), Gaussian noise. The sampler starts from a
geometry off by 20 mas in RA and 2 deg in inclination (the "frank geometry" of the test).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from spiralbayes.axisymmetric import AxisymmetricModel
from spiralbayes.geometry import DiscGeometry
from spiralbayes.model import perturbation_visibilities
from spiralbayes.posterior import PARAMETER_NAMES, SpiralLikelihood
from spiralbayes.sampling import (
    ConvergenceError,
    ConvergenceWarning,
    LogPosterior,
    Priors,
    _apply_policy,
    _initial_walkers,
    _wrap_phi,
    convergence_diagnostics,
    sample_posterior,
)
from spiralbayes.templates import make_template
from spiralbayes.visibilities import Visibilities

TRUE_GEOMETRY = DiscGeometry(40.0, 70.0, 0.005, -0.01)
START_GEOMETRY = DiscGeometry(42.0, 70.0, 0.025, -0.01)  # 2 deg and 20 mas off
R_P, PHI_P = 0.35, 2.0
TRUTH = np.array([R_P, PHI_P, 40.0, 70.0, 0.005, -0.01])
R_RANGE = (0.15, 0.6)


def _profile(r):
    r = np.asarray(r, dtype=float)
    return 5e10 * np.exp(-r / 0.3 - (r / 0.8) ** 6)


@pytest.fixture(scope="module")
def setup():
    template = make_template(3.0, 0.3, 0.0, "R", n_x=160, n_phi=360)
    truth_model = AxisymmetricModel.from_profile(_profile, TRUE_GEOMETRY)
    rng = np.random.default_rng(1)
    n = 3000
    q = 2e6 * np.sqrt(rng.uniform(4e-4, 1, n))
    th = rng.uniform(0, 2 * np.pi, n)
    u, v = q * np.cos(th), q * np.sin(th)
    dV = perturbation_visibilities(u, v, TRUE_GEOMETRY, truth_model.brightness, template, R_P, PHI_P)
    sigma = np.sqrt(np.sum(np.abs(dV) ** 2) / 600.0)  # the planet alone: chi2 ~ 600
    V = truth_model.visibilities(u, v, TRUE_GEOMETRY) + dV + sigma * (rng.normal(size=n) + 1j * rng.normal(size=n))
    vis = Visibilities(u, v, V, np.full(n, sigma ** -2))
    model = AxisymmetricModel.from_profile(_profile, START_GEOMETRY)
    priors = Priors.default(model, r_p=R_RANGE)
    return {"vis": vis, "model": model, "template": template, "priors": priors}


@pytest.fixture(scope="module")
def likelihood(setup):
    return SpiralLikelihood(setup["vis"], setup["model"], setup["template"], R_RANGE)


# ------------------------------------------------------------------------------------------------
def test_axisymmetric_table_matches_exact_visibilities(setup, likelihood):
    assert likelihood.axis_table.max_error(setup["model"]) < 1e-6
    g = DiscGeometry(37.0, 65.0, -0.01, 0.02)
    vis = setup["vis"]
    exact = setup["model"].visibilities(vis.u, vis.v, g)
    up, vp = g.deproject_uv(vis.u, vis.v)
    fast = g.cos_inc * likelihood.axis_table(np.hypot(up, vp)) * g.phase_factor(vis.u, vis.v)
    assert np.max(np.abs(fast - exact)) < 1e-6 * np.max(np.abs(exact))


def test_fast_likelihood_matches_exact(setup, likelihood):
    """|Δ ln L| < 0.02 at random points (planet anywhere in the r_p window, geometry within ~2 prior sigma)."""
    rng = np.random.default_rng(7)
    priors = setup["priors"]
    for k in range(6):
        theta = priors.centre + rng.normal(size=6) * priors.widths * np.array([0, 0, 0.4, 0.4, 0.4, 0.4])
        theta[0] = rng.uniform(*R_RANGE)
        theta[1] = rng.uniform(-np.pi, 3 * np.pi)  # beyond 2 pi: periodic
        if k == 0:
            theta = TRUTH.copy()
        fast, exact = likelihood(theta), likelihood.exact_log_likelihood(theta)
        assert abs(fast - exact) < 0.02, (theta, fast, exact)
        V_fast, V_exact = likelihood.model_visibilities(theta), likelihood.exact_model_visibilities(theta)
        assert np.max(np.abs(V_fast - V_exact)) < 1e-4 * np.max(np.abs(V_exact))
    # the planet is detected: ln L(truth) far above the axisymmetric model at the true geometry
    assert likelihood(TRUTH) - likelihood.log_likelihood_axisymmetric(TRUE_GEOMETRY) > 200


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
    assert set(marg) == {"hand", "mass", "beta", "tau0"}
    assert marg["mass"][3.0] == pytest.approx(1.0)
    # two evidence estimators agree for a well-sampled unimodal posterior
    assert abs(run.ln_evidence - run.ln_evidence_laplace) < 1.0
    assert run.diagnostics["tau_max"] > 0 and "arviz" in run.diagnostics
    assert run.diagnostics["arviz"]["r_p"]["r_hat"] < 1.1
    # plots and persistence
    from spiralbayes.plotting.posterior import plot_corner, plot_template_probabilities, plot_trace

    fig = plot_corner(result, truths=dict(zip(PARAMETER_NAMES, TRUTH)))
    fig.savefig(tmp_path / "corner.png")
    assert plot_trace(result).axes and plot_template_probabilities(result).axes
    loaded = type(result).load(result.save(tmp_path / "posterior.h5"))
    assert loaded.template_probabilities == pytest.approx(result.template_probabilities)
    np.testing.assert_allclose(loaded.run(template.name).samples, run.samples)
    # the optional refit: frank again at the posterior geometry, same hyperparameters
    from spiralbayes.sampling import refit_axisymmetric

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


def test_log_posterior_and_phi_wrapping(likelihood, setup):
    lp = LogPosterior(likelihood, setup["priors"])
    assert lp(TRUTH) == pytest.approx(lp(TRUTH + np.array([0, 2 * np.pi, 0, 0, 0, 0])), abs=1e-6)
    outside = TRUTH.copy()
    outside[0] = 0.7
    assert lp(outside) == -np.inf
    samples = np.zeros((100, 6))
    samples[:, 1] = np.r_[np.full(50, 0.05), np.full(50, 2 * np.pi - 0.05)]
    wrapped, mu = _wrap_phi(samples)
    assert np.ptp(wrapped[:, 1]) == pytest.approx(0.1)


def test_cli_sample_from_toml_config(setup, tmp_path):
    """`spiralbayes sample CONFIG` writes chains under OUT/chains/<run_name>.h5 and a summary."""
    import json

    from spiralbayes.cli import main
    from spiralbayes.templates import TemplateBank
    from spiralbayes.visibilities import save_visibilities

    save_visibilities(setup["vis"], tmp_path / "obs.h5")
    setup["model"].save(tmp_path / "axisym.h5")
    template = setup["template"]
    TemplateBank([template, template.mirror()]).save(tmp_path / "bank.h5")
    (tmp_path / "run.toml").write_text(
        'data = "obs.h5"\naxisymmetric = "axisym.h5"\ntemplates = "bank.h5"\nrun_name = "cli"\n'
        f"[priors]\nr_p = [{R_RANGE[0]}, {R_RANGE[1]}]\ninc = [42.0, 3.0]\nPA = [70.0, 3.0]\n"
        "dRA = [0.025, 0.03]\ndDec = [-0.01, 0.03]\n"
        '[sampler]\nn_walkers = 16\nn_steps = 40\nconvergence = "ignore"\nevidence_draws = 200\n')
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["-q", "sample", str(tmp_path / "run.toml"), "--out", str(tmp_path / "out")]) == 0
    assert (tmp_path / "out" / "chains" / "cli.h5").exists()
    summary = json.loads((tmp_path / "out" / "cli_summary.json").read_text())
    assert "summary" in summary
    assert (tmp_path / "out" / "cli_corner.png").exists()
    (tmp_path / "bad.toml").write_text('data = "obs.h5"\nbogus = 1\n')
    assert main(["sample", str(tmp_path / "bad.toml")]) == 2
