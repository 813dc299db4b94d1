"""Image-plane comparisons: the statistics on synthetic images (always), tclean on simulated data (``casa``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from spiralbayes.image_plane import (
    CleanImage,
    default_clean_grid,
    gap_depth,
    radial_profile,
    residual_detection,
)
from spiralbayes.fourier import image_axes
from spiralbayes.geometry import DiscGeometry
from spiralbayes.visibilities import Visibilities

GEOM = DiscGeometry(30.0, 60.0)
CELL = 0.02


def _disc_r(shape, geometry=GEOM, cell=CELL):
    l, m = image_axes(shape, cell)
    ll, mm = np.meshgrid(l, m)
    return geometry.sky_to_disc(ll, mm)


def _smooth_noise(rng, n, beam_fwhm_pixels):
    """Gaussian random field whose correlation function is a Gaussian of FWHM ``beam_fwhm_pixels``."""
    k = np.fft.fftfreq(n)
    kx, ky = np.meshgrid(k, k)
    sigma = beam_fwhm_pixels / math.sqrt(2.0) / (2.0 * math.sqrt(2.0 * math.log(2.0)))  # kernel of FWHM beam / sqrt 2
    kernel = np.exp(-2.0 * np.pi**2 * sigma**2 * (kx**2 + ky**2))
    return np.fft.ifft2(np.fft.fft2(rng.normal(size=(n, n))) * kernel).real


@pytest.mark.parametrize("beam_pixels", [4.0, 7.0])
def test_residual_false_alarm_rate_is_calibrated(beam_pixels):
    """On pure noise correlated like the beam, p < 0.05 happens in ~5 % of images (Monte Carlo)."""
    rng = np.random.default_rng(0)
    beam = (beam_pixels * CELL, beam_pixels * CELL, 0.0)
    p_values = np.array([residual_detection(_smooth_noise(rng, 192, beam_pixels), CELL, GEOM, 0.5, beam).p_false_alarm
                         for _ in range(400)])
    for level in (0.01, 0.05, 0.2):
        rate = np.mean(p_values < level)
        tolerance = 3.5 * math.sqrt(level * (1 - level) / p_values.size) + 0.005
        assert rate < level + tolerance, (level, rate)
        if level <= 0.05:  # calibrated where decisions are made; conservative for large p (EC approximation)
            assert rate > level - tolerance, (level, rate)


def test_residual_peak_is_found_where_it_was_put():
    rng = np.random.default_rng(1)
    image = rng.normal(size=(128, 128))
    r_true, phi_true = 0.3, np.radians(70.0)
    l0, m0 = GEOM.disc_to_sky(r_true, phi_true)
    ix, iy = 64 - round(l0 / CELL), 64 + round(m0 / CELL)
    image[iy, ix] += 9.0
    beam_fwhm = CELL / math.sqrt(math.pi / (4 * math.log(2)))
    det = residual_detection(image, CELL, GEOM, 0.5, (beam_fwhm, beam_fwhm, 0.0))
    assert det.verdict == "detected" and det.peak_snr > 8
    assert det.noise == pytest.approx(1.0, rel=0.05)
    assert det.peak_r == pytest.approx(r_true, abs=2 * CELL / GEOM.cos_inc)
    assert det.peak_phi_deg == pytest.approx(70.0, abs=8.0)
    n_disc = np.sum(_disc_r(image.shape)[0] < 0.5)
    assert det.n_beams == pytest.approx(n_disc, rel=0.05)  # one beam per pixel: the disc's pixel count


def test_residual_detection_needs_sky_outside_the_disc():
    with pytest.raises(ValueError, match="too little sky"):
        residual_detection(np.zeros((40, 40)), CELL, GEOM, 0.4, (0.1, 0.1, 0.0))


def _clean_of_profile(profile, noise=0.0, seed=0, shape=(256, 256), beam=(0.08, 0.08, 0.0)):
    r, _ = _disc_r(shape)
    image = profile(r)
    residual = np.random.default_rng(seed).normal(scale=noise, size=shape) if noise else np.zeros(shape)
    return CleanImage(image=image + residual, residual=residual, model=np.zeros(shape), cell=CELL, beam=beam,
                      sumwt=1.0, iterations=0)


def test_radial_profile_recovers_an_inclined_axisymmetric_image():
    profile = lambda r: np.exp(-0.5 * (r / 0.6) ** 2)  # noqa: E731
    clean = _clean_of_profile(profile)
    r, mean, counts = radial_profile(clean.image, CELL, GEOM, 1.5, 0.05)
    assert np.all(counts > 0) and r[0] == pytest.approx(0.025)
    # the mean over an annulus of a smooth profile: its value at the centre to second order in the width
    np.testing.assert_allclose(mean[2:], profile(r[2:]), atol=2e-3)


def test_gap_depth_matches_the_profile_it_was_drawn_from():
    def gapped(r):
        return 1e-2 * (0.2 + r) ** -1 * (1.0 - 0.7 * np.exp(-0.5 * ((r - 0.5) / 0.06) ** 2)) * (r < 1.0)

    gap = gap_depth(_clean_of_profile(gapped, noise=1e-5), GEOM, 0.95, bin_width=0.02)
    fine = np.linspace(0.3, 0.9, 6001)
    i_gap = np.argmin(np.where(fine < 0.55, gapped(fine), np.inf))
    i_ring = i_gap + np.argmax(gapped(fine[i_gap:]) * (fine[i_gap:] < 0.8))
    expected = gapped(fine[i_ring]) / gapped(fine[i_gap])
    assert gap.verdict == "clear"
    assert gap.delta == pytest.approx(expected, rel=0.05)  # bins of 0.02" average the sharp minimum
    assert gap.r_gap == pytest.approx(fine[i_gap], abs=0.03) and gap.r_ring == pytest.approx(fine[i_ring], abs=0.03)


def test_no_gap_in_a_power_law_and_a_shallow_one_is_marginal():
    smooth = gap_depth(_clean_of_profile(lambda r: 1e-2 * (0.2 + r) ** -1 * (r < 1.0), noise=1e-5), GEOM, 0.95)
    assert smooth.verdict == "none" and smooth.delta < 1.05

    def shallow(r):
        return 1e-2 * (1.0 - 0.25 * np.exp(-0.5 * ((r - 0.5) / 0.06) ** 2)) * (r < 1.0)

    gap = gap_depth(_clean_of_profile(shallow, noise=1e-5), GEOM, 0.95)
    assert gap.verdict == "marginal" and 1.1 < gap.delta < 1.5


def test_default_clean_grid_resolves_the_longest_baseline_and_fits_the_disc():
    rng = np.random.default_rng(2)
    u, v = rng.uniform(-4e6, 4e6, (2, 500))
    vis = Visibilities(u, v, np.ones(500), np.ones(500), wavelength=1e-3)
    n, cell = default_clean_grid(vis, 0.8)
    q_max = np.max(np.hypot(u, v))
    assert cell <= 1.0 / (2.0 * q_max) / 4.8481368e-6  # Nyquist
    assert n * cell >= 4.8 and n % 2 == 0
    assert all(p in (2, 3, 5) for p in _prime_factors(n))


def _prime_factors(n):
    out, k = [], 2
    while n > 1:
        while n % k == 0:
            out.append(k)
            n //= k
        k += 1
    return out


# ----------------------------------------------------------------------------- with CASA
@pytest.fixture(scope="module")
def casa():
    from tests._support.casa_support import require_casa

    return require_casa()


@pytest.mark.casa
def test_clean_image_of_a_point_source(casa, tmp_path):
    """tclean puts 10 mJy 0.1" east; its natural beam matches the package's PSF fit."""
    from spiralbayes.image_plane import clean_image
    from spiralbayes.simulate import fit_beam, observe, uv_coverage
    from spiralbayes.units import ARCSEC

    cov = uv_coverage(["C-4", "C-7"], -25.0, [(-0.02, 0.02), (-0.035, 0.035)], 30.0, 0.87e-3)
    vis = observe(lambda u, v: 0.01 * np.exp(2j * np.pi * u * 0.1 * ARCSEC), cov, sensitivity=50e-6, seed=2)
    clean = clean_image(vis, tmp_path, "point", imsize=200, cell=0.01, weighting="natural", niter=500,
                        threshold=2e-4)
    iy, ix = np.unravel_index(np.argmax(clean.image), clean.shape)
    assert (iy, ix) == (100, 90)
    assert clean.image.max() == pytest.approx(0.01, abs=4 * 50e-6)
    assert clean.model.sum() == pytest.approx(0.01, rel=0.05)
    assert clean.sumwt == pytest.approx(vis.weights.sum(), rel=1e-5)
    bmaj, bmin, _ = fit_beam(vis.u, vis.v, vis.weights)
    # CASA fits its PSF over its own region (6-min tracks: a non-Gaussian main lobe); measured +16 %
    assert clean.beam[0] == pytest.approx(bmaj, rel=0.25) and clean.beam[1] == pytest.approx(bmin, rel=0.25)
    assert clean.timings["tclean_wall_s"] > 0 and (tmp_path / "point.image").exists()


@pytest.mark.casa
def test_clean_residuals_of_an_axisymmetric_disc_show_nothing(casa, tmp_path):
    """Data = the axisymmetric model's own visibilities + noise: no residual detection and no gap."""
    from spiralbayes.axisymmetric import AxisymmetricModel
    from spiralbayes.image_plane import clean_residuals
    from spiralbayes.simulate import DiscModel, observe, preset_coverage

    disc = DiscModel(tau_ref=3.0)
    cov = preset_coverage("fiducial")
    truth = AxisymmetricModel.from_profile(disc.profile(cov.wavelength), GEOM, N=300, Rmax=1.2)
    vis = observe(truth.visibilities, cov, sensitivity=35e-6, seed=3)
    res = clean_residuals(vis, truth, tmp_path, r_out=disc.r_max)
    assert res.detection.verdict == "not detected", res.detection
    assert res.detection.noise == pytest.approx(35e-6, rel=0.5)  # Briggs 0.5: ~1.3 x the natural noise
    gap = gap_depth(res.data, GEOM, disc.r_max)
    assert gap.verdict == "none"
