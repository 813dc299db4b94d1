"""Built-in wake generator: geometry, amplitude trends, cooling, radiative transfer."""

import numpy as np
import pytest

from spiralbayes.templates import make_template, paper_grid, wake_shape
from spiralbayes.templates.radiative import dlnB_dlnT, midplane_temperature, planck_nu
from spiralbayes.templates.wake import (
    WakeSettings,
    cooling_response,
    gap_profile,
    linear_profile,
    solve_burgers,
    surface_density_perturbation,
    wake_phase,
    wave_time,
)

SMALL = dict(n_x=120, n_phi=360, n_eta=1024)
RIDGE_X = (0.5, 0.8, 1.3, 1.5)


def _wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def _ridge(t, xx):
    i = np.argmin(np.abs(t.x - xx))
    return t.x[i], t.phi[np.argmax(t.delta[i])]


def test_ridge_follows_linear_wake_shape():
    """With the linear profile the δ maximum sits on Rafikov's φ_wake(r) at every radius."""
    t = make_template(0.3, 0.3, 0.0, nonlinear=False, secondary=False, **SMALL)
    dphi = 2 * np.pi / t.phi.size
    for xx in RIDGE_X:
        xi, phi_peak = _ridge(t, xx)
        err = _wrap(phi_peak - wake_shape(xi))
        assert abs(err) <= 1.5 * dphi, (xx, np.degrees(err))


def test_nonlinear_ridge_leads_by_nwave_shift():
    """With Burgers evolution the shock front runs ahead of the linear ridge (towards +φ outside,
    −φ inside) by at most the N-wave half-width (2h/3)√(2 C t) (Rafikov 2002)."""
    mass = 0.1
    st = WakeSettings(**SMALL)
    t = make_template(mass, 0.1, 0.0, secondary=False, **SMALL)
    eta = np.linspace(-30, 30, 20001)
    lam = linear_profile(eta, st.profile_amp, st.profile_width)
    C = 2.0 * 1.5 * mass * np.trapezoid(np.clip(lam, 0, None), eta) / 2**0.75
    for xx in RIDGE_X:
        xi, phi_peak = _ridge(t, xx)
        shift = _wrap(phi_peak - wake_shape(xi)) * np.sign(xi - 1)
        bound = 2 * st.h_p / 3 * np.sqrt(2 * C * wave_time(np.array([xi]))[0])
        assert 0 < shift <= bound + 2 * np.pi / t.phi.size, (xx, shift, bound)


def test_wave_time_reference_values():
    """template-physics.md §1b: t(x) for h = 0.07, q = 1/4, p = 1."""
    st = WakeSettings(x_max=3.2)
    x = np.array([0.7, 0.5, 0.3, 1.3, 1.5, 2.0, 3.0])
    want = np.array([48, 232, 829, 28, 88, 382, 1488])
    np.testing.assert_allclose(wave_time(x, 0.0, st), want, rtol=0.01)


def test_cooled_wake_opens_with_sound_speed():
    """β = 0 reproduces the closed form; slow cooling (γ_eff → γ) opens the spiral by ~1/√γ."""
    st = WakeSettings()
    x = np.array([0.4, 0.6, 1.6, 2.0])
    np.testing.assert_allclose(wake_phase(x, 0.0, st), wake_shape(x), rtol=1e-5)
    ratio = wake_phase(x, 10.0, st) / wake_shape(x)
    assert np.all(ratio < 1) and np.all(ratio > 1 / np.sqrt(1.4) - 0.01)


def test_cooling_response_limits():
    x = np.array([0.5, 0.9, 1.5])
    _, g0, f0 = cooling_response(x, 0.0, 0.07)
    np.testing.assert_array_equal(g0, 1.0)
    np.testing.assert_array_equal(f0, 0.0)
    wt, g10, f10 = cooling_response(x, 10.0, 0.07)
    assert np.all(f10 > 0.97) and np.all(np.abs(g10 - 1.4) < 0.01)


def test_burgers_conserves_and_decays_as_nwave():
    n, L = 2048, 200.0
    dx = L / n
    eta = -L / 2 + dx * np.arange(n)
    u0 = np.exp(-0.5 * eta**2)
    times = np.array([0.0, 50.0, 200.0, 800.0])
    u = solve_burgers(u0, dx, times)
    np.testing.assert_allclose(u.sum(axis=1) * dx, u0.sum() * dx, rtol=1e-10)  # conservative
    C = np.sqrt(2 * np.pi)  # positive area
    for k in (2, 3):
        assert u[k].max() == pytest.approx(np.sqrt(2 * C / times[k]), rel=0.08)


