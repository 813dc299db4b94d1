"""The physics posterior on a learned model's lattice: its quantiles against closed forms, its resolution checks,
and a planted learned template's H/r and mass inside its 95 % intervals."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.stats import norm

from spiralbayes.axisymmetric import AxisymmetricModel
from spiralbayes.exceptions import InputError
from spiralbayes.inference.posterior import MassPrior, Priors
from spiralbayes.inference.posterior.physics import DEFAULT_AGES, PhysicsPosterior, default_ages, physics_posterior
from spiralbayes.templates.learned import LearnedTemplateModel, read_training_runs, reference_files
from tests._support.mass_setup import plant
from tests._support.posterior_setup import R_RANGE, TRUE_GEOMETRY, profile

NO_SCATTER = MassPrior(systematic=0.0, mstar_sigma=0.0).to_dict()


MASSES = tuple(np.geomspace(0.1, 3.0, 12))


def lattice_posterior(ln_b_of_h, h, masses=MASSES, ln_b_coarse=None) -> PhysicsPosterior:
    ln_b = np.broadcast_to(np.asarray(ln_b_of_h, float)[:, None, None, None, None, None],
                           (h.size, 1, 1, 1, 1, len(masses))).copy()
    return PhysicsPosterior(h, [1.0], [1e-3], [200.0], np.asarray(masses), ["R"], ln_b, 0.3, ln_b_coarse, NO_SCATTER)


def test_intervals_of_a_gaussian_likelihood_are_its_quantiles():
    h = np.round(np.arange(0.04, 0.12001, 0.001), 6)
    h0, sigma = 0.08, 0.006
    post = lattice_posterior(-0.5 * ((h - h0) / sigma) ** 2, h)
    ci = post.intervals(0.95, n=200000)
    # piecewise-constant density on 0.001 cells: the quantiles within a cell of the Gaussian's
    assert ci["h_p"]["lo"] == pytest.approx(norm.ppf(0.025, h0, sigma), abs=0.001)
    assert ci["h_p"]["hi"] == pytest.approx(norm.ppf(0.975, h0, sigma), abs=0.001)
    assert ci["h_p"]["median"] == pytest.approx(h0, abs=0.0005)
    # a flat likelihood in mass leaves the log-uniform prior: quantiles exp(ln 0.1 + q ln 30)
    for q, key in ((0.025, "lo"), (0.5, "median"), (0.975, "hi")):
        assert ci["M_p"][key] == pytest.approx(np.exp(np.log(0.1) + q * np.log(30.0)), rel=0.02)
    # M_Jup = M_th h^3 M_* / M_Jup with each draw's own h (M_* fixed at 0.8 M_sun here)
    draws = post.draw(1000, seed=3)
    np.testing.assert_allclose(draws["M_p_MJup"], draws["M_p"] * draws["h_p"] ** 3 * 0.8 * 1047.57, rtol=2e-3)
    assert post.resolved("h_p") and post.resolved("mass")


def test_flat_likelihood_gives_the_prior_cells_half_weight_at_the_ends():
    h = np.array([0.05, 0.06, 0.07, 0.08])
    post = lattice_posterior(np.zeros(4), h)
    np.testing.assert_allclose(list(post.marginal("h_p").values()), [1 / 6, 1 / 3, 1 / 3, 1 / 6])
    assert post.ln_bayes_factor == pytest.approx(0.0)
    assert post.marginal("hand") == {"R": pytest.approx(1.0)}


def test_an_interval_narrower_than_three_steps_is_not_resolved():
    h = np.round(np.arange(0.05, 0.1001, 0.005), 6)
    narrow = lattice_posterior(-0.5 * ((h - 0.075) / 0.001) ** 2, h)
    wide = lattice_posterior(-0.5 * ((h - 0.075) / 0.008) ** 2, h)
    assert not narrow.resolved("h_p") and wide.resolved("h_p")
    assert "finer lattice" in narrow.summary() and "finer lattice" not in wide.summary()


def test_position_resolution_compares_the_coarse_grid():
    h = np.round(np.arange(0.05, 0.1001, 0.005), 6)
    ln_b = -0.5 * ((h - 0.075) / 0.008) ** 2
    same = lattice_posterior(ln_b, h, ln_b_coarse=lattice_posterior(ln_b, h).ln_bayes)
    elsewhere = -0.5 * ((h - 0.09) / 0.008) ** 2  # the coarse grid's peak two steps away
    moved = lattice_posterior(ln_b, h, ln_b_coarse=lattice_posterior(elsewhere, h).ln_bayes)
    assert same.position_resolved() is True and lattice_posterior(ln_b, h).position_resolved() is None
    assert moved.position_resolved() is False and "does not resolve the planet" in moved.summary()


def test_bad_lattices_are_refused():
    with pytest.raises(InputError, match="must increase"):
        lattice_posterior(np.zeros(3), np.array([0.07, 0.06, 0.08]))
    with pytest.raises(InputError, match="shape"):
        PhysicsPosterior([0.07], [1.0], [1e-3], [200.0], [1.0], ["R"], np.zeros((2, 1, 1, 1, 1, 1)), 0.3)
    with pytest.raises(InputError, match="unknown axis"):
        lattice_posterior(np.zeros(2), np.array([0.06, 0.07])).marginal("beta")


class _Box:
    def __init__(self, lo: float, hi: float):
        self.bounds = {"orbits": (lo, hi)}


def test_the_default_ages_are_those_inside_the_models_box():
    assert default_ages(_Box(20.0, 1000.0)) == DEFAULT_AGES == (20.0, 200.0, 1000.0)
    assert default_ages(_Box(20.0, 500.0)) == (20.0, 200.0)
    assert default_ages(_Box(40.0, 40.0)) == (40.0,)  # none inside: the box's own age


@pytest.fixture(scope="module")
def model() -> LearnedTemplateModel:
    return LearnedTemplateModel.fit(read_training_runs(reference_files()), restarts=0)


def test_a_planted_learned_planets_aspect_ratio_and_mass_lie_in_the_95_percent_intervals(model, tmp_path):
    """Reference: the planted template's own (M_p, H/r), between lattice values (1.5 M_th at H/r 0.0725),
    in the weak observation (the planet alone at χ² 400)."""
    truth = model.predict(1.5, 0.0725, 1.0, 1e-3, 200.0, 0.3)
    vis = plant(truth, snr2=400.0)
    axisym = AxisymmetricModel.from_profile(profile, TRUE_GEOMETRY, N=80)
    kwargs = dict(h_p=[0.06, 0.065, 0.07, 0.075, 0.08, 0.085], slope=1.0, alpha=1e-3, orbits=200.0,
                  masses=[0.5, 1.0, 2.0, 3.0], priors=Priors.default(axisym, r_p=R_RANGE), progress=False,
                  cache_dir=tmp_path, mass_prior=MassPrior(mass_range=(0.5, 3.0)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        post = physics_posterior(vis, axisym, model, 0.3, r_p=np.linspace(0.25, 0.45, 41), **kwargs)
        coarse = physics_posterior(vis, axisym, model, 0.3, r_p=np.linspace(0.2, 0.5, 11), n_phi_p=60, refine=0,
                                   **kwargs)
        refined = physics_posterior(vis, axisym, model, 0.3, r_p=np.linspace(0.2, 0.5, 11), n_phi_p=60, **kwargs)
    ci = post.intervals(0.95)
    print(post.summary(), refined.provenance["position_levels"], sep="\n")
    assert post.position_resolved() is True and coarse.position_resolved() is False
    # refined around the peak, the coarse grid's posterior is the fine grid's
    assert refined.position_resolved() is True and len(refined.provenance["position_levels"]) > 1
    for axis in ("h_p", "mass"):
        fine, ref = np.array(list(post.marginal(axis).values())), np.array(list(refined.marginal(axis).values()))
        assert 0.5 * np.abs(fine - ref).sum() < 0.05, (axis, fine, ref)
    assert ci["h_p"]["lo"] <= 0.0725 <= ci["h_p"]["hi"] and ci["h_p"]["hi"] - ci["h_p"]["lo"] < 0.02
    assert ci["M_p"]["lo"] <= 1.5 <= ci["M_p"]["hi"]
    assert post.marginal("hand")["R"] > 0.99 and post.ln_bayes_factor > 50
    loaded = PhysicsPosterior.load(post.save(tmp_path / "physics.h5"))
    assert loaded.summary() == post.summary() and loaded.best == post.best
    with pytest.raises(InputError, match="outside the box"):
        physics_posterior(vis, axisym, model, 0.3, h_p=[0.2], progress=False, cache_dir=tmp_path)
