"""The scan-grid Bayes factor against a brute-force integral over the priors, and its draws."""

import numpy as np
import pytest
from scipy.integrate import quad

from spiralbayes.inference.posterior import Priors
from spiralbayes.inference.posterior.scan_evidence import family_grid_evidence, template_grid_evidence
from tests._support.result_builders import scan_result


def _priors(r_p, amplitude_max=2.0):
    return Priors(tuple(r_p), (30.0, 1.0), (60.0, 1.0), (0.0, 0.01), (0.0, 0.01), amplitude_max)


def _brute_ln_b(scan, index, priors, n_r=200000):
    """ln of the prior average, over fine r_p midpoints, of the amplitude integral of the nearest scanned row, with
    scipy's quad for the amplitude (an independent route to every part of the grid estimate)."""
    lo, hi = priors.r_p
    radii = lo + (np.arange(n_r) + 0.5) * (hi - lo) / n_r
    nearest = np.abs(radii[:, None] - scan.r_p[None, :]).argmin(axis=1)
    a_max = priors.amplitude_max
    values = np.empty(scan.r_p.size)
    for i in range(scan.r_p.size):
        row = []
        for c1, c2 in zip(scan.cross[index, i], scan.power[index, i]):
            peak = max(0.0, min(a_max, c1 / c2)) * c1 - 0.5 * max(0.0, min(a_max, c1 / c2)) ** 2 * c2
            integral = quad(lambda a, c1=c1, c2=c2, peak=peak: np.exp(a * c1 - 0.5 * a * a * c2 - peak), 0.0, a_max,
                            points=[c1 / c2], limit=200)[0] / a_max
            row.append(np.log(integral) + peak)
        values[i] = np.log(np.mean(np.exp(np.array(row) - max(row)))) + max(row)
    per_r = values[nearest]
    return float(np.log(np.mean(np.exp(per_r - per_r.max()))) + per_r.max())


@pytest.mark.parametrize("r_p", [(0.1, 0.5), (0.05, 0.62), (0.22, 0.41)])
def test_template_ln_b_is_the_integral_over_the_priors(r_p):
    """Over the whole prior, a prior wider than the scan (edge rows extended) and one narrower (cells cut),
    for every template of a scan with one strong peak: within 1e-3 of the brute-force integral."""
    scan = scan_result()
    priors = _priors(r_p)
    for k, t in enumerate(scan.templates):
        got = template_grid_evidence(scan, t["name"], priors).ln_bayes
        assert got == pytest.approx(_brute_ln_b(scan, k, priors), abs=1e-3), t["name"]


def test_fixed_amplitude_uses_the_paper_delta_chi2():
    """With ``A = 1`` fixed the cells carry ``exp(delta chi2 / 2)``: a flat scan gives that value exactly."""
    scan = scan_result()
    scan.cross[:] = 30.0
    scan.power[:] = 20.0
    assert template_grid_evidence(scan, scan.templates[0]["name"], _priors((0.1, 0.5), None)).ln_bayes == \
        pytest.approx(20.0, abs=1e-12)


def test_family_ln_b_weights_the_members_by_the_nearest_mass():
    """Members at 0.3, 1, 3 M_th with a log-uniform prior on 0.1-3: weights ln-distance to the midpoints."""
    scan = scan_result()
    priors = _priors((0.1, 0.5))
    members = [type("T", (), {"name": t["name"], "mass": t["mass"]})() for t in scan.templates if t["hand"] == "R"]
    fam = family_grid_evidence(scan, members, (0.1, 3.0), priors)
    lnm = np.log([0.1, 0.3, 1.0, 3.0])
    cuts = [lnm[0], 0.5 * (lnm[1] + lnm[2]), 0.5 * (lnm[2] + lnm[3]), lnm[3]]
    q = np.diff(cuts) / (lnm[3] - lnm[0])
    each = [template_grid_evidence(scan, t.name, priors).ln_bayes for t in members]
    assert fam.ln_bayes == pytest.approx(np.log(np.sum(q * np.exp(each))), abs=1e-10)


