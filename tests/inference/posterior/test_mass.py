"""The planet mass as a sampled parameter (:mod:`spiralbayes.inference.posterior.mass`).

References: the fast family perturbation against a table built for the family's interpolated template
itself (that table is checked against the exact type-3 transform in ``test_perturbation.py``); the family
likelihood at a node mass against the fixed-template likelihood of that node; the M_Jup conversion
against :func:`spiralbayes.units.thermal_mass`. The run end to end on a planted 0.5 M_th planet (a mass
the bank does not hold) is in :func:`test_continuous_run_end_to_end`; the slow planted-mass checks are in
``test_mass_recovery.py``.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from spiralbayes.axisymmetric import AxisymmetricModel
from spiralbayes.exceptions import InputError
from spiralbayes.inference.posterior import (
    MASS_SAMPLE_NAMES,
    MASS_SYSTEMATIC,
    FamilyPerturbation,
    MarginalSpiralLikelihood,
    MassLikelihood,
    MassPrior,
    PriorSettings,
    Priors,
    ProfileMarginal,
    SamplingSettings,
    family_of,
    group_families,
)
from spiralbayes.inference.posterior.perturbation import FastPerturbation
from spiralbayes.inference.posterior.sampler import sample_posterior
from spiralbayes.templates import make_template
from spiralbayes.units import thermal_mass
from tests._support.mass_setup import GRID, bank_members, planted_observation
from tests._support.posterior_setup import R_RANGE, TRUE_GEOMETRY, profile

TABLES = {"rp_tolerance": 0.05}


@pytest.fixture(scope="module")
def case():
    vis = planted_observation(0.5).standardised()
    model = AxisymmetricModel.from_profile(profile, TRUE_GEOMETRY, N=80)
    return vis, model


@pytest.mark.parametrize("hand", ["R", "L"])
def test_family_perturbation_is_the_interpolated_templates_table(case, hand):
    vis, model = case
    family = family_of(make_template(1.0, 0.3, 0.0, hand, **GRID))
    fp = FamilyPerturbation(vis.u, vis.v, vis.weights, model.brightness, family, R_RANGE, TRUE_GEOMETRY, **TABLES)
    w = vis.weights
    for mass, r_p, phi_p in (((0.2, 0.3, 0.4), (2.0, 0.45, 5.5)) if hand == "R" else ((0.5, 0.35, 2.0),)):
        fast = fp.disc_frame(r_p, phi_p, 40.0, 70.0, mass)
        ref = FastPerturbation(vis.u, vis.v, w, model.brightness, family.at(mass), R_RANGE, TRUE_GEOMETRY,
                               refine_from=fp._right[family.masses.size - 1],  # the nodes' r_p step
                               **TABLES).disc_frame(r_p, phi_p, 40.0, 70.0)
        norm = np.sqrt(np.sum(w * np.abs(ref) ** 2))
        assert norm > 0.5  # the spiral is far above the noise: the comparison means something
        assert np.sqrt(np.sum(w * np.abs(fast - ref) ** 2)) < 1e-5 * norm
    assert len(fp.tables) <= 12  # only the nodes next to the masses asked for were built


def test_mass_likelihood_at_a_node_is_the_node_templates_likelihood(case):
    vis, model = case
    family = family_of(make_template(1.0, 0.3, 0.0, "R", **GRID))
    base = ProfileMarginal(vis, model)
    fp = FamilyPerturbation(vis.u, vis.v, vis.weights, model.brightness, family, R_RANGE, TRUE_GEOMETRY, **TABLES)
    j = 20
    node = family.node(j)
    mass = MassLikelihood(base, fp)
    mass.amplitude_terms(np.array([0.35, 2.0, 40.0, 70.0, 0.0, 0.0, np.log(family.masses[j])]))
    fixed = MarginalSpiralLikelihood(base, FastPerturbation(vis.u, vis.v, vis.weights, model.brightness, node,
                                                            R_RANGE, TRUE_GEOMETRY, **TABLES,
                                                            refine_from=fp._right[family.masses.size - 1]))
    theta = np.array([0.35, 2.0, 40.0, 70.0, 0.005, -0.01])
    a = fixed.amplitude_terms(theta)
    b = mass.amplitude_terms(np.append(theta, np.log(family.masses[j])))
    assert abs(a[1]) > 50  # the planted planet: a large cross term
    np.testing.assert_allclose(b, a, rtol=1e-5, atol=1e-6)


def test_mass_prior_density_and_jupiter_masses():
    prior = MassPrior((0.1, 3.0), mstar=1.2, mstar_sigma=0.0)
    x = np.linspace(np.log(0.05), np.log(6.0), 200001)
    dens = np.exp([prior.log_prior(v) for v in x])
    assert np.trapezoid(dens, x) == pytest.approx(1.0, rel=1e-3)
    mj = prior.to_mjup(np.array([0.5, 2.0]), 0.07, np.random.default_rng(0))
    ref = np.array([0.5, 2.0]) * thermal_mass(50.0, 1.2, h_ref=0.07, r_ref=50.0, unit="Mjup")
    np.testing.assert_allclose(mj, ref, rtol=1e-12)
    draws = MassPrior(mstar=0.8).draw_mstar(20000, np.random.default_rng(1))
    assert draws.mean() == pytest.approx(0.8, abs=0.003) and draws.std() == pytest.approx(0.08, rel=0.03)


def test_families_group_the_bank_by_morphology_and_refuse_foreign_templates():
    members = bank_members("R") + bank_members("L")
    groups = group_families(members, MassPrior())
    assert [f.hand for f, _ in groups] == ["R", "L"] and all(len(m) == 4 for _, m in groups)
    other = make_template(1.0, 0.3, 0.0, "R", **GRID)
    from dataclasses import replace

    with pytest.raises(InputError, match="not made by the built-in generator"):
        family_of(replace(other, provenance={}))
    with pytest.raises(InputError, match="does not remake it"):
        family_of(replace(other, delta=other.delta * 1.1))


def test_the_planet_mass_is_the_template_mass_with_the_mismatch_scatter():
    rng = np.random.default_rng(3)
    template_mass = np.full(40000, 0.8)
    same, mjup = MassPrior(mstar_sigma=0.0, systematic=0.0).planet_masses(template_mass, 0.07, rng)
    np.testing.assert_array_equal(same, template_mass)
    np.testing.assert_allclose(mjup / same, thermal_mass(50.0, 0.8, h_ref=0.07, r_ref=50.0, unit="Mjup"), rtol=1e-12)
    mass, mjup = MassPrior(mstar_sigma=0.0, systematic=0.3).planet_masses(template_mass, 0.07, rng)
    ln_ratio = np.log(mass / template_mass)
    assert ln_ratio.mean() == pytest.approx(0.0, abs=0.006) and ln_ratio.std() == pytest.approx(0.3, rel=0.02)
    np.testing.assert_allclose(mjup / mass, thermal_mass(50.0, 0.8, h_ref=0.07, r_ref=50.0, unit="Mjup"), rtol=1e-12)
    with pytest.raises(InputError, match="systematic"):
        MassPrior(systematic=-0.1)


def test_settings_name_the_mass_options():
    with pytest.raises(InputError, match="mass = 'grid'"):
        SamplingSettings(mass="grid")
    with pytest.raises(InputError, match="mass_min"):
        PriorSettings(mass_min=-1.0)
    with pytest.raises(InputError, match="mass_max"):
        PriorSettings(mass_min=1.0, mass_max=0.5)
    with pytest.raises(InputError, match="mstar_sigma"):
        PriorSettings(mstar_sigma=-0.1)
    with pytest.raises(InputError, match="mass_systematic"):
        PriorSettings(mass_systematic=float("nan"))
    assert PriorSettings(mass_systematic=0.0).mass_prior().systematic == 0.0
    assert PriorSettings(mstar=1.0, mstar_sigma=0.2).mass_prior().sigma == pytest.approx(0.2)


def test_continuous_run_end_to_end(case, tmp_path):
    """A short run on the planted 0.5 M_th planet with both hands' families (9 mass nodes over 0.2-1.5
    M_th): the mass is sampled and reported in M_th and M_Jup, the mirror family shares the tables."""
    vis, model = case
    families = [family_of(make_template(1.0, 0.3, 0.0, hand, **GRID), (0.2, 1.5), n_masses=9) for hand in "RL"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        post = sample_posterior(vis, model, families,
                                priors=Priors.default(model, r_p=R_RANGE),
                                mass="continuous", mass_prior=MassPrior((0.2, 1.5)), chains_dir=tmp_path,
                                n_walkers=16, n_steps=80, evidence_draws=120, progress=False, convergence="ignore",
                                likelihood_kwargs=TABLES, seed=2)
    run = post.best
    assert run.continuous_mass and run.sample_names == MASS_SAMPLE_NAMES and len(post.runs) == 2
    assert run.name == "wake_mcont_tau0.3_b0_h0.07_R" and post.p_right_handed > 0.99
    left = post.run("wake_mcont_tau0.3_b0_h0.07_L")
    # the mirror family reads the right-handed family's node tables, building only nodes its own walkers reach first
    assert left.diagnostics["build_time_s"] < 0.5 * run.diagnostics["build_time_s"]
    assert post.planet_preferred and "M_p sampled" in post.verdict
    m = run.samples[:, 7]
    ratio = run.samples[:, 8] / m  # M_Jup per M_th: h_p^3 M_* with M_* ~ N(0.8, 0.08)
    per_mth = thermal_mass(50.0, 0.8, h_ref=0.07, r_ref=50.0, unit="Mjup")
    assert np.mean(ratio) == pytest.approx(per_mth, rel=0.03) and np.std(ratio) / per_mth == pytest.approx(0.1, rel=0.3)
    idata = post.to_inference_data()
    assert {"M_p", "M_p_MJup", "lnM_p"} <= set(idata.posterior.data_vars)
    template_mass = np.exp(idata.posterior["lnM_p"].values)
    assert template_mass.min() >= 0.2 and template_mass.max() <= 1.5
    # the planet's mass is the template's scattered by the mismatch systematic, and only by it
    scatter = np.log(idata.posterior["M_p"].values / template_mass).ravel()
    assert abs(scatter.mean()) < 4 * MASS_SYSTEMATIC / np.sqrt(scatter.size)
    assert scatter.std() == pytest.approx(MASS_SYSTEMATIC, rel=4 / np.sqrt(2 * scatter.size))
    summary = post.mass_posterior()
    assert summary["mth"]["lo95"] <= summary["mth"]["median"] <= summary["mth"]["hi95"]
    # the chain file resumes: a second call reads the finished family back
    again = sample_posterior(vis, model, families,
                             priors=Priors.default(model, r_p=R_RANGE),
                             mass="continuous", mass_prior=MassPrior((0.2, 1.5)), chains_dir=tmp_path, n_walkers=16,
                             n_steps=80, evidence_draws=120, progress=False, convergence="ignore",
                             likelihood_kwargs=TABLES, seed=2)
    np.testing.assert_array_equal(again.best.samples, run.samples)
    from spiralbayes.plotting import plot_corner

    fig = plot_corner(post, truths={"M_p": 0.5, "r_p": 0.35})
    assert any("M_{th}" in ax.get_xlabel() or "M_th" in ax.get_xlabel() for ax in fig.axes)


def test_a_family_is_taken_as_it_is_and_must_hold_the_prior(case, tmp_path):
    vis, model = case
    family = family_of(make_template(1.0, 0.3, 0.0, "R", **GRID), mass_range=(0.2, 2.0), n_masses=9)
    assert group_families([family], MassPrior((0.3, 1.0))) == [(family, [])]
    with pytest.raises(InputError, match="build the family over the prior's range"):
        group_families([family], MassPrior((0.1, 1.0)))
    with pytest.raises(InputError, match="mass='continuous'"):
        sample_posterior(vis, model, family, priors=Priors.default(model, r_p=R_RANGE), chains_dir=tmp_path,
                         progress=False)


def test_mirror_families_share_their_node_tables(case):
    """The left-handed family reads the right-handed family's tables (one coordinate flipped) and agrees
    with a table built for its own interpolated template."""
    vis, model = case
    right = family_of(make_template(1.0, 0.3, 0.0, "R", **GRID))
    left = family_of(make_template(1.0, 0.3, 0.0, "L", **GRID))
    args = (vis.u, vis.v, vis.weights, model.brightness)
    fp_r = FamilyPerturbation(*args, right, R_RANGE, TRUE_GEOMETRY, **TABLES)
    fp_l = FamilyPerturbation(*args, left, R_RANGE, TRUE_GEOMETRY, mirror_of=fp_r, **TABLES)
    fp_r.disc_frame(0.35, 2.0, 40.0, 70.0, 0.7)
    built = dict(fp_r._right)
    fast = fp_l.disc_frame(0.35, 2.0, 40.0, 70.0, 0.7)
    assert fp_l._right is fp_r._right and all(fp_l._right[j] is t for j, t in built.items())  # nothing rebuilt
    assert fp_l.build_time_s == 0.0
    ref = FastPerturbation(*args, left.at(0.7), R_RANGE, TRUE_GEOMETRY, refine_from=fp_r._right[right.masses.size - 1],
                           **TABLES).disc_frame(0.35, 2.0, 40.0, 70.0)
    w = vis.weights
    assert np.sqrt(np.sum(w * np.abs(fast - ref) ** 2)) < 1e-5 * np.sqrt(np.sum(w * np.abs(ref) ** 2))
    with pytest.raises(InputError, match="not the mirror"):
        FamilyPerturbation(*args, right, R_RANGE, TRUE_GEOMETRY, mirror_of=fp_r, **TABLES)


def test_a_pickled_family_perturbation_still_builds_tables(case):
    """Pool workers get a pickled copy: it keeps the profile, so a node it has not seen can be built."""
    import pickle

    vis, model = case
    family = family_of(make_template(1.0, 0.3, 0.0, "R", **GRID), (0.2, 1.5), n_masses=7)
    fp = FamilyPerturbation(vis.u, vis.v, vis.weights, model.brightness, family, R_RANGE, TRUE_GEOMETRY, **TABLES)
    fp.disc_frame(0.35, 2.0, 40.0, 70.0, 0.25)
    copy = pickle.loads(pickle.dumps(fp))
    np.testing.assert_allclose(copy.disc_frame(0.35, 2.0, 40.0, 70.0, 1.2), fp.disc_frame(0.35, 2.0, 40.0, 70.0, 1.2),
                               rtol=1e-6, atol=1e-9)
    assert fp.build_nodes() == 7 and len(fp.tables) == 7


def test_walker_threads_reaching_a_new_node_build_it_once(case):
    """Walker threads (the default pool) that need the same unbuilt node at once share one build."""
    from concurrent.futures import ThreadPoolExecutor

    vis, model = case
    family = family_of(make_template(1.0, 0.3, 0.0, "R", **GRID), (0.2, 1.5), n_masses=5)
    fp = FamilyPerturbation(vis.u, vis.v, vis.weights, model.brightness, family, R_RANGE, TRUE_GEOMETRY, **TABLES)
    with ThreadPoolExecutor(4) as pool:
        tables = list(pool.map(lambda _: fp.node_table(2), range(8)))
    # the heaviest node (4) first: node 2 starts its r_p refinement from it
    assert all(t is tables[0] for t in tables) and list(fp.tables) == [2] and list(fp._right) == [4, 2]


def test_node_tables_sharing_radial_integrals_are_the_standalone_tables(case):
    """The mass nodes share each radius's rule and radial integrals (one radial grid, one profile) and
    start their r_p refinement from the heaviest node's: the tables are bit for bit those of each node
    template built on its own (the heaviest refined in full, the others from its table), and a second
    node adds no radius."""
    vis, model = case
    family = family_of(make_template(1.0, 0.3, 0.0, "R", **GRID), (0.2, 1.5), n_masses=5)
    brightness = model.brightness
    fp = FamilyPerturbation(vis.u, vis.v, vis.weights, brightness, family, R_RANGE, TRUE_GEOMETRY, **TABLES)
    first = fp.node_table(1)
    radii = len(fp._radial)
    second = fp.node_table(3)
    assert radii > 0 and len(fp._radial) == radii
    args = (vis.u, vis.v, vis.weights, brightness)
    heaviest = FastPerturbation(*args, family.node(4), R_RANGE, TRUE_GEOMETRY, **TABLES)
    np.testing.assert_array_equal(fp._right[4].table.grids, heaviest.table.grids)
    for j, shared in ((1, first), (3, second)):
        alone = FastPerturbation(*args, family.node(j), R_RANGE, TRUE_GEOMETRY, refine_from=heaviest, **TABLES)
        np.testing.assert_array_equal(shared.table.grids, alone.table.grids)
        np.testing.assert_array_equal(shared.table.r_nodes, alone.table.r_nodes)
        assert shared.quadrature_error == alone.quadrature_error
        assert shared.table.refinement[0]["midpoints_checked"] <= 8


def test_node_tables_built_by_worker_processes_are_the_lazily_built_tables(case):
    """``build_nodes(processes=2)`` builds a family's missing node tables in forked workers before a
    chain, their grids written to memory shared with this process: the tables (reference: each node
    built in this process on first use) bit for bit, and the family's perturbation the same at a mass
    between the nodes."""
    vis, model = case
    family = family_of(make_template(1.0, 0.3, 0.0, "R", **GRID), (0.2, 1.5), n_masses=5)
    args = (vis.u, vis.v, vis.weights, model.brightness, family, R_RANGE, TRUE_GEOMETRY)
    lazy = FamilyPerturbation(*args, **TABLES)
    pooled = FamilyPerturbation(*args, **TABLES)
    assert pooled.build_nodes(processes=2) == 5 and sorted(pooled.tables) == list(range(5))
    for j in range(5):
        np.testing.assert_array_equal(pooled.node_table(j).table.grids, lazy.node_table(j).table.grids)
        np.testing.assert_array_equal(pooled.node_table(j).table.r_nodes, lazy.node_table(j).table.r_nodes)
        assert pooled._build_s[j] > 0  # the workers' build times are kept
    # the workers' nodes (all but the heaviest, built here first) arrived in one shared block, not pickled
    assert len({id(pooled.node_table(j).table.grids.base) for j in range(4)}) == 1
    assert pooled.node_table(4).table.grids.base is not pooled.node_table(0).table.grids.base
    at = (0.35, 2.0, 40.0, 70.0, 0.7)
    np.testing.assert_array_equal(pooled.disc_frame(*at), lazy.disc_frame(*at))
    left = FamilyPerturbation(vis.u, vis.v, vis.weights, model.brightness, family_of(
        make_template(1.0, 0.3, 0.0, "L", **GRID), (0.2, 1.5), n_masses=5), R_RANGE, TRUE_GEOMETRY, mirror_of=pooled,
        **TABLES)
    assert left.build_nodes(processes=2) == 5 and all(left._right[j] is pooled._right[j] for j in range(5))
