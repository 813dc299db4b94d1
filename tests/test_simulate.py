"""Synthetic observations: uv geometry, noise level, model transforms, planted perturbations, presets."""

import json
from importlib import resources

import numpy as np
import pytest
from scipy.special import j1

from spiralbayes.fourier import dirty_image
from spiralbayes.geometry import ARCSEC, DiscGeometry
from spiralbayes.simulate import (
    ALMA_LATITUDE,
    PRESETS,
    DiscModel,
    Radiometer,
    available_configurations,
    baseline_uvw,
    disc_visibilities,
    elevation,
    fit_beam,
    hankel_visibilities,
    image_noise,
    load_configuration,
    measure_image_noise,
    observe,
    preset_table,
    simulate_observation,
    uv_coverage,
)
from spiralbayes.visibilities import Visibilities

LAM = 0.87e-3
LONGEST = {"C-4": 783.5, "C-5": 1397.9, "C-6": 2516.9, "C-7": 3637.8, "C-8": 8547.8}  # data README


@pytest.fixture(scope="module")
def short_cov():
    """C-4 + C-7, a few minutes each: fast, but with the fiducial's baseline range."""
    return uv_coverage(["C-4", "C-7"], -25.0, [(-0.05, 0.05), (-0.1, 0.1)], 30.0, LAM)


# --- configurations ------------------------------------------------------------------------
def test_packaged_configurations_found_via_importlib_resources():
    root = resources.files("spiralbayes").joinpath("data", "alma-configurations")
    assert root.joinpath("README.md").is_file()
    names = available_configurations()
    assert len(names) == 18 and "cycle11.10" in names and "cycle10.8" in names
    for name in names:
        pos = load_configuration(name)
        assert pos.shape == (43, 3)


@pytest.mark.parametrize("name", sorted(LONGEST))
def test_longest_baselines_match_data_readme(name):
    pos = load_configuration(name)
    d = np.sqrt(((pos[:, None] - pos[None]) ** 2).sum(-1))
    assert d.max() == pytest.approx(LONGEST[name], abs=0.06)
    np.testing.assert_array_equal(pos, load_configuration(f"cycle11.{name[2:]}"))
    np.testing.assert_array_equal(pos, load_configuration(name.replace("-", "").lower()))


def test_configuration_names_cycle10_and_paths(tmp_path):
    np.testing.assert_array_equal(load_configuration("C-4", cycle=10), load_configuration("cycle10.4"))
    np.testing.assert_array_equal(load_configuration("alma.cycle10.4.layout.txt"),
                                  load_configuration("cycle10.4"))
    f = tmp_path / "three.txt"
    np.savetxt(f, [[0, 0, 0], [100, 0, 0], [0, 50, 1]])
    assert load_configuration(f).shape == (3, 3)
    cov = uv_coverage(f, -23.0, (-0.01, 0.01), 30.0, LAM)
    assert cov.n == 3 * 2 and cov.configurations == [str(f)]


@pytest.mark.parametrize("bad", ["C-12", "cycle9.4", "C-4x", "compact"])
def test_unknown_configuration_lists_valid_ones(bad):
    with pytest.raises(ValueError, match=r"unknown ALMA configuration.*cycle11\.4.*C-M"):
        load_configuration(bad)
    with pytest.raises(ValueError, match="unknown ALMA configuration"):
        uv_coverage(["C-4", bad], -25.0, (-0.1, 0.1), 30.0, LAM)


# --- uv geometry -----------------------------------------------------------------------------
def test_baseline_hand_computation():
    """East-west and north-south baselines at transit and at H = 6 h (TMS eqs. 4.1, 4.15)."""
    lat, dec = np.radians(ALMA_LATITUDE), np.radians(-40.0)
    ew = baseline_uvw([100.0, 0, 0], 0.0, -40.0)
    np.testing.assert_allclose(ew, [100.0, 0, 0], atol=1e-12)
    ew6 = baseline_uvw([100.0, 0, 0], 6.0, -40.0)
    np.testing.assert_allclose(ew6, [0, 100 * np.sin(dec), -100 * np.cos(dec)], atol=1e-12)
    ns = baseline_uvw([0, 100.0, 0], 0.0, -40.0)
    np.testing.assert_allclose(ns, [0, 100 * np.cos(dec - lat), 100 * np.sin(dec - lat)], atol=1e-12)
    # a source at the zenith sees a north-south baseline at full length, with w = 0
    np.testing.assert_allclose(baseline_uvw([0, 100.0, 0], 0.0, ALMA_LATITUDE), [0, 100, 0], atol=1e-12)


def test_w_is_baseline_along_source_direction():
    """For a vertical baseline w = h sin(elevation); for any, |(u, v, w)| = |b|."""
    H = np.linspace(-4, 4, 17)
    w = baseline_uvw([0, 0, 10.0], H, -60.0)[:, 2]
    np.testing.assert_allclose(w, 10.0 * np.sin(np.radians(elevation(H, -60.0))), atol=1e-12)
    rng = np.random.default_rng(3)
    b = rng.normal(size=(50, 3)) * 500
    uvw = baseline_uvw(b, rng.uniform(-6, 6, 50), -35.0)
    np.testing.assert_allclose(np.linalg.norm(uvw, axis=-1), np.linalg.norm(b, axis=-1), rtol=1e-12)


