"""The exactness suite of the scan (issue 11): every instance of whole grids against an independent,
converged reference, for a thin-tau0 template, a 0.1 M_th template and a 1 M_th one, on an inclined
disc with a phase-centre offset.

The reference (:mod:`tests._support.quadrature_reference`) integrates the continuous model with Gauss-Legendre
nodes inside every template cell and sends them to every baseline with a 1e-12 NUFFT; it is shown
converged by raising its orders on a subset of instances. The scan must match it within
``0.05 + 1e-4 |Δχ²|`` everywhere, ``power`` and ``cross`` within 1e-6 (``cross`` relative to
``max(|cross|, sqrt(power))``, its size for a pure-noise residual), and its own error estimate must
cover the difference. The always-run check uses synthetic data (3000 baselines); the slow one an
ALMA simulation (the paper's low-sensitivity set-up: the fiducial C-4 + C-7 coverage, 18k
visibilities) with a frank fit and the paper's 25 x 90 grid.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from spiralbayes import DiscGeometry
from spiralbayes.axisymmetric import AxisymmetricModel
from spiralbayes.exceptions import AccuracyWarning
from spiralbayes.inference.scan.run import scan
from spiralbayes.model import perturbation_visibilities
from spiralbayes.visibilities import Visibilities
from tests._support.quadrature_reference import reference_terms

GEOMETRY = DiscGeometry(35.0, 70.0, 0.006, -0.004)  # inclined, offset phase centre
FINE_ORDERS = ((4, 3), (6, 4))  # reference orders (radial, azimuthal Gauss nodes per cell), and the check's
COARSE_ORDERS = ((5, 4), (7, 6))  # for templates on coarser grids (wider cells)


def _templates(n_x=None, n_phi=None):
    from spiralbayes.templates import make_template

    size = {} if n_x is None else {"n_x": n_x, "n_phi": n_phi}
    return [make_template(1.0, 3.0, 10.0, "R", **size),   # the planet's own
            make_template(1.0, 0.1, 0.0, "R", **size),    # optically thin: sharp, deep wakes
            make_template(0.1, 3.0, 10.0, "R", **size)]   # 0.1 M_th: weak


def compare_whole_grid(vis, model, templates, r_p, n_phi_p, orders=FINE_ORDERS, **scan_options):
    """Scan, then the reference at every instance; returns the worst relative errors and the
    reference's own convergence (printed)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)  # the scan must not doubt itself here
        result = scan(vis, model, templates, GEOMETRY, r_p=r_p, n_phi_p=n_phi_p, progress=False, **scan_options)
    residual = vis.V - model.visibilities(vis.u, vis.v, GEOMETRY)
    (ORDER, CHECK_ORDER) = orders
    phi = result.phi_p
    worst = {"power": 0.0, "cross": 0.0, "dchi2_excess": -np.inf, "estimate_short": -np.inf, "reference": 0.0}
    for t, template in enumerate(templates):
        for i, r in enumerate(r_p):
            c_ref, p_ref = reference_terms(vis, residual, GEOMETRY, model.brightness, template, r, phi,
                                           order_r=ORDER[0], order_phi=ORDER[1], support=model.Rmax)
            if i in (0, len(r_p) - 1):  # the reference itself: raise its orders on every fifth azimuth
                c2, p2 = reference_terms(vis, residual, GEOMETRY, model.brightness, template, r, phi[::5],
                                         order_r=CHECK_ORDER[0], order_phi=CHECK_ORDER[1], support=model.Rmax)
                change = np.abs((2 * c2 - p2) - (2 * c_ref[::5] - p_ref[::5]))
                worst["reference"] = max(worst["reference"], float(np.max(change)))
            cross, power = result.cross[t, i], result.power[t, i]
            d_ref, d = 2 * c_ref - p_ref, 2 * cross - power
            worst["power"] = max(worst["power"], float(np.max(np.abs(power - p_ref) / p_ref)))
            worst["cross"] = max(worst["cross"], float(np.max(np.abs(cross - c_ref)
                                                               / np.maximum(np.abs(c_ref), np.sqrt(p_ref)))))
            excess = np.abs(d - d_ref) - (0.05 + 1e-4 * np.abs(d_ref))
            worst["dchi2_excess"] = max(worst["dchi2_excess"], float(np.max(excess)))
            short = np.abs(d - d_ref) - result.delta_chi2_error()[t, i]
            worst["estimate_short"] = max(worst["estimate_short"], float(np.max(short)))
    print(f"whole grid ({len(templates)} templates x {len(r_p)} r_p x {n_phi_p} phi_p, "
          f"{result.provenance['quadrature']['power_path_used']} path): max |d power| / power = "
          f"{worst['power']:.2e}, max |d cross| / max(|cross|, sqrt(power)) = {worst['cross']:.2e}, "
          f"reference change at orders {CHECK_ORDER} = {worst['reference']:.2e}, "
          f"max Δχ² error estimate = {np.nanmax(result.delta_chi2_error()):.2e}")
    return result, worst


