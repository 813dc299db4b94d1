"""frank's Gaussian-process pieces: the prior's precision against frank's own, and the q-grid
normal equations against dense sums over frank's DHT coefficients at every datum."""

import numpy as np
import pytest

from spiralbayes.axisymmetric import AxisymmetricModel
from spiralbayes.axisymmetric.gp import ProfilePrior, QGridProjector
from spiralbayes.exceptions import InputError
from spiralbayes.units import ARCSEC


def _model(N=60):
    return AxisymmetricModel.from_profile(lambda r: 1e10 * np.exp(-np.asarray(r) / 0.3), N=N)


def test_precision_is_franks():
    from frank.hankel import DiscreteHankelTransform
    from frank.statistical_models import GaussianModel

    model = _model()
    p = np.geomspace(1e-2, 1e-12, model.N)
    prior = ProfilePrior(model.Rmax, p)
    dht = DiscreteHankelTransform(model.Rmax * ARCSEC, model.N)
    frank = GaussianModel(dht, np.eye(model.N), np.ones(model.N), p)
    np.testing.assert_allclose(prior.precision, frank._Sinv, rtol=1e-10)
    # the model's own power spectrum when frank left one, the profile's power otherwise
    assert ProfilePrior.from_model(model).source == "profile power"
    from dataclasses import replace

    assert ProfilePrior.from_model(replace(model, power_spectrum=p)).source == "frank"
    with pytest.raises(InputError, match="positive"):
        ProfilePrior(1.2, np.r_[p[:-1], 0.0])


@pytest.mark.parametrize("order", [4, 6, 8, 10])
def test_q_grid_normal_equations_match_dense_sums(order):
    model = _model(N=80)
    prior = ProfilePrior.from_model(model)
    rng = np.random.default_rng(0)
    q = rng.uniform(0, 2e6, 4000)
    w = rng.uniform(0.5, 2.0, q.size)
    y = rng.normal(size=q.size)
    P = QGridProjector.build(prior, 2e6, tolerance=1e-9, order=order)
    H = prior.coefficients(q)
    first, weights = P.stencil(q)
    M = P.normal_matrix(P.spread(first, weights, w))
    j = P.project(P.spread(first, weights, w * y))
    M_dense, j_dense = H.T @ (w[:, None] * H), (w * y) @ H
    assert np.max(np.abs(M - M_dense)) < 1e-8 * np.max(np.abs(M_dense))
    assert np.max(np.abs(j - j_dense)) < 1e-8 * np.max(np.abs(H)) * np.sum(np.abs(w * y)) / np.sqrt(q.size)
    # the visibility curve of a profile, interpolated from the grid
    curve = P.interpolate(first, weights, P.H @ model.I)
    np.testing.assert_allclose(curve, H @ model.I, atol=1e-9 * np.max(np.abs(H @ model.I)))
    assert P.max_error(prior, q[:500]) < 1e-9
    with pytest.raises(InputError, match="exceed the q grid"):
        P.stencil(np.array([3e6]))


def test_the_cheapest_stencil_shortens_as_the_data_grow():
    """Per call the data cost n x order and the grid n_grid x N^2; more data (or shorter baselines)
    favour a shorter stencil on a finer grid, never a longer one."""
    prior = ProfilePrior.from_model(_model(N=200))
    for q_max in (1e6, 4e6):
        orders = [QGridProjector.cheapest_order(prior, q_max, n, 1e-7) for n in (1e3, 3e4, 1e5, 1e6, 1e7)]
        assert orders == sorted(orders, reverse=True) and orders[0] > orders[-1]
    P = QGridProjector.build(prior, 4e6, tolerance=1e-7, order=None, n_data=36000)
    assert P.order == QGridProjector.cheapest_order(prior, 4e6, 36000, 1e-7)
    with pytest.raises(InputError, match="n_data"):
        QGridProjector.build(prior, 4e6, order=None)
