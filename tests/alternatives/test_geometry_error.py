"""The geometry-error model: splined Hankel transform against frank's exact visibilities, Jacobian."""

import numpy as np
import pytest

from spiralbayes.alternatives import HankelTable, geometry_visibilities, offset_geometry
from spiralbayes.axisymmetric import AxisymmetricModel
from spiralbayes.geometry import DiscGeometry
from tests.alternatives.test_fields import ring_profile

GEOMETRY = DiscGeometry(inc=35.0, PA=70.0, dRA=0.004, dDec=-0.002)


@pytest.fixture(scope="module")
def setup():
    model = AxisymmetricModel.from_profile(ring_profile, GEOMETRY, N=150, Rmax=1.2)
    rng = np.random.default_rng(5)
    q = 10 ** rng.uniform(4, np.log10(2.5e6), 1500)
    theta = rng.uniform(0, 2 * np.pi, q.size)
    u, v = q * np.cos(theta), q * np.sin(theta)
    return model, HankelTable(model, float(np.max(q)), 0.9), u, v


def test_splined_visibilities_match_the_model_at_offset_geometries(setup):
    model, table, u, v = setup
    for theta in ([0, 0, 0, 0], [1.5, -2.0, 8.0, -3.0]):
        g = offset_geometry(GEOMETRY, theta)
        exact = model.visibilities(u, v, g)
        got = geometry_visibilities(table, u, v, g)
        assert np.max(np.abs(got - exact)) < 1e-6 * np.max(np.abs(exact))


def test_offset_geometry_units():
    g = offset_geometry(GEOMETRY, [1.0, -2.0, 10.0, -5.0])
    assert (g.inc, g.PA) == pytest.approx((36.0, 68.0))
    assert (g.dRA, g.dDec) == pytest.approx((0.014, -0.007))


def test_jacobian_matches_finite_differences(setup):
    _, table, u, v = setup
    theta = np.array([0.7, -1.2, 3.0, 2.0])
    _, dV = geometry_visibilities(table, u, v, offset_geometry(GEOMETRY, theta), jacobian=True)
    steps = [1e-4, 1e-4, 1e-3, 1e-3]
    for k, h in enumerate(steps):
        up, down = theta.copy(), theta.copy()
        up[k] += h
        down[k] -= h
        numeric = (geometry_visibilities(table, u, v, offset_geometry(GEOMETRY, up))
                   - geometry_visibilities(table, u, v, offset_geometry(GEOMETRY, down))) / (2 * h)
        assert np.max(np.abs(dV[k] - numeric)) < 1e-4 * np.max(np.abs(numeric)), k
