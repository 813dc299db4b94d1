"""Maximum-likelihood fits of the competing asymmetry models: injection and recovery, exact Δχ²."""

import json

import numpy as np
import pytest

from spiralbayes.alternatives import FIELD_MODELS, DiscGrid, FieldTransform, ProfileContext, offset_geometry
from spiralbayes.axisymmetric import AxisymmetricModel
from spiralbayes.exceptions import InputError
from spiralbayes.geometry import DiscGeometry
from spiralbayes.inference.detection.alternatives import AlternativesResult, delta_chi2_direct, fit_alternatives
from spiralbayes.inference.scan.statistics import chi2
from spiralbayes.visibilities import Visibilities
from tests.alternatives.test_fields import ring_profile

GEOMETRY = DiscGeometry(inc=40.0, PA=30.0)
ARC = np.array([0.25, 0.43, 2.0, 0.04, 0.35])  # contrast, r_c ["], phi_c, sigma_r ["], sigma_phi [rad]
SIGMA = 5e-4  # Jy


def observe(V, rng):
    return V + SIGMA * (rng.normal(size=V.size) + 1j * rng.normal(size=V.size))


@pytest.fixture(scope="module")
def disc():
    model = AxisymmetricModel.from_profile(ring_profile, GEOMETRY, N=150, Rmax=1.2)
    rng = np.random.default_rng(11)
    q = 10 ** rng.uniform(4, np.log10(2e6), 3000)
    theta = rng.uniform(0, 2 * np.pi, q.size)
    return model, q * np.cos(theta), q * np.sin(theta)


def arc_visibilities(model, u, v):
    """The injected arc on a grid twice as fine as the fit's (a different discretisation)."""
    grid = DiscGrid.for_baselines(float(np.max(np.hypot(u, v))), 0.8, cell_factor=20)
    field = FIELD_MODELS["arc"].field(ARC, ProfileContext.build(model.brightness, grid))
    return FieldTransform(grid, u, v, GEOMETRY).visibilities(field)


@pytest.fixture(scope="module")
def arc_fit(disc):
    model, u, v = disc
    rng = np.random.default_rng(12)
    V = observe(model.visibilities(u, v) + arc_visibilities(model, u, v), rng)
    vis = Visibilities(u, v, V, np.full(u.size, SIGMA ** -2))
    return vis, fit_alternatives(vis, model)


def test_injected_arc_is_recovered_and_named(arc_fit, disc):
    model, u, v = disc
    vis, result = arc_fit
    assert result.best.name == "arc"
    p = result.fits["arc"].params
    assert p["r_c"] == pytest.approx(ARC[1], abs=0.005)
    assert p["phi_c_deg"] == pytest.approx(np.degrees(ARC[2]), abs=3.0)
    assert p["sigma_r"] == pytest.approx(ARC[3], rel=0.2)
    assert p["sigma_phi_deg"] == pytest.approx(np.degrees(ARC[4]), rel=0.2)
    assert p["contrast"] == pytest.approx(ARC[0], rel=0.15)
    # at least as good as the truth (a maximum-likelihood fit), and every other model is worse
    truth = chi2(model.visibilities(u, v), vis.V, vis.weights) - chi2(
        model.visibilities(u, v) + arc_visibilities(model, u, v), vis.V, vis.weights)
    assert result.fits["arc"].delta_chi2 > truth - 1.0
    others = [f.delta_bic(result.n_data) for n, f in result.fits.items() if n != "arc"]
    assert max(others) < result.fits["arc"].delta_bic(result.n_data) - 10


@pytest.mark.parametrize("name", ["arc", "lopsided"])
def test_reported_delta_chi2_equals_direct_fourier_sums(arc_fit, disc, name):
    model, _, _ = disc
    vis, result = arc_fit
    direct = delta_chi2_direct(result, name, vis, model)
    assert result.fits[name].delta_chi2 == pytest.approx(direct, rel=1e-6, abs=1e-3)


