"""Fourier sampling: sign convention, NUFFT vs direct sum, analytic Gaussians, adjoint."""

import numpy as np
import pytest

from spiralbayes.fourier import (
    ImageGridError,
    ImageSampler,
    check_image_grid,
    dirty_image,
    image_axes,
    psf,
    sample_image,
    sample_image_dft,
    sample_image_fft_bilinear,
    suggest_image_grid,
)
from spiralbayes.geometry import ARCSEC, DiscGeometry


def random_baselines(rng, n, uv_max=2e6, uv_min=2e4):
    q = rng.uniform(uv_min, uv_max, n)
    theta = rng.uniform(0, 2 * np.pi, n)
    return q * np.cos(theta), q * np.sin(theta)


def test_image_axes_centre_and_orientation():
    l, m = image_axes((8, 8), 0.1)
    assert l[4] == 0 and m[4] == 0
    assert l[0] > 0 > l[-1]  # east on the left of the array
    assert m[0] < 0 < m[-1]


def test_point_source_east_of_phase_centre_comes_out_east():
    """A source at l > 0 (east) must give V = exp(+2 pi i u l) (CASA/frank/galario sign)."""
    n, pix = 64, 0.01
    image = np.zeros((n, n))
    ix = n // 2 - 5  # five pixels towards smaller ix = east
    image[n // 2, ix] = 1.0
    l_src = 5 * pix
    u = np.array([1e5, -3e5, 0.0, 2e4])
    v = np.array([0.0, 1e5, 2e5, 3e4])
    V = sample_image(image, pix, u, v, check=False)
    expected = np.exp(2j * np.pi * u * l_src * ARCSEC)
    np.testing.assert_allclose(V, expected, atol=1e-9)
    # the dirty image of those visibilities peaks east, where the source is
    rng = np.random.default_rng(1)
    uu, vv = random_baselines(rng, 400, uv_max=4e6)
    Vs = np.exp(2j * np.pi * uu * l_src * ARCSEC)
    dirty = dirty_image(uu, vv, Vs, np.ones(uu.size), (n, n), pix)
    iy, jx = np.unravel_index(np.argmax(dirty), dirty.shape)
    assert (iy, jx) == (n // 2, ix)


def test_offset_moves_source_east():
    n, pix = 32, 0.02
    image = np.zeros((n, n))
    image[n // 2, n // 2] = 2.0
    u, v = np.array([3e5, 1e4]), np.array([-2e5, 4e5])
    V = sample_image(image, pix, u, v, dRA=0.1, dDec=-0.05, check=False)
    expected = 2.0 * np.exp(2j * np.pi * (u * 0.1 - v * 0.05) * ARCSEC)
    np.testing.assert_allclose(V, expected, atol=1e-9)


@pytest.mark.parametrize("geom", [DiscGeometry(), DiscGeometry(0, 37.0, 0.03, -0.02), DiscGeometry(0, -110.0)])
def test_nufft_matches_direct_sum(geom):
    rng = np.random.default_rng(42)
    n, pix = 96, 0.02
    image = rng.normal(size=(n, n))
    u, v = random_baselines(rng, 500, uv_max=0.49 / (pix * ARCSEC) / 1.5, uv_min=1.0 / (n * pix * ARCSEC))
    V_fast = sample_image(image, pix, u, v, geom)
    V_ref = sample_image_dft(image, pix, u, v, geom)
    err = np.sqrt(np.mean(np.abs(V_fast - V_ref) ** 2) / np.mean(np.abs(V_ref) ** 2))
    assert err < 1e-6
    assert np.max(np.abs(V_fast - V_ref)) / np.max(np.abs(V_ref)) < 1e-6


def gaussian_disc_image(shape, pix, sigma, inc):
    l, m = image_axes(shape, pix)
    L, M = np.meshgrid(l, m)
    x = L / np.cos(np.radians(inc))  # major axis north before rotation
    return np.exp(-(x ** 2 + M ** 2) / (2 * sigma ** 2)) * pix ** 2


def test_inclined_rotated_offset_gaussian_matches_closed_form():
    """I(r) = exp(-r^2 / 2 sigma^2) [Jy/arcsec^2] in the disc plane, inclined, rotated, offset."""
    geom = DiscGeometry(inc=55.0, PA=123.0, dRA=0.04, dDec=-0.07)
    n, pix, sigma = 256, 0.01, 0.15
    image = gaussian_disc_image((n, n), pix, sigma, geom.inc)
    rng = np.random.default_rng(3)
    u, v = random_baselines(rng, 2000, uv_max=1.5e6, uv_min=1e4)
    V = sample_image(image, pix, u, v, geom)
    up, vp = geom.deproject_uv(u, v)
    s = sigma * ARCSEC
    closed = (2 * np.pi * sigma ** 2 * geom.cos_inc * np.exp(-2 * np.pi ** 2 * s ** 2 * (up ** 2 + vp ** 2))
              * geom.phase_factor(u, v))
    assert np.max(np.abs(V - closed)) / np.max(np.abs(closed)) < 1e-6


def test_adjoint_is_exact_adjoint():
    rng = np.random.default_rng(5)
    shape, pix = (40, 48), 0.03
    u, v = random_baselines(rng, 300, uv_max=3e6)
    sampler = ImageSampler(u, v, shape, pix, PA=20.0, dRA=0.01, check=False)
    x = rng.normal(size=shape)
    y = rng.normal(size=u.size) + 1j * rng.normal(size=u.size)
    lhs = np.vdot(y, sampler.sample(x))
    rhs = np.vdot(sampler.adjoint(y), x)
    assert abs(lhs - rhs) / abs(lhs) < 1e-8


def test_psf_peaks_at_one_at_centre():
    rng = np.random.default_rng(6)
    u, v = random_baselines(rng, 500, uv_max=1e6)
    beam = psf(u, v, rng.uniform(1, 2, u.size), (64, 64), 0.05)
    assert beam[32, 32] == pytest.approx(1.0)
    assert beam.max() == pytest.approx(1.0)


def test_fft_bilinear_baseline_is_close_but_not_exact():
    geom = DiscGeometry(0, 30.0, 0.02, 0.01)
    n, pix = 256, 0.01
    image = gaussian_disc_image((n, n), pix, 0.1, 40.0)
    rng = np.random.default_rng(7)
    u, v = random_baselines(rng, 200, uv_max=1e6)
    ref = sample_image(image, pix, u, v, geom)
    approx = sample_image_fft_bilinear(image, pix, u, v, geom, pad=2)
    err = np.max(np.abs(approx - ref)) / np.max(np.abs(ref))
    assert 1e-8 < err < 0.05


def test_grid_checks_refuse_coarse_or_small_images():
    u, v = np.array([1e4, 2e6]), np.array([0.0, 0.0])
    with pytest.raises(ImageGridError, match="too coarse.*pixel_size <="):
        check_image_grid(u, v, (1024, 1024), 0.1)
    with pytest.raises(ImageGridError, match="too small.*at least"):
        check_image_grid(u, v, (16, 16), 0.02)
    n, pix = suggest_image_grid(u, v)
    check_image_grid(u, v, (n, n), pix)
    with pytest.raises(ImageGridError, match="too small"):
        ImageSampler(u, v, (16, 16), 0.02, check="full")
    with pytest.raises(ImageGridError, match="too coarse"):
        ImageSampler(u, v, (16, 16), 0.1)
    ImageSampler(u, v, (16, 16), 0.02)  # compact image: exact for the NUFFT, accepted by default
