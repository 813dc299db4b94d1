"""Synthetic observations: uv geometry, noise level, model transforms, planted perturbations, presets."""

import numpy as np
import pytest
from scipy.special import j1

from spiralbayes.fourier import dirty_image
from spiralbayes.geometry import ARCSEC, DiscGeometry
from spiralbayes.simulate import (
    DiscModel,
    disc_visibilities,
    hankel_visibilities,
    uv_coverage,
)

LAM = 0.87e-3


GEOM = DiscGeometry(inc=40.0, PA=70.0, dRA=0.05, dDec=-0.03)

def test_gaussian_disc_matches_closed_form(short_cov):
    """Both paths (Hankel quadrature, supersampled image + NUFFT) vs the analytic transform."""
    s, A = 0.15, 1e10
    prof = lambda r: A * np.exp(-0.5 * (np.asarray(r) / s) ** 2)  # noqa: E731
    u, v = short_cov.u, short_cov.v
    up, vp = GEOM.deproject_uv(u, v)
    sr = s * ARCSEC
    ref = (GEOM.cos_inc * 2 * np.pi * sr**2 * A * np.exp(-2 * np.pi**2 * sr**2 * (up**2 + vp**2))
           * GEOM.phase_factor(u, v))
    peak = np.abs(ref).max()
    Vh = disc_visibilities(u, v, prof, GEOM, 8 * s, method="hankel")
    Vi = disc_visibilities(u, v, prof, GEOM, 8 * s, method="image")
    assert np.abs(Vh - ref).max() < 1e-4 * peak
    assert np.abs(Vi - ref).max() < 1e-4 * peak
    # the supersampling kernel correction is what makes the image path exact
    Vraw = disc_visibilities(u, v, prof, GEOM, 8 * s, method="image", pixel_window_correction=False)
    assert np.abs(Vraw - ref).max() > 10 * np.abs(Vi - ref).max()


def test_hankel_uniform_ring_matches_bessel_closed_form(short_cov):
    """A uniform annulus a < r < b: V(q) = I [b J1(2 pi q b) - a J1(2 pi q a)] / q."""
    a, b, I0 = 0.07, 0.79, 3e9
    prof = lambda r: np.where((r >= a) & (r <= b), I0, 0.0)  # noqa: E731
    u, v = short_cov.u, short_cov.v
    q = np.hypot(*GEOM.deproject_uv(u, v))
    ar, br = a * ARCSEC, b * ARCSEC
    ref = GEOM.cos_inc * I0 * (br * j1(2 * np.pi * q * br) - ar * j1(2 * np.pi * q * ar)) / q
    ref = ref * GEOM.phase_factor(u, v)
    V = hankel_visibilities(prof, u, v, GEOM, a, b)
    assert np.abs(V - ref).max() < 1e-6 * np.abs(ref).max()


def test_power_law_disc_flux_and_image_path_converge(short_cov):
    disc = DiscModel(flux=0.25)
    assert disc.r_min == pytest.approx(10 / 140) and disc.r_max == pytest.approx(110 / 140)
    prof = disc.profile(LAM)
    V0 = hankel_visibilities(prof, np.array([0.0]), np.array([0.0]), GEOM, disc.r_min, disc.r_max)
    assert V0[0].real == pytest.approx(0.25 * GEOM.cos_inc, rel=1e-10)
    u, v = short_cov.u, short_cov.v
    Vh = disc_visibilities(u, v, prof, GEOM, disc.r_max, r_min=disc.r_min)
    Vi = disc_visibilities(u, v, prof, GEOM, disc.r_max, method="image", pixel_size=0.002)
    # sharp edges limit the rendered image, not the exact Hankel path
    assert np.sqrt(np.mean(np.abs(Vi - Vh) ** 2)) < 2e-4 * np.sqrt(np.mean(np.abs(Vh) ** 2))


def test_brightness_is_planck_times_optical_depth():
    disc = DiscModel()
    r = np.array([0.05, 30 / 140, 50 / 140, 100 / 140, 0.9])
    I = disc.brightness(r, LAM)
    assert I[0] == 0 and I[-1] == 0
    nu = 299792458.0 / LAM
    T = 20.0 * (30 / 50) ** -0.5
    B = 2 * 6.62607015e-34 * nu**3 / 299792458.0**2 / np.expm1(6.62607015e-34 * nu / (1.380649e-23 * T))
    assert I[1] == pytest.approx(B * 1e26 * (1 - np.exp(-0.3 * 50 / 30)), rel=1e-12)


class BlobTemplate:
    """A stand-in for a spiral template: a Gaussian bump at the planet in the disc plane."""

    name = "blob"

    def __init__(self, amplitude=5.0, width=0.01):
        self.amplitude, self.width = amplitude, width

    def evaluate(self, r, phi, r_p, phi_p):
        dx = r * np.cos(phi) - r_p * np.cos(phi_p)
        dy = r * np.sin(phi) - r_p * np.sin(phi_p)
        return self.amplitude * np.exp(-0.5 * (dx**2 + dy**2) / self.width**2)


@pytest.mark.parametrize("phi_p", [0.0, 1.0, 2.5, -2.0])
def test_point_perturbation_appears_at_disc_to_sky_position(phi_p):
    cov = uv_coverage(["C-4", "C-7"], -25.0, [(-0.05, 0.05), (-0.5, 0.5)], 120.0, LAM)
    disc, r_p = DiscModel(), 0.4
    prof = disc.profile(LAM)
    kw = dict(r_min=disc.r_min)
    V1 = disc_visibilities(cov.u, cov.v, prof, GEOM, disc.r_max, perturbation=BlobTemplate(),
                           r_p=r_p, phi_p=phi_p, **kw)
    V0 = disc_visibilities(cov.u, cov.v, prof, GEOM, disc.r_max, **kw)
    n, pix = 512, 0.005
    img = dirty_image(cov.u, cov.v, V1 - V0, np.ones(cov.n), (n, n), pix)
    iy, ix = np.unravel_index(np.argmax(img), img.shape)
    l_peak, m_peak = -(ix - n // 2) * pix, (iy - n // 2) * pix
    l_true, m_true = GEOM.disc_to_sky(r_p, phi_p)
    assert np.hypot(l_peak - l_true, m_peak - m_true) <= 1.5 * pix
    # the same perturbation as a plain callable delta(r, phi) gives the same visibilities
    blob = BlobTemplate()
    V2 = disc_visibilities(cov.u, cov.v, prof, GEOM, disc.r_max,
                           perturbation=lambda r, phi: blob.evaluate(r, phi, r_p, phi_p), **kw)
    np.testing.assert_allclose(V2, V1, rtol=0, atol=1e-12)


def test_template_perturbation_needs_planet_position(short_cov):
    with pytest.raises(ValueError, match="r_p"):
        disc_visibilities(short_cov.u, short_cov.v, DiscModel().profile(LAM), GEOM, 0.8,
                          perturbation=BlobTemplate())