def test_injected_geometry_error_is_recovered(disc):
    model, u, v = disc
    truth = [0.8, -1.5, 12.0, -6.0]  # deg, deg, mas, mas
    rng = np.random.default_rng(13)
    V = observe(model.visibilities(u, v, offset_geometry(GEOMETRY, truth)), rng)
    vis = Visibilities(u, v, V, np.full(u.size, SIGMA ** -2))
    result = fit_alternatives(vis, model, models=["geometry", "lopsided"])
    fit = result.fits["geometry"]
    assert np.all(np.abs(np.subtract(fit.theta, truth)) < [0.1, 0.3, 0.5, 0.5])
    assert result.best.name == "geometry"
    assert fit.delta_chi2 == pytest.approx(delta_chi2_direct(result, "geometry", vis, model), rel=1e-9)
    got = result.fitted_geometry()
    assert got.dRA == pytest.approx(0.012, abs=5e-4) and got.inc == pytest.approx(40.8, abs=0.1)


def test_result_round_trips_through_hdf5_and_json(arc_fit, tmp_path, disc):
    model, _, _ = disc
    vis, result = arc_fit
    loaded = AlternativesResult.load(result.save(tmp_path / "alternatives.h5"))
    assert loaded.fits == result.fits and loaded.grid == result.grid and loaded.geometry == result.geometry
    d = json.loads(json.dumps(result.to_dict()))
    assert d["fits"]["arc"]["delta_bic"] == pytest.approx(result.delta_bic()["arc"])
    assert "arc" in result.table().splitlines()[1]
    np.testing.assert_allclose(loaded.model_visibilities("arc", vis, model),
                               result.model_visibilities("arc", vis, model))


def test_bad_requests_are_refused(arc_fit, disc):
    model, _, _ = disc
    vis, _ = arc_fit
    with pytest.raises(InputError, match="unknown asymmetry model"):
        fit_alternatives(vis, model, models=["vortex"])
    with pytest.raises(InputError, match="n_starts"):
        fit_alternatives(vis, model, n_starts=0)
    with pytest.raises(InputError, match="geometry"):
        AlternativesResult({}, 1, 0.0, GEOMETRY, DiscGrid(1, 4, 8)).fitted_geometry()


def test_injected_eccentric_ring_of_excess_emission_is_recovered(disc):
    """Reference: the simulator's eccentric ring (``simulate.asymmetric.eccentric_ring``: the disc brightened by a
    Gaussian ring along a Keplerian ellipse), on a grid twice as fine as the fit's."""
    from spiralbayes.alternatives import remove_ring_mean
    from spiralbayes.simulate.asymmetric import eccentric_ring

    model, u, v = disc
    r_0, width, e, omega, contrast = 0.3, 0.03, 0.08, 2.0, 2.0   # on the core's steep tail, not on its ring
    grid = DiscGrid.for_baselines(float(np.max(np.hypot(u, v))), 0.8, cell_factor=20)
    delta = eccentric_ring(r_0, width, e, omega, contrast)(grid.r[:, None], grid.phi[None, :])
    V_ring = FieldTransform(grid, u, v, GEOMETRY).visibilities(remove_ring_mean(ring_profile(grid.r)[:, None] * delta))
    V = observe(model.visibilities(u, v) + V_ring, np.random.default_rng(13))
    vis = Visibilities(u, v, V, np.full(u.size, SIGMA ** -2))
    result = fit_alternatives(vis, model, models=["lopsided", "eccentric_ring", "eccentric_excess"])
    fit = result.fits["eccentric_excess"]
    assert result.best.name == "eccentric_excess"
    assert fit.params["e"] == pytest.approx(e, rel=0.1)
    assert fit.params["omega_deg"] == pytest.approx(np.degrees(omega), abs=4.0)
    assert fit.params["r_c"] == pytest.approx(r_0, abs=0.005)
    assert fit.params["width"] == pytest.approx(width, rel=0.15)
    assert fit.params["contrast"] == pytest.approx(contrast, rel=0.1)
    truth = chi2(model.visibilities(u, v), vis.V, vis.weights) - chi2(model.visibilities(u, v) + V_ring, vis.V,
                                                                       vis.weights)
    assert fit.delta_chi2 > truth - 1.0
    # the whole-profile remap moves the steep background too (Δχ² 3308 against 3567 when written)
    assert result.fits["eccentric_ring"].delta_chi2 < fit.delta_chi2 - 100
    assert fit.delta_chi2 == pytest.approx(delta_chi2_direct(result, "eccentric_excess", vis, model), rel=1e-6,
                                           abs=1e-3)