def test_draws_follow_the_cell_weights():
    """The draws' r_p histogram over the cells matches the cells' posterior masses (chi2 over 5 cells)."""
    scan = scan_result()
    priors = _priors((0.1, 0.5))
    grid = template_grid_evidence(scan, scan.templates[1]["name"], priors)
    rng = np.random.default_rng(3)
    null = rng.normal(size=(50, 4))
    draws = grid.draw(20000, null, 2.0, rng)
    assert np.all((draws[:, 0] >= 0.1) & (draws[:, 0] <= 0.5))
    assert np.all((draws[:, 2] >= 0) & (draws[:, 2] <= 2.0))
    mass = np.exp(grid.log_weights[0] - grid.ln_bayes).sum(axis=1)
    counts = np.histogram(draws[:, 0], bins=np.append(grid.r_edges[:, 0], grid.r_edges[-1, 1]))[0]
    expected = 20000 * mass
    keep = expected > 5
    chi2 = np.sum((counts[keep] - expected[keep]) ** 2 / expected[keep])
    assert chi2 < 20.0  # 4 dof: p ~ 5e-4


def test_templates_without_a_chain_keep_the_grid_evidence(tmp_path):
    """``sample_posterior`` with a scan and ``max_chains = 1`` on the weak planet: the template gets the chain,
    its mirror the grid's evidence exactly (ln Z_0 + ln B_grid), grid-posterior samples inside the priors, and
    both survive a save and load of the result."""
    import warnings

    import spiralbayes as sb
    from spiralbayes.axisymmetric import AxisymmetricModel
    from spiralbayes.inference.posterior import GRID_LN_B_ERROR, PosteriorResult
    from tests._support.posterior_setup import R_RANGE, WEAK_START, build_weak_observation, profile, weak_template

    vis = build_weak_observation()
    model = AxisymmetricModel.from_profile(profile, WEAK_START, N=80)
    template = weak_template()
    templates = [template, template.mirror()]
    priors = Priors.default(model, r_p=R_RANGE)
    scan = sb.scan(vis, model, templates, model.geometry, r_p_min=0.12, r_p_max=0.62, n_r_p=11, n_phi_p=36,
                   progress=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        post = sb.sample_posterior(vis, model, templates, scan_result=scan, priors=priors, chains_dir=tmp_path,
                                   n_walkers=12, n_steps=40, evidence_draws=100, max_chains=1, progress=False,
                                   convergence="ignore", likelihood_kwargs={"rp_tolerance": 0.05})
    chained, mirror = post.run(template.name), post.run(template.mirror().name)
    assert (chained.mode, mirror.mode) == ("mcmc", "scan")
    grid = template_grid_evidence(scan, mirror.name, priors)
    assert mirror.ln_evidence == pytest.approx(post.null.ln_evidence + grid.ln_bayes, abs=1e-12)
    assert mirror.ln_evidence_err == pytest.approx(np.hypot(post.null.ln_evidence_err, GRID_LN_B_ERROR))
    s = mirror.samples
    assert s.shape == (400, 7) and np.all((s[:, 0] >= R_RANGE[0]) & (s[:, 0] <= R_RANGE[1]))
    assert np.all((s[:, 2] >= 0) & (s[:, 2] <= priors.amplitude_max))
    back = PosteriorResult.load(post.save(tmp_path / "post.h5"))
    assert back.run(mirror.name).mode == "scan" and back.p_planet == pytest.approx(post.p_planet)


def test_a_family_without_a_chain_has_mass_samples():
    """A family's grid run: ``M_p`` within each member's ln-mass interval and ``M_p_MJup`` = M_p h_p^3 M_*."""
    from types import SimpleNamespace

    from spiralbayes.inference.posterior import MassPrior
    from spiralbayes.inference.posterior.scan_evidence import grid_run

    scan = scan_result()
    priors = _priors((0.1, 0.5))
    members = [SimpleNamespace(name=t["name"], mass=t["mass"]) for t in scan.templates if t["hand"] == "R"]
    grid = family_grid_evidence(scan, members, (0.1, 3.0), priors)
    rng = np.random.default_rng(0)
    null = SimpleNamespace(samples=rng.normal([30, 60, 0, 0], [1, 1, 0.01, 0.01], size=(100, 4)),
                           geometry_map=np.array([30.0, 60.0, 0.0, 0.0]), ln_evidence=-10.0, ln_evidence_err=0.1)
    mass_prior = MassPrior((0.1, 3.0), 0.8, 0.0, systematic=0.0)
    run = grid_run("fam", {"name": "fam", "mass_mode": "continuous"}, grid, null, priors, rng, mass_prior=mass_prior,
                   h_p=0.07)
    assert run.continuous_mass and run.samples.shape == (400, 9) and run.theta_map.shape == (7,)
    m = run.samples[:, 7]
    assert m.min() >= 0.1 and m.max() <= 3.0
    np.testing.assert_allclose(run.samples[:, 8], mass_prior.to_mjup(m, 0.07, rng), rtol=1e-12)
    assert run.ln_evidence == pytest.approx(-10.0 + grid.ln_bayes)
