"""FITS templates in the layout of Stevenson et al. (2024)."""

import numpy as np
import pytest
from astropy.io import fits

from spiralbayes.templates import make_template, read_fits_template, write_fits_template


def test_roundtrip_paper_layout(tmp_path):
    t = make_template(1.0, 0.3, 0.0, n_x=40, n_phi=180, n_eta=512)
    base = tmp_path / "f3d2c_dust1_orbit1500_EOSiso_EPSTEIN_2D_CPD0"
    files = write_fits_template(t, base)
    assert all(f.exists() for f in files)
    back = read_fits_template(base, mass=1.0, tau0=0.3, beta=0.0)
    np.testing.assert_allclose(back.x, t.x)
    np.testing.assert_allclose(back.delta, t.delta, atol=1e-6)
    assert back.hand == "R" and back.mass == 1.0


def test_authors_shift_and_transpose(tmp_path):
    """Map stored transposed (n_φ, n_r) on FARGO azimuths (−π, π) and shifted by π, r in au."""
    n_r, n_phi = 20, 120
    r_au = 50.0 * np.geomspace(0.3, 2.0, n_r)
    t_unshifted = -np.pi + (np.arange(n_phi) + 0.5) * 2 * np.pi / n_phi
    t_shifted = t_unshifted + np.pi
    # a feature at disc azimuth +0.6 rad from the planet, radius 1.2 r_p
    phi_disc = t_shifted + (t_shifted[0] - t_unshifted[0])  # authors: column k at tcenters[k] + Δφ
    dphi = (phi_disc - 0.6 + np.pi) % (2 * np.pi) - np.pi
    delta = np.exp(-((r_au[:, None] / 50 - 1.2) / 0.1) ** 2 - (dphi[None, :] / 0.1) ** 2)
    delta[0, 0] = np.nan
    base = str(tmp_path / "tmpl")
    fits.PrimaryHDU(delta.T).writeto(base + "_intens_frac_rt.fits")
    fits.PrimaryHDU(r_au).writeto(base + "_rcenters.fits")
    fits.PrimaryHDU(t_shifted).writeto(base + "_tcenters.fits")
    fits.PrimaryHDU(t_unshifted).writeto(base + "_tcenters_notshifted.fits")
    t = read_fits_template(base)
    i, j = np.unravel_index(np.argmax(t.delta), t.delta.shape)
    assert t.x[i] == pytest.approx(1.2, rel=0.06)
    assert (t.phi[j] + np.pi) % (2 * np.pi) - np.pi == pytest.approx(0.6, abs=2 * np.pi / n_phi)
    assert np.all(np.isfinite(t.delta))


def test_missing_fits_files(tmp_path):
    with pytest.raises(FileNotFoundError, match="_intens_frac_rt.fits|not found"):
        read_fits_template(tmp_path / "nothing")
    p = tmp_path / "delta.fits"
    fits.PrimaryHDU(np.zeros((3, 4))).writeto(p)
    with pytest.raises(ValueError, match="r_file"):
        read_fits_template(p)