def test_polar_source_from_polar_array_gives_circular_tracks():
    b = np.array([300.0, -120.0, 4.0])
    H = np.linspace(0, 24, 49)
    uvw = baseline_uvw(b, H, -90.0, latitude=-90.0)
    np.testing.assert_allclose(np.hypot(uvw[:, 0], uvw[:, 1]), np.hypot(b[0], b[1]), rtol=1e-12)
    np.testing.assert_allclose(uvw[:, 2], b[2], atol=1e-9)  # the source is at the zenith


@pytest.mark.parametrize("config", ["C-4", "C-7"])
def test_baselines_not_longer_than_configuration(config):
    cov = uv_coverage(config, -25.0, (-2.0, 2.0), 300.0, LAM)
    assert cov.n == 903 * 47  # 4 h of hour angle = 3.989 h of time (sidereal rate): 47 x 300 s
    pos = load_configuration(config)
    longest = np.sqrt(((pos[:, None] - pos[None]) ** 2).sum(-1)).max()
    uvw = np.sqrt(cov.u**2 + cov.v**2 + cov.w**2)
    assert cov.uv_distance.max() <= longest / LAM * (1 + 1e-12)
    assert uvw.max() == pytest.approx(longest / LAM, rel=1e-12)
    assert cov.uv_distance.max() > 0.8 * longest / LAM


def test_multi_configuration_concatenates_with_own_time_ranges(short_cov):
    n4, n7 = (short_cov.configuration == 0).sum(), (short_cov.configuration == 1).sum()
    # 0.1 h and 0.2 h of hour angle hold 11 and 23 integrations of 30 s (sidereal rate 1.0027)
    assert (n4, n7) == (903 * 11, 903 * 23)
    assert short_cov.configurations == ["cycle11.4", "cycle11.7"]
    assert np.abs(short_cov.hour_angle[short_cov.configuration == 0]).max() < 0.05


def test_elevation_limit_drops_integrations():
    cov = uv_coverage("C-4", -25.0, (3.0, 6.0), 600.0, LAM, min_elevation=30.0)
    el = elevation(np.unique(cov.hour_angle), -25.0)
    assert el.min() >= 30.0 and cov.n_dropped > 0


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


# --- model discs -------------------------------------------------------------------------------
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


# --- presets ----------------------------------------------------------------------------------------
def test_presets_sizes_close_to_paper():
    rows = preset_table(measure=False)
    assert [r["name"] for r in rows] == ["fiducial", "high_sensitivity", "low_sensitivity",
                                         "high_resolution", "taurus"]
    for row in rows:
        assert abs(row["6lnN"] - row["paper_6lnN"]) < 1.0, row
        # the radiometer equation with typical T_sys agrees with the requested noise within 30 %
        assert row["radiometer_noise"] == pytest.approx(row["sensitivity"], rel=0.3), row


def test_simulate_observation_preset_end_to_end():
    vis = simulate_observation("taurus", DiscModel(flux=0.1), DiscGeometry(35, 120), BlobTemplate(),
                               r_p=0.4, phi_p=1.0, seed=2)
    assert isinstance(vis, Visibilities) and vis.n == PRESETS["taurus"].coverage().n
    assert vis.wavelength == pytest.approx(1.33e-3)
    prov = vis.provenance
    assert prov["preset"]["name"] == "taurus" and prov["seed"] == 2
    assert prov["model"]["perturbation"] == "blob" and prov["model"]["r_p_arcsec"] == 0.4
    json.dumps(prov)  # plain types: every writer can store it
    assert image_noise(vis.weights) == pytest.approx(50e-6)
    again = simulate_observation("taurus", DiscModel(flux=0.1), DiscGeometry(35, 120), BlobTemplate(),
                                 r_p=0.4, phi_p=1.0, seed=2)
    np.testing.assert_array_equal(vis.V, again.V)


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


# --- errors -----------------------------------------------------------------------------------------
def test_unknown_preset():
    with pytest.raises(ValueError, match="unknown preset 'fidu'.*fiducial.*taurus"):
        simulate_observation("fidu")


@pytest.mark.parametrize("hours, match", [
    ((0.5, -0.5), "no data"),
    ((0.0, 0.001), "shorter than one integration"),
    ((7.0, 9.0), "below min_elevation.*throughout"),
])
def test_hour_angles_giving_no_data(hours, match):
    with pytest.raises(ValueError, match=match):
        uv_coverage("C-4", -25.0, hours, 30.0, LAM)


def test_source_never_above_horizon():
    with pytest.raises(ValueError, match=r"\+70.* never rises above min_elevation"):
        uv_coverage("C-4", 70.0, (-1, 1), 30.0, LAM)
    with pytest.raises(ValueError, match="never rises"):
        uv_coverage("C-4", 55.0, (-1, 1), 30.0, LAM)  # up to 12 deg only, below the 15 deg limit
    assert uv_coverage("C-4", 55.0, (-0.1, 0.1), 30.0, LAM, min_elevation=5.0).n > 0


def test_bad_wavelength_and_hour_angle_shapes():
    with pytest.raises(ValueError, match="metres"):
        uv_coverage("C-4", -25.0, (-0.1, 0.1), 30.0, 870.0)
    with pytest.raises(ValueError, match="exactly one"):
        uv_coverage("C-4", -25.0, (-0.1, 0.1), 30.0)
    with pytest.raises(ValueError, match="one \\(start, end\\) per configuration"):
        uv_coverage(["C-4", "C-7"], -25.0, [(-0.1, 0.1)] * 3, 30.0, LAM)
    cov = uv_coverage("C-4", -25.0, (-0.1, 0.1), 30.0, frequency=345e9)
    assert cov.wavelength == pytest.approx(299792458.0 / 345e9)
