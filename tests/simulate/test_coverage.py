"""Synthetic observations: uv geometry, noise level, model transforms, planted perturbations, presets."""

from importlib import resources

import numpy as np
import pytest

from spiralbayes.simulate import (
    ALMA_LATITUDE,
    available_configurations,
    baseline_uvw,
    elevation,
    load_configuration,
    uv_coverage,
)

LAM = 0.87e-3
LONGEST = {"C-4": 783.5, "C-5": 1397.9, "C-6": 2516.9, "C-7": 3637.8, "C-8": 8547.8}  # data README


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
