"""The geometry least squares from blocked normal equations against scipy's on the full stacked problem."""

import numpy as np
import pytest
from scipy.optimize import least_squares

from spiralbayes.alternatives import HankelTable, geometry_visibilities, offset_geometry
from spiralbayes.axisymmetric import AxisymmetricModel
from spiralbayes.geometry import DiscGeometry
from spiralbayes.inference.detection.geometry_fit import (
    GEOMETRY_SCALES,
    fit_geometry_offsets,
    geometry_bounds,
    normal_equations,
)
from spiralbayes.visibilities import Visibilities
from tests.alternatives.test_fields import ring_profile

GEOMETRY = DiscGeometry(inc=40.0, PA=30.0)
SIGMA = 5e-4  # Jy
TRUTH = [0.8, -1.5, 12.0, -6.0]  # deg, deg, mas, mas


@pytest.fixture(scope="module")
def problem():
    model = AxisymmetricModel.from_profile(ring_profile, GEOMETRY, N=150, Rmax=1.2)
    rng = np.random.default_rng(21)
    q = 10 ** rng.uniform(4, np.log10(2e6), 2500)
    ang = rng.uniform(0, 2 * np.pi, q.size)
    u, v = q * np.cos(ang), q * np.sin(ang)
    spiral = 2e-3 * np.exp(-((u - 3e5) ** 2 + v ** 2) / 1e11) * np.exp(2j * np.pi * 1e-6 * u)
    peak = 1e-3 * np.exp(-(u ** 2 + v ** 2) / 4e12) * np.exp(-2j * np.pi * 1.5e-6 * v)
    V = (model.visibilities(u, v, offset_geometry(GEOMETRY, TRUTH)) + 0.7 * spiral + 1.3 * peak
         + SIGMA * (rng.normal(size=u.size) + 1j * rng.normal(size=u.size)))
    w = rng.uniform(0.5, 1.5, u.size) * SIGMA ** -2
    vis = Visibilities(u, v, V, w)
    table = HankelTable(model, float(np.max(q)), 1.2)
    return vis, table, spiral, peak


def _stacked(vis, table, theta, offset, basis):
    """The full problem as scipy would see it written out: 2N residuals, 2N x 4 Jacobian, QR projection."""
    sw = np.sqrt(vis.weights)
    V, dV = geometry_visibilities(table, vis.u, vis.v, offset_geometry(GEOMETRY, theta), jacobian=True)
    d = sw * (vis.V - V - (0 if offset is None else offset))
    f = np.concatenate([d.real, d.imag])
    J = np.concatenate([(-sw * dV).real, (-sw * dV).imag], axis=1).T
    if basis:
        B = np.stack([np.concatenate([(sw * b).real, (sw * b).imag]) for b in basis], axis=1)
        Q = np.linalg.qr(B)[0]
        f, J = f - Q @ (Q.T @ f), J - Q @ (Q.T @ J)
    return f, J


@pytest.mark.parametrize("with_basis", [False, True])
def test_blocked_normal_equations_equal_the_stacked_problem(problem, with_basis):
    vis, table, spiral, peak = problem
    basis = [spiral, peak] if with_basis else []
    offset = 0.5 * spiral if with_basis else None
    theta = [0.3, 0.7, -4.0, 9.0]
    f, J = _stacked(vis, table, theta, offset, basis)
    M, g, c = normal_equations(table, vis, vis.weights, GEOMETRY, theta, offset=offset, basis=basis, block=333)
    np.testing.assert_allclose(M, J.T @ J, rtol=1e-10, atol=1e-10 * np.abs(J.T @ J).max())
    np.testing.assert_allclose(g, J.T @ f, rtol=1e-9, atol=1e-9 * np.abs(J.T @ f).max())
    assert c == pytest.approx(f @ f, rel=1e-11)


@pytest.mark.parametrize("with_basis", [False, True])
def test_fit_matches_scipy_on_the_full_problem(problem, with_basis):
    vis, table, spiral, peak = problem
    basis = [spiral, peak] if with_basis else []
    lo, hi = geometry_bounds(GEOMETRY)
    ref = least_squares(lambda t: _stacked(vis, table, t, None, basis)[0], np.zeros(4),
                        jac=lambda t: _stacked(vis, table, t, None, basis)[1], bounds=(lo, hi),
                        x_scale=list(GEOMETRY_SCALES), method="trf", xtol=1e-10, ftol=1e-12, max_nfev=200)
    counter = {"n": 0}
    got = fit_geometry_offsets(table, vis, vis.weights, GEOMETRY, np.zeros(4), basis=basis, counter=counter, block=700)
    assert got.success and counter["n"] == got.nfev
    np.testing.assert_allclose(got.x, ref.x, rtol=1e-6, atol=1e-6)
    assert got.cost == pytest.approx(ref.cost, rel=1e-10)
    if with_basis:  # the spiral and the peak in the data are then fitted: the offsets are the truth's
        assert np.all(np.abs(np.subtract(got.x, TRUTH)) < [0.1, 0.3, 0.5, 0.5])
