"""Calibration of the exclusion limits on synthetic observations (issue 10, done-when (a) and (c)).

(a) A planet planted at exactly the reported limiting mass is wrongly excluded in at most
1 - CL = 5 % of noise realisations (within the binomial error), and the amplitude estimate at the
planted instance is unbiased with the stated error.
(c) The template systematic: spirals not made by the bank's generator (the reference maps of the
template-fidelity work, ``tests/data/references/*.h5``, or the folder in ``SPIRALBAYES_REFERENCES``)
are planted and the rate at which the bank's family wrongly excludes them is reported.
"""

import json
import os
from pathlib import Path

import numpy as np
import pytest

from spiralbayes.inference.validation.planted import planted_exclusion_rate
from spiralbayes.inference.limits.exclusion import compute_limits
from spiralbayes.inference.scan.engine import ScanContext, cross_template, scan_template, with_residual
from spiralbayes.model import perturbation_visibilities
from spiralbayes.templates import SpiralTemplate, make_template
from tests._support import limits_setup

CL = 0.95
REFERENCES = Path(os.environ.get("SPIRALBAYES_REFERENCES", Path(__file__).parents[2] / "data" / "references"))


def allowed_wrong(n: int, cl: float = CL) -> float:
    """The nominal rate plus two binomial standard errors."""
    p = 1 - cl
    return p + 2 * np.sqrt(p * (1 - p) / n)


def reported_limit(limits_case):
    """The limiting mass reported by the planet-free data at the first radius with one."""
    vis, model, templates, result = limits_case
    limits = compute_limits(result, cl=CL, resolution=0.0, bright_radius=np.inf)
    i = int(np.flatnonzero(limits.m_lim_status[0] == "limit")[-1])
    return float(result.r_p[i]), float(limits.m_lim[0, i])


ON_GRID_PHI = 2 * np.pi * 10 / limits_setup.N_PHI


def planted_at_limit(limits_case, n, phi_p=ON_GRID_PHI):
    vis, model, templates, result = limits_case
    r_p, m_lim = reported_limit(limits_case)
    planted = make_template(m_lim, 0.3, 10.0, "R", **limits_setup.GRID)
    return planted_exclusion_rate(vis, model, templates, planted, r_p, phi_p, m_lim, n_realisations=n, cl=CL,
                                  n_phi_p=limits_setup.N_PHI, seed=1000)


def test_planet_at_the_limiting_mass_is_rarely_excluded(limits_case):
    out = planted_at_limit(limits_case, 50)
    assert out.n == 50 and out.family == "tau0=0.3, beta=10, h_p=0.07"
    assert 0.3 < out.true_mass < 3.0
    assert out.rate <= allowed_wrong(out.n), out.summary()
    print(out.summary())


@pytest.mark.slow
def test_planet_at_the_limiting_mass_is_rarely_excluded_many_realisations(limits_case):
    out = planted_at_limit(limits_case, 400)
    assert out.rate <= allowed_wrong(out.n), out.summary()
    print(out.summary())
    # between two scanned azimuths (half a 12 deg step) the nearest template instance overlaps the
    # planet less; reported, not asserted (docs/limits.md, "azimuth grid")
    off_grid = planted_at_limit(limits_case, 400, ON_GRID_PHI + np.pi / limits_setup.N_PHI)
    print("half a grid step off:", off_grid.summary())


def test_amplitude_estimate_at_the_planted_instance_is_unbiased_with_the_stated_error(limits_case):
    """(A_hat - 1) / sigma_A over noise realisations ~ N(0, 1), so P(A_hat + z sigma_A < 1) = 1 - CL."""
    vis, model, templates, _ = limits_case
    template, r_p, phi_p = templates[2], 0.35, 2 * np.pi * 7 / limits_setup.N_PHI  # 1 M_th, on the grid
    ctx = ScanContext.build(vis, model, limits_setup.GEOMETRY, [r_p], limits_setup.N_PHI)
    power = scan_template(ctx, template)[1][0, 7]
    dv = perturbation_visibilities(vis.u, vis.v, limits_setup.GEOMETRY, ctx.profile, template, r_p, phi_p,
                                   quad=ctx.quadrature(template, r_p))
    scale = 0.2  # a fainter planet (amplitude 0.2), so that sigma_A is not tiny
    sigma = 1 / np.sqrt(vis.weights)
    rng = np.random.default_rng(7)
    pulls = []
    for _ in range(60):
        noise = sigma * (rng.standard_normal(vis.n) + 1j * rng.standard_normal(vis.n))
        cross = cross_template(with_residual(ctx, scale * dv + noise), template)[0, 7]
        pulls.append((cross / power - scale) * np.sqrt(power))
    pulls = np.array(pulls)
    assert abs(pulls.mean()) < 3 / np.sqrt(pulls.size)
    assert 0.75 < pulls.std() < 1.3


