"""Axisymmetric frank model: fits recover known discs, exact visibilities, image vs Hankel, I/O.

References used: analytic transforms of Gaussians, frank's own ``sol.predict`` /
``predict_deprojected`` / ``interpolate_brightness``, the NUFFT of ``spiralbayes.fourier``,
and synthetic data with a known profile, geometry and noise."""

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
from spiralbayes.axisymmetric import AxisymmetricModel, fit_axisymmetric
from spiralbayes.geometry import ARCSEC, DiscGeometry
from spiralbayes.visibilities import Visibilities
from tests._support.axisymmetric_setup import (
    PEAK,
    TRUE_GEOMETRY,
    random_baselines,
    ring_and_core,
)


# --- (a) profile recovery ---------------------------------------------------------------------
def test_fixed_geometry_fit_recovers_profile_within_noise(fixed_fit, truth_model):
    m = fixed_fit
    assert m.hyperparameters["N"] == 200 and m.hyperparameters["Rmax"] == 1.2
    assert m.hyperparameters["fit_geometry"] is None and m.geometry == TRUE_GEOMETRY
    assert m.provenance["converged"] and m.fit_time_s > 0
    resolved = m.r < 0.9  # the disc; beyond it I ~ 0 and only the prior speaks
    dev = (m.I - ring_and_core(m.r))[resolved]
    z = dev / m.I_err[resolved]
    # frank's sigma_I leaves out the prior's smoothing bias; over five noise seeds the worst
    # point was 4.2 sigma and the RMS of z at most 1.7, the worst deviation 2.4 % of the peak.
    assert np.max(np.abs(z)) < 5
    assert np.sqrt(np.mean(z ** 2)) < 2
    assert np.max(np.abs(dev)) < 0.04 * PEAK
    assert m.total_flux == pytest.approx(truth_model.total_flux, rel=5e-3)
    assert m.R_eff(0.95) == pytest.approx(truth_model.R_eff(0.95), rel=1e-2)


def test_nonnegative_profile(fixed_fit):
    m = fixed_fit
    assert m.I_nonneg is not None and np.all(m.I_nonneg >= 0)
    nn = m.nonnegative()
    assert np.array_equal(nn.I, m.I_nonneg) and nn.I_err is None
    assert nn.total_flux == pytest.approx(m.total_flux, rel=1e-2)


# --- (b) geometry fits ---------------------------------------------------------------------------
def test_fitted_geometry_recovers_inc_pa_and_offset(synthetic):
    m = fit_axisymmetric(synthetic, fit_geometry="nonparametric", progress=False)
    g = m.geometry
    assert m.hyperparameters["fit_geometry"] == "nonparametric"
    assert abs(g.inc - TRUE_GEOMETRY.inc) < 1.0
    assert abs(g.PA - TRUE_GEOMETRY.PA) < 1.0
    assert abs(g.dRA - TRUE_GEOMETRY.dRA) < 5e-3
    assert abs(g.dDec - TRUE_GEOMETRY.dDec) < 5e-3
    assert m.provenance["geometry_fit_time_s"] > 0


def gaussian_disc_visibilities(rng, n, sigma_arcsec, flux, geometry, noise):
    """Analytic visibilities of an inclined, offset Gaussian disc (optically thick)."""
    u, v = random_baselines(rng, n, q_max=1.5e6)
    up, vp = geometry.deproject_uv(u, v)
    s = sigma_arcsec * ARCSEC
    V = flux * geometry.cos_inc * np.exp(-2 * np.pi ** 2 * s ** 2 * (up ** 2 + vp ** 2))
    V = V * geometry.phase_factor(u, v)
    V = V + noise * (rng.normal(size=n) + 1j * rng.normal(size=n))
    return Visibilities(u, v, V, np.full(n, noise ** -2))


