"""DiscGeometry against frank.geometry, and the disc-azimuth convention."""

import numpy as np
import pytest

frank_geometry = pytest.importorskip("frank.geometry")

from spiralbayes.geometry import DiscGeometry  # noqa: E402


@pytest.fixture
def uvV():
    rng = np.random.default_rng(0)
    u, v = rng.uniform(-1e6, 1e6, (2, 200))
    V = rng.normal(size=200) + 1j * rng.normal(size=200)
    return u, v, V


@pytest.mark.parametrize("inc,PA,dRA,dDec",
                         [(34.97, 85.76, -1.9e-3, 2.5e-3), (60.0, -30.0, 0.1, -0.2), (0.0, 0.0, 0.0, 0.0)])
def test_matches_frank(uvV, inc, PA, dRA, dDec):
    u, v, V = uvV
    ours = DiscGeometry(inc, PA, dRA, dDec)
    theirs = frank_geometry.FixedGeometry(inc, PA, dRA, dDec)
    up, vp, Vp = ours.apply_correction(u, v, V)
    fu, fv, fV = theirs.apply_correction(u, v, V)
    np.testing.assert_allclose(up, fu, rtol=1e-12, atol=1e-6)
    np.testing.assert_allclose(vp, fv, rtol=1e-12, atol=1e-6)
    np.testing.assert_allclose(Vp, fV, rtol=1e-12, atol=1e-12)
    ru, rv = ours.reproject_uv(up, vp)
    np.testing.assert_allclose(ru, u, atol=1e-6)
    np.testing.assert_allclose(rv, v, atol=1e-6)
    np.testing.assert_allclose(ours.phase_shift(u, v, V), frank_geometry.apply_phase_shift(u, v, V, dRA, dDec))


def test_disc_sky_round_trip():
    geom = DiscGeometry(50.0, 140.0, 0.05, -0.03)
    rng = np.random.default_rng(1)
    r, phi = rng.uniform(0.01, 1, 100), rng.uniform(-np.pi, np.pi, 100)
    l, m = geom.disc_to_sky(r, phi)
    r2, phi2 = geom.sky_to_disc(l, m)
    np.testing.assert_allclose(r2, r, rtol=1e-12)
    np.testing.assert_allclose(np.angle(np.exp(1j * (phi2 - phi))), 0, atol=1e-12)


def test_phi_zero_is_right_hand_minor_axis_and_increases_anticlockwise():
    """PA = 0: major axis north-south, so the minor axis is east-west and its right-hand arm
    on a north-up, east-left display is west (l < 0); phi = 90 deg is north (anticlockwise)."""
    geom = DiscGeometry(30.0, 0.0)
    l, m = geom.disc_to_sky(1.0, 0.0)
    assert l == pytest.approx(-np.cos(np.radians(30.0))) and m == pytest.approx(0.0, abs=1e-12)
    l, m = geom.disc_to_sky(1.0, np.pi / 2)
    assert l == pytest.approx(0.0, abs=1e-12) and m == pytest.approx(1.0)


def test_phi_follows_the_rotated_display():
    """PA = 90: major axis east-west; rotating the display to put it vertical, phi = 0 is north or south
    and phi = 90 deg lies along the major axis towards PA (east)."""
    geom = DiscGeometry(0.0, 90.0)
    l, m = geom.disc_to_sky(1.0, np.pi / 2)
    assert l == pytest.approx(1.0) and m == pytest.approx(0.0, abs=1e-12)


def test_disc_frame_uv_consistent_with_positions():
    """exp(2 pi i (u l + v m)) equals exp(2 pi i (q_disc . s_disc)) times the offset phase."""
    geom = DiscGeometry(40.0, 70.0, 0.02, 0.01)
    rng = np.random.default_rng(2)
    u, v = rng.uniform(-1e6, 1e6, (2, 50))
    r, phi = 0.3, 1.1
    l, m = geom.disc_to_sky(r, phi)
    xi, eta = geom.disc_frame_uv(u, v)
    arc = np.pi / 180 / 3600
    lhs = np.exp(2j * np.pi * (u * l + v * m) * arc)
    rhs = np.exp(2j * np.pi * (xi * r * np.cos(phi) + eta * r * np.sin(phi)) * arc) * geom.phase_factor(u, v)
    np.testing.assert_allclose(lhs, rhs, atol=1e-9)


@pytest.mark.parametrize("bad", [dict(inc=90.0), dict(inc=-1.0), dict(PA=np.nan)])
def test_bad_geometry_raises(bad):
    with pytest.raises(ValueError, match="DiscGeometry"):
        DiscGeometry(**bad)