# -- (c) the template systematic ---------------------------------------------------------------------
def reference_cases(h_p=0.07, masses=(0.3, 1.0)):
    """(name, SpiralTemplate, mu) for every reference map with delta_tau0.3 at this h_p."""
    import h5py

    files = sorted(REFERENCES.glob("*.h5")) if REFERENCES.is_dir() else []
    out = []
    for path in files:
        with h5py.File(path, "r") as f:
            if "x" not in f or "phi" not in f:
                continue
            x, phi = f["x"][()], f["phi"][()]
            for case in json.loads(f.attrs.get("cases", "[]")) or [k for k in f if k not in ("x", "phi")]:
                g = f[case]
                mu, h = float(g.attrs.get("mu_Mth", np.nan)), float(g.attrs.get("h_p", np.nan))
                if "delta_tau0.3" not in g or not np.isclose(h, h_p) or not np.any(np.isclose(mu, masses)):
                    continue
                template = SpiralTemplate(x=x, phi=phi, delta=g["delta_tau0.3"][()].astype(float), mass=mu, tau0=0.3,
                                          beta=0.0, h_p=h, hand="R", name=f"{path.stem}:{case}")
                out.append((template.name, template, mu))
    return out


def systematic_rates(cases, n, power=100.0):
    """Plant each reference spiral where the bank's template of its mass has ``sum w |ΔV|^2 = power``
    (a planet the data exclude firmly when absent); count the wrong exclusions."""
    family = limits_setup.family(tau0=0.3, beta=0.0)
    r_p, phi_p = 0.3, ON_GRID_PHI  # on the azimuth grid: only the template differs
    reports = []
    for _name, reference, mu in cases:
        bank = [t for t in family if np.isclose(t.mass, mu) and t.hand == "R"][0]
        probe = limits_setup.observation(35e-6)
        ctx = ScanContext.build(probe, limits_setup.disc_model(), limits_setup.GEOMETRY, [r_p], limits_setup.N_PHI)
        p35 = scan_template(ctx, bank)[1].mean()
        vis = limits_setup.observation(35e-6 * np.sqrt(p35 / power))
        ref = planted_exclusion_rate(vis, limits_setup.disc_model(), family, reference, r_p, phi_p, mu,
                                     n_realisations=n, cl=CL, n_phi_p=limits_setup.N_PHI, seed=50)
        control = planted_exclusion_rate(vis, limits_setup.disc_model(), family, bank, r_p, phi_p, mu,
                                         n_realisations=n, cl=CL, n_phi_p=limits_setup.N_PHI, seed=50)
        reports.append((ref, control))
    return reports


def test_template_systematic_of_reference_spirals():
    cases = reference_cases(masses=(1.0,))
    if not cases:
        pytest.skip(f"no reference maps with delta_tau0.3 at h_p = 0.07 in {REFERENCES} (they come from the "
                    "template-fidelity work; set SPIRALBAYES_REFERENCES to their folder)")
    for ref, control in systematic_rates(cases[:1], 30):
        print(ref.summary())
        print("control (the bank's own template):", control.summary())
        assert control.rate <= allowed_wrong(control.n)
        assert ref.family == "tau0=0.3, beta=0, h_p=0.07" and ref.n == 30
        assert np.all(np.isfinite(ref.m_lim) | ~ref.wrongly_excluded)


@pytest.mark.slow
def test_template_systematic_of_every_reference_spiral():
    cases = reference_cases()
    if not cases:
        pytest.skip(f"no reference maps in {REFERENCES}")
    for ref, control in systematic_rates(cases, 100) + systematic_rates(cases, 100, power=400.0):
        print(ref.summary())
        print("control (the bank's own template):", control.summary())
        assert control.rate <= allowed_wrong(control.n)
