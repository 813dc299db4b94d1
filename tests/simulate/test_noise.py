"""Synthetic observations: uv geometry, noise level, model transforms, planted perturbations, presets."""

import numpy as np
import pytest

from spiralbayes.geometry import ARCSEC
from spiralbayes.simulate import (
    Radiometer,
    fit_beam,
    image_noise,
    measure_image_noise,
    observe,
    uv_coverage,
)

LAM = 0.87e-3


# --- noise -------------------------------------------------------------------------------------
def test_image_noise_matches_requested_sensitivity(short_cov):
    """Noise-only observation: the natural-weighted dirty-image RMS equals the request (10 %)."""
    request = 35e-6
    vis = observe(None, short_cov, sensitivity=request, seed=11)
    assert image_noise(vis.weights) == pytest.approx(request, rel=1e-12)
    rms = measure_image_noise(vis, n=256)
    assert rms == pytest.approx(request, rel=0.10)
    # the single-pixel statistic over many seeds (independent of image correlations)
    centre = [observe(None, short_cov, sensitivity=request, seed=s).V.real.mean() for s in range(300)]
    assert np.std(centre) == pytest.approx(request, rel=0.10)
    # and sigma_img = sigma / sqrt(N), not sigma / sqrt(2N)
    np.testing.assert_allclose(vis.sigma, request * np.sqrt(short_cov.n))


def test_radiometer_matches_alma_handbook_image_noise():
    """sigma_img = 2 k T / (eta A sqrt(N_ant (N_ant - 1) n_pol dnu t)) (ALMA Technical Handbook)."""
    rad = Radiometer(T_sys=120.0, bandwidth=7.5e9)
    cov = uv_coverage("C-5", -30.0, (-0.5, 0.5), 10.0, LAM)
    t_total = cov.n / 903 * 10.0
    eta = rad.aperture_efficiency * rad.quantisation_efficiency * rad.correlator_efficiency
    k = 1.380649e-23
    expected = 2 * k * 120.0 / (eta * np.pi * 36 * np.sqrt(43 * 42 * 2 * 7.5e9 * t_total)) * 1e26
    vis = observe(None, cov, radiometer=rad, seed=1)
    assert image_noise(vis.weights) == pytest.approx(expected, rel=1e-9)
    assert 1e-3 < vis.sigma[0] < 1e-1  # tens of mJy per 10-s visibility in Band 7


def test_observe_needs_one_noise_specification(short_cov):
    with pytest.raises(ValueError, match="exactly one"):
        observe(None, short_cov)
    with pytest.raises(ValueError, match="exactly one"):
        observe(None, short_cov, sensitivity=1e-5, sigma=1e-3)
    with pytest.raises(ValueError, match="shape"):
        observe(np.zeros(5), short_cov, sigma=1.0)


def test_seeds_reproduce(short_cov):
    model = lambda u, v: np.exp(-np.hypot(u, v) / 1e6) + 0j  # noqa: E731
    a = observe(model, short_cov, sensitivity=35e-6, seed=4)
    b = observe(model, short_cov, sensitivity=35e-6, seed=4)
    c = observe(model, short_cov, sensitivity=35e-6, seed=5)
    np.testing.assert_array_equal(a.V, b.V)
    assert not np.allclose(a.V, c.V)
    clean = observe(model, short_cov, sensitivity=35e-6, add_noise=False)
    np.testing.assert_array_equal(clean.V, model(short_cov.u, short_cov.v))
    np.testing.assert_array_equal(clean.weights, a.weights)


def test_fit_beam_recovers_gaussian_like_psf():
    """Dense Gaussian-distributed baselines give a Gaussian PSF of known width."""
    rng = np.random.default_rng(0)
    sig_uv = 1e6  # lambda: the PSF has sigma = 1 / (2 pi sig_uv) rad
    u, v = rng.normal(0, sig_uv, 40000), rng.normal(0, sig_uv / 2, 40000)
    bmaj, bmin, bpa = fit_beam(u, v)
    fwhm = 2 * np.sqrt(2 * np.log(2)) / (2 * np.pi * sig_uv) / ARCSEC
    assert bmin == pytest.approx(fwhm, rel=0.05)
    assert bmaj == pytest.approx(2 * fwhm, rel=0.05)
    assert abs(abs(bpa) - 0.0) < 3.0  # narrow in u: the beam is long north-south