def test_default_gaussian_geometry_fit_on_gaussian_disc():
    truth = DiscGeometry(inc=50.0, PA=130.0, dRA=-0.02, dDec=0.015)
    vis = gaussian_disc_visibilities(np.random.default_rng(5), 4000, 0.2, 0.1, truth, 2e-3)
    m = fit_axisymmetric(vis, N=60, progress=True)  # no geometry given: frank's Gaussian fit
    assert m.hyperparameters["fit_geometry"] == "gaussian"
    g = m.geometry
    assert abs(g.inc - truth.inc) < 1.0 and abs(g.PA - truth.PA) < 1.0
    assert abs(g.dRA - truth.dRA) < 5e-3 and abs(g.dDec - truth.dDec) < 5e-3
    assert m.total_flux == pytest.approx(0.1, rel=0.02)


# --- (g) bad input ----------------------------------------------------------------------------------
@pytest.mark.parametrize("kwargs, match", [
    ({"N": -5}, "N = -5"),
    ({"N": 0}, "N = 0"),
    ({"N": 20.5}, "N = 20.5"),
    ({"Rmax": 0.0}, "Rmax = 0.0"),
    ({"Rmax": -1.0}, "Rmax = -1.0"),
    ({"alpha": 0.5}, "alpha"),
    ({"p0": 0.0}, "p0"),
    ({"weights_smooth": -1.0}, "weights_smooth"),
    ({"method": "Poisson"}, "method"),
    ({"fit_geometry": "ellipse"}, "fit_geometry"),
    ({"convergence_failure": "shrug"}, "convergence_failure"),
])
def test_bad_hyperparameters_raise_clear_errors(synthetic, kwargs, match):
    with pytest.raises(ValueError, match=match):
        fit_axisymmetric(synthetic, TRUE_GEOMETRY, progress=False, **kwargs)


def test_baselines_beyond_the_series_ask_for_more_points(synthetic):
    with pytest.raises(ValueError, match="increase N"):
        fit_axisymmetric(synthetic, TRUE_GEOMETRY, N=20, progress=False)


def test_bad_input_types(synthetic):
    with pytest.raises(TypeError, match="Visibilities"):
        fit_axisymmetric((synthetic.u, synthetic.v, synthetic.V), TRUE_GEOMETRY)
    with pytest.raises(TypeError, match="DiscGeometry"):
        fit_axisymmetric(synthetic, (35.0, 60.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="collocation"):
        AxisymmetricModel(r=np.linspace(0, 1, 10), I=np.ones(10), geometry=DiscGeometry(), Rmax=1.0)
    with pytest.raises(ValueError, match="Rmax"):
        AxisymmetricModel.from_profile(np.ones_like, Rmax=-2)


# --- (h) sparse data ----------------------------------------------------------------------------------
def test_sparse_data_get_the_collocation_count_their_baselines_need():
    """150 visibilities: N is the data's own (not 200), frank's series still covers every baseline,
    and the disc comes back."""
    from spiralbayes.axisymmetric.fit import SPARSE_MARGIN, _minimum_collocation_count

    truth = DiscGeometry(inc=40.0, PA=20.0)
    vis = gaussian_disc_visibilities(np.random.default_rng(8), 150, 0.2, 0.1, truth, 2e-3)
    m = fit_axisymmetric(vis, truth, progress=False)
    needed = _minimum_collocation_count(vis, truth, 1.2)
    assert m.hyperparameters["N"] == int(np.ceil(SPARSE_MARGIN * needed)) < 200
    assert m.total_flux == pytest.approx(0.1, rel=0.03)
    with pytest.raises(ValueError, match="increase N"):  # and needed is really needed
        fit_axisymmetric(vis, truth, N=needed - 2, progress=False)


def test_more_collocation_points_than_visibilities_warn_with_the_fix():
    from spiralbayes.axisymmetric.fit import _collocation_count
    from spiralbayes.exceptions import DataWarning

    truth = DiscGeometry(inc=40.0, PA=20.0)
    vis = gaussian_disc_visibilities(np.random.default_rng(8), 150, 0.2, 0.1, truth, 2e-3)
    with pytest.warns(DataWarning, match=r"N = 200 exceeds the 150 visibilities.*leave N unset"):
        assert _collocation_count(vis, truth, 1.2, 200) == 200
    many = gaussian_disc_visibilities(np.random.default_rng(8), 400, 0.2, 0.1, truth, 2e-3)
    assert _collocation_count(many, truth, 1.2, None) == 200  # the paper's default when data are not sparse
