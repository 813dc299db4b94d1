"""Planet mass units (Stevenson et al. 2024; template-physics §0.5)."""

import numpy as np
import pytest

from spiralbayes.units import (
    aspect_ratio,
    mass_to_mth,
    mth_to_mass,
    mth_to_mjup,
    mth_to_mnep,
    thermal_mass,
)


def test_thermal_mass_at_50au():
    assert thermal_mass(50, 0.8, unit="Mjup") == pytest.approx(0.287, abs=0.001)
    assert thermal_mass(50, 0.8) == pytest.approx(0.8 * 0.07**3)


def test_paper_conversions():
    """0.1 M_th ≈ 0.5 M_Nep and 3 M_th ≈ 0.9 M_Jup at 50 au, h = 0.07, M_* = 0.8 M_sun."""
    assert mth_to_mnep(0.1, 50, 0.8) == pytest.approx(0.5, abs=0.05)
    assert mth_to_mjup(3.0, 50, 0.8) == pytest.approx(0.9, abs=0.05)


def test_thermal_mass_scales_as_r_to_three_quarters():
    r = np.array([20.0, 50.0, 100.0])
    m = thermal_mass(r, 0.8, unit="Mjup")
    np.testing.assert_allclose(m, [0.145, 0.287, 0.483], atol=0.001)
    np.testing.assert_allclose(m / m[1], (r / 50) ** 0.75)


def test_distance_and_reference_radius():
    # 0.35" at 140 pc = 49 au
    a = thermal_mass(0.35, 0.8, distance=140.0, unit="Mjup")
    b = thermal_mass(49.0, 0.8, unit="Mjup")
    assert a == pytest.approx(b)
    # the same disc described at another reference radius
    h100 = aspect_ratio(100.0)
    assert thermal_mass(50, 0.8, h_ref=h100, r_ref=100.0) == pytest.approx(thermal_mass(50, 0.8))


def test_roundtrip_and_units():
    m = mth_to_mass(1.7, 30.0, 1.2, unit="Mearth")
    assert mass_to_mth(m, 30.0, 1.2, unit="Mearth") == pytest.approx(1.7)
    assert mth_to_mass(1.0, 50, 0.8, unit="Mnep") == pytest.approx(mth_to_mnep(1.0, 50, 0.8))


@pytest.mark.parametrize(
    "call",
    [
        lambda: thermal_mass(-1.0, 0.8),
        lambda: thermal_mass(50.0, 0.0),
        lambda: thermal_mass(50.0, 0.8, unit="Mmoon"),
        lambda: mth_to_mjup(-0.1, 50.0, 0.8),
        lambda: thermal_mass(1.0, 0.8, distance=-5.0),
    ],
)
def test_bad_inputs(call):
    with pytest.raises(ValueError):
        call()


def test_wrap_angle_lands_in_range_by_whole_periods():
    from spiralbayes.units import wrap_angle

    rng = np.random.default_rng(3)
    a = rng.uniform(-50.0, 50.0, 1000)
    d = wrap_angle(a)
    # independent reference: the principal argument of exp(i a), (-pi, pi]
    assert np.allclose(np.exp(1j * d), np.exp(1j * a), atol=1e-12)
    assert d.min() >= -np.pi and d.max() < np.pi
    turns = (a - d) / (2 * np.pi)
    assert np.allclose(turns, np.round(turns), atol=1e-12)
    z = wrap_angle(a, 0.0)
    assert z.min() >= 0.0 and z.max() < 2 * np.pi and np.allclose(np.exp(1j * z), np.exp(1j * a), atol=1e-12)
    mu = 5.9
    c = wrap_angle(a, mu - np.pi)
    assert np.all(np.abs(c - mu) <= np.pi) and np.allclose(np.cos(c), np.cos(a), atol=1e-12)
    assert wrap_angle(370.0, 0.0, 360.0) == 10.0 and wrap_angle(-190.0, period=360.0) == 170.0
    assert wrap_angle(np.pi) == -np.pi  # the range is half-open


def test_constants_are_the_published_values():
    """The SI-exact constants and the IAU 2015 / CODATA 2018 masses, typed from the standards."""
    from spiralbayes import units

    assert units.C_LIGHT == 299_792_458.0
    assert units.H_PLANCK == 6.62607015e-34
    assert units.K_BOLTZMANN == 1.380649e-23
    assert units.G_NEWTON == 6.67430e-11
    assert units.AU == 1.495978707e11
    assert units.JY == 1e-26
    assert pytest.approx(np.pi / 648000, rel=1e-15) == units.ARCSEC
    # IAU 2015 B3 nominal GM values [m^3 s^-2] divided by CODATA 2018 G
    assert pytest.approx(1.3271244e20 / 6.67430e-11, rel=1e-15) == units.M_SUN
    assert pytest.approx(1.2668653e17 / 6.67430e-11, rel=1e-15) == units.M_JUP
    assert pytest.approx(3.986004e14 / 6.67430e-11, rel=1e-15) == units.M_EARTH


def test_astropy_mass_units_are_accepted():
    import astropy.units as u

    for name, unit in [("Mjup", u.M_jup), ("Msun", u.M_sun), ("Mearth", u.M_earth), ("kg", u.kg)]:
        assert thermal_mass(40.0, 1.1, unit=unit) == pytest.approx(thermal_mass(40.0, 1.1, unit=name), rel=1e-14)
    with pytest.raises(ValueError, match="not a mass unit"):
        thermal_mass(40.0, 1.1, unit=u.m)