def test_amplitude_grows_with_mass_and_falls_with_tau_isothermal():
    rms = {}
    for m in (0.1, 0.3, 1.0, 3.0):
        for tau in (0.1, 1.0, 3.0):
            rms[m, tau] = make_template(m, tau, 0.0, store_brightness=False, **SMALL).rms()
    for tau in (0.1, 1.0, 3.0):
        vals = [rms[m, tau] for m in (0.1, 0.3, 1.0, 3.0)]
        assert np.all(np.diff(vals) > 0), (tau, vals)
    for m in (0.1, 0.3, 1.0, 3.0):
        vals = [rms[m, tau] for tau in (0.1, 1.0, 3.0)]
        assert np.all(np.diff(vals) < 0), (m, vals)


@pytest.mark.parametrize("mass", [0.3, 1.0, 3.0])
def test_slow_cooling_brightens_optically_thick_spirals(mass):
    """τ0 = 3: the β = 10 temperature perturbation makes the residual larger (paper App. B)."""
    iso = make_template(mass, 3.0, 0.0, store_brightness=False, **SMALL)
    adi = make_template(mass, 3.0, 10.0, store_brightness=False, **SMALL)
    assert adi.rms() > 1.5 * iso.rms()


def test_isothermal_thick_disc_suppressed_like_linear_theory():
    """δ ≈ [τ e^{-τ}/(1 − e^{-τ})] δΣ/Σ for β = 0 (template-physics §2): small δΣ limit."""
    st = WakeSettings(secondary=False, gap=False, **SMALL)
    mass = 0.01
    dsig = surface_density_perturbation(mass, 0.0, st)
    for tau0 in (0.1, 1.0, 3.0):
        t = make_template(mass, tau0, 0.0, secondary=False, gap=False, **SMALL)
        i = np.argmin(np.abs(t.x - 1.0 / 1.5))
        tau = tau0 / t.x[i]  # τ = τ0 x^{-p}
        factor = tau * np.exp(-tau) / -np.expm1(-tau)
        ratio = np.max(t.delta[i]) / np.max(dsig[i])
        assert ratio == pytest.approx(factor, rel=0.05), tau0


def test_gap_depth_kanagawa():
    st = WakeSettings()
    K = (3.0 * 0.07**3) ** 2 * 0.07**-5 / 1e-3
    assert gap_profile(np.array([1.0]), 3.0, st)[0] == pytest.approx(1 / (1 + 0.04 * K))
    assert gap_profile(np.array([2.0]), 3.0, st)[0] == pytest.approx(1.0, abs=1e-3)


def test_temperature_and_planck():
    assert midplane_temperature(1.0) == pytest.approx(19.7, abs=0.1)
    assert midplane_temperature(4.0) == pytest.approx(19.73 / 2, rel=1e-3)
    assert dlnB_dlnT(20.0, 0.87e-3) == pytest.approx(1.47, abs=0.01)
    # Rayleigh–Jeans limit at long wavelength
    lam = 1.0
    T = 30.0
    rj = 2 * 1.380649e-23 * T / lam**2 * 1.0
    assert planck_nu(T, lam) == pytest.approx(rj, rel=1e-3)


def test_paper_grid_has_64_templates():
    grid = paper_grid(n_x=24, n_phi=90, n_eta=256)
    assert len(grid) == 64
    assert len({t.name for t in grid}) == 64
    assert {t.hand for t in grid} == {"R", "L"}
    assert all(t.delta.dtype == np.float32 and t.delta.shape == (24, 90) for t in grid)


@pytest.mark.parametrize(
    "args, kwargs, match",
    [
        ((-1.0, 1.0, 0.0), {}, "mass"),
        ((1.0, 0.0, 0.0), {}, "tau0"),
        ((1.0, 1.0, -2.0), {}, "beta"),
        ((1.0, 1.0, 0.0, "Q"), {}, "hand"),
        ((1.0, 1.0, 0.0), {"h_p": 2.0}, "h_p"),
        ((1.0, 1.0, 0.0), {"bogus": 1}, "valid options"),
        ((1.0, 1.0, 0.0), {"backend": "nope"}, "backend"),
    ],
)
def test_make_template_bad_inputs(args, kwargs, match):
    with pytest.raises(ValueError, match=match):
        make_template(*args, **{**SMALL, **kwargs})


def test_wakeflow_backend_is_optional():
    try:
        import wakeflow  # noqa: F401
    except ImportError:
        with pytest.raises(ImportError, match="wakeflow"):
            make_template(1.0, 1.0, 0.0, backend="wakeflow", **SMALL)
    else:  # pragma: no cover
        pytest.skip("wakeflow installed")
