"""The asymmetry fields: closed-form Jacobians against finite differences, shapes and limits."""

import numpy as np
import pytest

from spiralbayes.alternatives import FIELD_MODELS, DiscGrid, ProfileContext

GRID = DiscGrid(0.8, 80, 128)


def ring_profile(r):
    """A smooth core plus ring [Jy/sr] (arcsec)."""
    r = np.asarray(r, dtype=float)
    return 1e10 * (np.exp(-0.5 * (r / 0.15) ** 2) + 0.6 * np.exp(-0.5 * ((r - 0.45) / 0.06) ** 2))


CTX = ProfileContext.build(ring_profile, GRID)
THETAS = {
    "arc": [0.4, 0.42, 2.5, 0.05, 0.5],
    "lopsided": [0.1, -0.05, 0.4, 0.12],
    "eccentric_ring": [0.08, -0.05, 0.44, 0.07],
    "eccentric_excess": [0.06, 0.04, 0.44, 0.05, 0.3],
    "m2": [0.06, 0.03, 0.35, 0.1, 1.3],
}


@pytest.mark.parametrize("name", sorted(FIELD_MODELS))
def test_jacobian_matches_finite_differences(name):
    model = FIELD_MODELS[name]
    theta = np.array(THETAS[name])
    P, J = model.field_and_jacobian(theta, CTX)
    scale = np.max(np.abs(P))
    for k in range(model.n_params):
        h = 1e-6 * max(abs(theta[k]), 0.01)
        up, down = theta.copy(), theta.copy()
        up[k] += h
        down[k] -= h
        numeric = (model.field(up, CTX) - model.field(down, CTX)) / (2 * h)
        err = np.max(np.abs(J[k] - numeric)) / max(np.max(np.abs(numeric)), 1e-3 * scale / abs(theta[k] or 1))
        assert err < 1e-4, (name, model.param_names[k], err)


@pytest.mark.parametrize("name", sorted(FIELD_MODELS))
def test_fields_have_zero_ring_mean_and_vanish_at_zero_amplitude(name):
    model = FIELD_MODELS[name]
    theta = np.array(THETAS[name])
    P = model.field(theta, CTX)
    np.testing.assert_allclose(P.mean(axis=1), 0, atol=1e-9 * np.max(np.abs(P)))
    theta[list(model.amplitude_indices)] = 0.0
    assert np.max(np.abs(model.field(theta, CTX))) == 0.0


def test_arc_peaks_at_its_centre_and_wraps_its_azimuth():
    model = FIELD_MODELS["arc"]
    theta = np.array([0.5, 0.42, 2.5 + 2 * np.pi, 0.05, 0.5])
    contrast = model.field(theta, CTX) / CTX.I_ring[:, None]  # A W (von Mises - its mean)
    i, j = np.unravel_index(np.argmax(contrast), contrast.shape)
    assert abs(GRID.r[i] - 0.42) <= GRID.dr
    assert abs(np.angle(np.exp(1j * (GRID.phi[j] - 2.5)))) <= 2 * np.pi / GRID.n_phi
    described = model.describe(theta)
    assert described["phi_c_deg"] == pytest.approx(np.degrees(2.5))
    assert described["sigma_phi_deg"] == pytest.approx(np.degrees(0.5))


def test_eccentric_ring_is_a_radial_shift_to_first_order():
    """``I_A(a) - I_A(r)`` with ``a = r (1 + e W cos(phi - omega))`` is ``e W r I_A' cos(phi - omega)`` + O(e^2)."""
    model = FIELD_MODELS["eccentric_ring"]
    e, omega = 1e-3, 0.8
    theta = np.array([e * np.cos(omega), e * np.sin(omega), 0.44, 0.07])
    P = model.field(theta, CTX)
    r = GRID.r
    slope = np.gradient(ring_profile(r), r)
    W = np.exp(-0.5 * ((r - 0.44) / 0.07) ** 2)
    first = (e * W * r * slope)[:, None] * np.cos(GRID.phi[None, :] - omega)
    assert np.max(np.abs(P - first)) < 0.02 * np.max(np.abs(first))
    assert model.describe(theta)["e"] == pytest.approx(e)
    assert model.describe(theta)["omega_deg"] == pytest.approx(np.degrees(omega))


def test_bar_is_point_symmetric_and_lopsided_is_antisymmetric():
    half = GRID.n_phi // 2
    bar = FIELD_MODELS["m2"].field(np.array([0.1, 0.0, 0.35, 0.1, 0.0]), CTX)
    np.testing.assert_allclose(bar, np.roll(bar, half, axis=1), atol=1e-12 * np.max(np.abs(bar)))
    lop = FIELD_MODELS["lopsided"].field(np.array(THETAS["lopsided"]), CTX)
    np.testing.assert_allclose(lop, -np.roll(lop, half, axis=1), atol=1e-12 * np.max(np.abs(lop)))


def test_profile_interpolation_is_smooth_and_exact_at_nodes():
    r = CTX.r_table[10:20]
    value, slope = CTX.interpolate(r)
    np.testing.assert_allclose(value, CTX.I_table[10:20], rtol=1e-12)
    r_mid = np.linspace(0.05, 0.7, 50)
    value, slope = CTX.interpolate(r_mid)
    np.testing.assert_allclose(value, ring_profile(r_mid), rtol=1e-6, atol=1e-6 * 1e10)
    exact_slope = -1e10 * (r_mid / 0.15 ** 2 * np.exp(-0.5 * (r_mid / 0.15) ** 2)
                           + 0.6 * (r_mid - 0.45) / 0.06 ** 2 * np.exp(-0.5 * ((r_mid - 0.45) / 0.06) ** 2))
    assert np.max(np.abs(slope - exact_slope)) < 1e-4 * np.max(np.abs(exact_slope))
