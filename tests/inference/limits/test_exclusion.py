"""Exclusion limits: the amplitude test, azimuths, the limiting mass, flags, the table, errors."""

import numpy as np
import pytest
from scipy.stats import norm

from spiralbayes.inference.limits.exclusion import ExclusionLimits, amplitude_upper_limit, compute_limits, z_score
from spiralbayes.inference.limits.table3 import build_table3, limits_table, table_markdown, write_table
from spiralbayes.inference.scan.run import ScanResult
from spiralbayes.units import mth_to_mjup
from tests._support import limits_setup


def fake_scan(cross, power, masses=(0.3, 1.0, 3.0), r_p=(0.1, 0.2, 0.3), distance=140.0):
    """A ScanResult of one family (R, L per mass) with given cross/power arrays."""
    meta = []
    for m in masses:
        for hand in ("R", "L"):
            meta.append({"name": f"t_m{m}_{hand}", "mass": m, "tau0": 0.3, "beta": 10.0, "hand": hand, "h_p": 0.07})
    n_phi = max([np.shape(a)[-1] for a in (cross, power) if np.ndim(a) == 3] or [5])
    shape = (len(meta), len(r_p), n_phi)
    cross, power = np.broadcast_arrays(np.asarray(cross, float), np.asarray(power, float), np.empty(shape))[:2]
    return ScanResult(meta, np.asarray(r_p, float), 2 * np.pi * np.arange(n_phi) / n_phi, cross.copy(),
                      power.copy(), 0.0, 10000, limits_setup.GEOMETRY, distance)


def test_upper_limit_is_the_one_sided_gaussian_bound():
    rng = np.random.default_rng(0)
    power = rng.uniform(1, 100, (4, 7))
    cross = rng.normal(0, 10, (4, 7))
    a_hat, sigma = cross / power, 1 / np.sqrt(power)
    np.testing.assert_allclose(amplitude_upper_limit(cross, power, 0.95), a_hat + 1.6448536 * sigma, rtol=1e-6)
    np.testing.assert_allclose(amplitude_upper_limit(cross, power, 0.95, "all_phi"),
                               np.max(a_hat + 1.6448536 * sigma, axis=-1), rtol=1e-6)
    # one azimuth: the phi-marginalised bound is the per-instance bound
    single = amplitude_upper_limit(cross[:, :1], power[:, :1], 0.9, "marginal")
    np.testing.assert_allclose(single, (a_hat + norm.ppf(0.9) * sigma)[:, 0], rtol=1e-6)
    # marginalising over azimuths never excludes more than the largest per-azimuth bound allows
    assert np.all(amplitude_upper_limit(cross, power, 0.95, "marginal") <= np.max(a_hat + 1.65 * sigma, axis=-1) + 1e-9)


def test_marginal_bound_matches_numerical_mixture():
    """Flat prior on A, uniform over azimuths: P(A > A_up) = 1 - CL from a direct integration."""
    power = np.array([[4.0, 25.0, 9.0]])
    cross = np.array([[1.0, -5.0, 6.0]])
    up = amplitude_upper_limit(cross, power, 0.9, "marginal")[0]
    a = np.linspace(-10, 10, 200001)
    like = np.exp(-0.5 * (power.T * a ** 2 - 2 * cross.T * a)).sum(axis=0)
    tail = like[a > up].sum() / like.sum()
    assert tail == pytest.approx(0.1, abs=1e-4)


def test_limiting_mass_interpolates_log_upper_limit_in_log_mass():
    # noise-free, no planet: A_hat = 0 and A_up = z / sqrt(power)
    z = z_score(0.95)
    u = np.array([2.0, 0.5, 0.1])  # A_up of the masses 0.3, 1, 3 at every radius and azimuth
    power = (z / u) ** 2
    power = np.repeat(power, 2)[:, None, None] * np.ones((6, 3, 5))
    limits = compute_limits(fake_scan(0.0, power))
    expected = np.exp(np.log(0.3) + np.log(2.0) / (np.log(2.0) - np.log(0.5)) * np.log(1 / 0.3))
    np.testing.assert_allclose(limits.m_lim[0], expected, rtol=1e-9)
    assert set(limits.m_lim_status[0]) == {"limit"}
    np.testing.assert_allclose(limits.excluded_fraction, np.repeat([0.0, 1.0, 1.0], 2)[:, None] * np.ones((6, 3)))
    assert limits.excluded(mass=1.0).all() and not limits.excluded(mass=0.3).any()
    np.testing.assert_allclose(limits.m_lim_mjup(), mth_to_mjup(expected, limits.r_p, 0.8, distance=140.0))


def test_all_phi_needs_every_azimuth_and_both_hands():
    z = z_score(0.95)
    power = np.full((6, 1, 4), (z / 0.5) ** 2)  # A_up = 0.5 everywhere: all excluded
    cross = np.zeros((6, 1, 4))
    cross[2, 0, 1] = power[2, 0, 1] * 0.9  # R template of 1 M_th fits at one azimuth: A_up = 1.4 there
    limits = compute_limits(fake_scan(cross, power, r_p=[0.2]))
    assert limits.m_lim_status[0, 0] == "limit" and 1.0 < limits.m_lim[0, 0] < 3.0
    assert limits.excluded_fraction[2, 0] == 0.75
    only_left = compute_limits(fake_scan(cross, power, r_p=[0.2]), hand="L")
    assert only_left.m_lim_status[0, 0] == "below_bank"
    marginal = compute_limits(fake_scan(cross, power, r_p=[0.2]), method="marginal")
    assert marginal.upper_limit[2, 0] < limits.upper_limit[2, 0]


