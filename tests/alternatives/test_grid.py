"""The disc grid's transform: equal to direct sums, its own adjoint, and close to continuous transforms."""

import numpy as np
import pytest

from spiralbayes.alternatives import DiscGrid, FieldTransform, field_visibilities_dft, remove_ring_mean
from spiralbayes.exceptions import InputError
from spiralbayes.geometry import DiscGeometry
from spiralbayes.units import ARCSEC

GEOMETRY = DiscGeometry(inc=40.0, PA=25.0, dRA=0.012, dDec=-0.004)


def baselines(rng, n, q_max=2e6):
    q = 10 ** rng.uniform(4, np.log10(q_max), n)
    theta = rng.uniform(0, 2 * np.pi, n)
    return q * np.cos(theta), q * np.sin(theta)


def test_transform_equals_direct_sum_in_double_and_single_precision():
    rng = np.random.default_rng(1)
    u, v = baselines(rng, 300)
    grid = DiscGrid(0.5, 24, 64)
    field = rng.normal(size=grid.shape)
    reference = field_visibilities_dft(field, grid, u, v, GEOMETRY)
    scale = np.max(np.abs(reference))
    exact = FieldTransform(grid, u, v, GEOMETRY).visibilities(field)
    fast = FieldTransform(grid, u, v, GEOMETRY, single=True).visibilities(field)
    assert np.max(np.abs(exact - reference)) < 1e-6 * scale
    assert np.max(np.abs(fast - reference)) < 1e-4 * scale


def test_gradient_map_is_the_adjoint_of_the_transform():
    rng = np.random.default_rng(2)
    u, v = baselines(rng, 500)
    grid = DiscGrid(0.4, 16, 32)
    transform = FieldTransform(grid, u, v, GEOMETRY)
    field = rng.normal(size=grid.shape)
    y = rng.normal(size=u.size) + 1j * rng.normal(size=u.size)
    lhs = np.sum(np.conj(y) * transform.visibilities(field)).real
    rhs = np.sum(field * transform.gradient_map(y))
    assert rhs == pytest.approx(lhs, rel=1e-8)


def hankel_order_m(h, m, q, r_max, n=1500):
    """``2 pi i^m int_0^r_max h(r) J_m(2 pi q r) r dr`` by Gauss-Legendre quadrature (r in arcsec)."""
    from scipy.special import jv, roots_legendre

    x, w = roots_legendre(n)
    r = 0.5 * r_max * (x + 1)
    rr = r * ARCSEC
    weight = 0.5 * r_max * ARCSEC * w * h(r) * rr
    return 2 * np.pi * (1j ** m) * (jv(m, 2 * np.pi * np.outer(q, rr)) @ weight)


@pytest.mark.parametrize("m", [1, 2])
def test_smooth_m_mode_matches_its_hankel_transform(m):
    """``h(r) cos(m (phi - phi_0))`` has ``V = cos i e^{2 pi i u.d} 2 pi i^m cos(m (theta - phi_0)) H_m[h](q)``."""
    rng = np.random.default_rng(3)
    u, v = baselines(rng, 400, q_max=2e6)
    grid = DiscGrid.for_baselines(float(np.max(np.hypot(u, v))), 0.6)
    h = lambda r: 1e9 * np.exp(-0.5 * ((r - 0.3) / 0.06) ** 2)  # noqa: E731
    phi0 = 0.7
    field = h(grid.r)[:, None] * np.cos(m * (grid.phi[None, :] - phi0))
    got = FieldTransform(grid, u, v, GEOMETRY).visibilities(field)
    xi, eta = GEOMETRY.disc_frame_uv(u, v)
    q, theta = np.hypot(xi, eta), np.arctan2(eta, xi)
    expected = (GEOMETRY.cos_inc * GEOMETRY.phase_factor(u, v) * np.cos(m * (theta - phi0))
                * hankel_order_m(h, m, q, 0.6))
    rms = np.sqrt(np.mean(np.abs(got - expected) ** 2) / np.mean(np.abs(expected) ** 2))
    assert rms < 1e-6  # measured 3e-8: the midpoint rule is spectrally accurate for such fields


def test_grid_for_baselines_resolves_cells_and_azimuthal_bandwidth():
    grid = DiscGrid.for_baselines(4e6, 0.8, cell_factor=10)
    assert grid.dr * ARCSEC <= 1 / (10 * 4e6) * (1 + 1e-12)
    assert grid.n_phi >= 2 * np.pi * 4e6 * 0.8 * ARCSEC and grid.n_phi & (grid.n_phi - 1) == 0
    assert np.sum(grid.cell_area) * grid.n_phi == pytest.approx(np.pi * (0.8 * ARCSEC) ** 2)


def test_ring_mean_removal_and_bad_grids():
    field = np.arange(12.0).reshape(3, 4)
    out = remove_ring_mean(field)
    np.testing.assert_allclose(out.mean(axis=1), 0, atol=1e-12)
    np.testing.assert_allclose(out, field - field.mean(axis=1, keepdims=True))
    with pytest.raises(InputError, match="r_max"):
        DiscGrid(-1.0, 10, 64)
    with pytest.raises(InputError, match="n_r"):
        DiscGrid(1.0, 1, 64)