def _assert_exact(result, worst):
    assert worst["reference"] < 1e-3  # the reference has converged far below the tolerance
    assert worst["power"] < 1e-6 and worst["cross"] < 1e-6
    assert worst["dchi2_excess"] < 0  # within 0.05 + 1e-4 |Δχ²| at every instance
    assert worst["estimate_short"] < worst["reference"] + 1e-6  # the error estimate covers the error
    assert np.all(np.isfinite(result.delta_chi2_error()))
    assert not result.accuracy_violations().any()


# --- always-run: synthetic data ---------------------------------------------------------------------
def _profile(r):
    r = np.asarray(r, dtype=float)
    return 4e10 * np.exp(-r / 0.25 - (r / 0.7) ** 6) * (1 + 0.5 * np.exp(-0.5 * ((r - 0.4) / 0.03) ** 2))


@pytest.fixture(scope="module")
def synthetic():
    """3000 baselines to 3 Mlambda, a ringed disc (frank-style profile), a 1 M_th planet at 0.3 arcsec."""
    rng = np.random.default_rng(21)
    n = 3000
    q = 3e6 * np.sqrt(rng.uniform(1e-3, 1, n))
    th = rng.uniform(0, 2 * np.pi, n)
    u, v = q * np.cos(th), q * np.sin(th)
    model = AxisymmetricModel.from_profile(_profile, GEOMETRY, N=300, Rmax=1.2)
    planet = _templates(120, 240)[0]
    dV = perturbation_visibilities(u, v, GEOMETRY, model.brightness, planet, 0.3, 1.0)
    sigma = np.sqrt(np.sum(np.abs(dV) ** 2) / 400.0)  # the planet alone: Δχ² ~ 400
    V = model.visibilities(u, v, GEOMETRY) + dV + sigma * (rng.normal(size=n) + 1j * rng.normal(size=n))
    return Visibilities(u, v, V, np.full(n, sigma ** -2)), model


@pytest.mark.parametrize("power_path", ["polar", "direct"])
def test_scan_matches_converged_reference_on_whole_grids(synthetic, power_path):
    vis, model = synthetic
    result, worst = compare_whole_grid(vis, model, _templates(120, 240), np.array([0.06, 0.18, 0.3, 0.42]), 30,
                                       COARSE_ORDERS, power_path=power_path)
    assert result.provenance["quadrature"]["power_path_used"] == power_path
    assert np.nanmax(result.dchi2) > 200  # the planted planet is found, so large |Δχ²| are tested too
    _assert_exact(result, worst)


# --- slow: the fiducial ALMA observation, frank, the paper's grid ---------------------------------------
@pytest.mark.slow
def test_scan_matches_converged_reference_on_the_papers_grid():
    from spiralbayes.axisymmetric import fit_axisymmetric
    from spiralbayes.simulate import DiscModel, simulate_observation

    templates = _templates()
    vis = simulate_observation("low_sensitivity", DiscModel(tau_ref=3.0), GEOMETRY, templates[0], r_p=50 / 140,
                               phi_p=0.0, seed=1)  # the fiducial coverage in half the time: half the reference's cost
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = fit_axisymmetric(vis, GEOMETRY, progress=False)
    result, worst = compare_whole_grid(vis, model, templates, np.linspace(0.02, 0.5, 25), 90)
    assert np.nanmax(result.dchi2) > 100
    _assert_exact(result, worst)