def test_no_limit_and_below_bank():
    z = z_score(0.95)
    weak = fake_scan(0.0, (z / 5.0) ** 2)  # A_up = 5 for every mass: nothing excluded
    assert set(compute_limits(weak).m_lim_status[0]) == {"none"}
    strong = fake_scan(0.0, (z / 0.1) ** 2)
    limits = compute_limits(strong)
    assert set(limits.m_lim_status[0]) == {"below_bank"} and np.all(limits.m_lim[0] == 0.3)


def test_flagged_radii_are_not_excluded():
    z = z_score(0.95)
    scan_result = fake_scan(0.0, (z / 0.1) ** 2, r_p=[0.05, 0.2, 0.3, 0.6])
    limits = compute_limits(scan_result, resolution=0.1, bright_radius=0.5)
    assert limits.flags.tolist() == ["unresolved", "", "", "beyond_bright_extent"]
    assert limits.m_lim_status[0].tolist() == ["flagged", "below_bank", "below_bank", "flagged"]
    assert np.isnan(limits.m_lim[0, [0, 3]]).all()
    assert limits.excluded(mass=3.0).tolist() == [False, True, True, False]
    assert limits.excluded_ranges(mass=1.0) == [(0.2, 0.3)]


def test_real_scan_limits_lie_between_bank_masses(limits_case):
    vis, model, templates, result = limits_case
    limits = compute_limits(result, vis=vis, axisymmetric=model)
    assert 0.1 < limits.resolution < 0.6  # C-4 at 0.87 mm: a natural beam of ~0.3 arcsec
    assert limits.bright_radius == pytest.approx(model.R_eff(0.95))
    ok = limits.m_lim_status[0] == "limit"
    assert ok.sum() >= 2 and np.all((limits.m_lim[0][ok] > 0.3) & (limits.m_lim[0][ok] < 3.0))


def test_table3_names_the_family_and_ranges(tmp_path):
    z = z_score(0.95)
    power = np.repeat((z / np.array([2.0, 0.8, 0.1])) ** 2, 2)[:, None, None] * np.ones((6, 4, 3))
    power[:, 0] = 1e-3  # nothing excluded at the first radius
    limits = compute_limits(fake_scan(0.0, power, r_p=[0.1, 0.2, 0.3, 0.4]))
    text = table_markdown(limits, name="synthetic")
    assert "tau0=0.3, beta=10, h_p=0.07" in text and "synthetic" in text
    assert "28-56 au" in text and "M_Jup" in text
    rows = limits_table(limits, name="synthetic")
    three = [r for r in rows if r["mass_mth"] == 3.0]
    assert three[0]["r_min_au"] == pytest.approx(28.0) and three[0]["r_max_au"] == pytest.approx(56.0)
    assert three[0]["m_min_mjup"] == pytest.approx(mth_to_mjup(3.0, 0.2, 0.8, distance=140.0))
    table = build_table3(limits, name="synthetic")
    assert table.colnames == ["disc", "families", "morphologies", "price_of_robustness", "excluded_ge3Mth",
                              "excluded_ge1Mth"]
    assert table["excluded_ge3Mth"][0].startswith("28-56 au (") and table["morphologies"][0] == "unlabelled"
    ecsv, md = write_table(table, tmp_path / "table3")
    from astropy.table import Table

    back = Table.read(ecsv, format="ascii.ecsv")
    assert list(back["excluded_ge3Mth"]) == list(table["excluded_ge3Mth"]) and back.meta["caption"] in text
    assert md.read_text() == text
    assert "family tau0=0.3, beta=10, h_p=0.07" in limits.summary()
    path = limits.save(tmp_path / "limits.h5")
    loaded = ExclusionLimits.load(path)
    np.testing.assert_array_equal(loaded.m_lim, limits.m_lim)
    assert loaded.m_lim_status.tolist() == limits.m_lim_status.tolist()
    assert loaded.families[0].label == limits.families[0].label and loaded.summary() == limits.summary()


@pytest.mark.parametrize("cl", [0.3, 1.0, 1.2, "high"])
def test_bad_confidence_level_is_refused(cl):
    with pytest.raises(ValueError, match="confidence level"):
        compute_limits(fake_scan(0.0, 1.0), cl=cl)


def test_empty_family_and_grid_outside_the_data_are_refused():
    scan_result = fake_scan(0.0, 1.0, r_p=[0.05, 0.08])
    with pytest.raises(ValueError, match="outside the data"):
        compute_limits(scan_result, resolution=0.1)
    limits = compute_limits(fake_scan(0.0, 1.0))
    with pytest.raises(ValueError, match="family .* is empty"):
        limits.family({"tau0": 5.0})
    bare = ScanResult([{"name": "x", "hand": "R"}], np.array([0.2]), np.zeros(1), np.zeros((1, 1, 1)),
                      np.ones((1, 1, 1)), 0.0, 10, limits_setup.GEOMETRY)
    with pytest.raises(ValueError, match="no template family"):
        compute_limits(bare)
    with pytest.raises(ValueError, match="method"):
        compute_limits(fake_scan(0.0, 1.0), method="median")
