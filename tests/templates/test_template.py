"""SpiralTemplate: conventions, mirror, evaluation, resampling, validation."""

import numpy as np
import pytest

from spiralbayes.templates import SpiralTemplate, make_template

SMALL = dict(n_x=120, n_phi=360, n_eta=1024)

def _wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


@pytest.fixture(scope="module")
def linear_r():
    """Low-mass, linear-profile, no-secondary template: its ridge is the linear wake."""
    return make_template(0.1, 0.1, 0.0, "R", nonlinear=False, secondary=False, gap=False, **SMALL)


def _analytic(n_x=50, n_phi=72):
    x = np.geomspace(0.2, 2.2, n_x)
    phi = 2 * np.pi * np.arange(n_phi) / n_phi
    delta = np.sin(phi)[None, :] * np.log(x)[:, None] + 0.1 * np.cos(2 * phi)[None, :]
    return SpiralTemplate(x=x, phi=phi, delta=delta, mass=1, tau0=1, beta=0, hand="R", name="ana_R")


def test_right_handed_convention_trailing_arms(linear_r):
    """Hand R: planet orbits anticlockwise, arms trail: outer arm at φ < 0, inner arm at φ > 0."""
    t = linear_r
    for xx, sign in [(1.2, -1), (1.4, -1), (0.8, +1), (0.9, +1)]:
        i = np.argmin(np.abs(t.x - xx))
        phi_peak = _wrap(t.phi[np.argmax(t.delta[i])])
        assert np.sign(phi_peak) == sign, (xx, np.degrees(phi_peak))
    # the ridge angle decreases with radius across the planet
    ridge = [_wrap(t.phi[np.argmax(t.delta[np.argmin(np.abs(t.x - xx))])]) for xx in (0.85, 0.95, 1.05, 1.15)]
    assert np.all(np.diff(ridge) < 0)


def test_left_hand_is_mirror(linear_r):
    left = make_template(0.1, 0.1, 0.0, "L", nonlinear=False, secondary=False, gap=False, **SMALL)
    assert left.hand == "L"
    np.testing.assert_array_equal(left.delta, linear_r.mirror().delta)
    i = np.argmin(np.abs(left.x - 1.3))
    assert _wrap(left.phi[np.argmax(left.delta[i])]) > 0  # outer arm now at φ > 0


def test_mirror_flips_hand_and_twice_is_identity():
    t = _analytic()
    m = t.mirror()
    assert m.hand == "L" and m.name == "ana_L"
    # δ_L(x, φ) = δ_R(x, −φ)
    phi = np.linspace(-3, 3, 11)
    x = np.full_like(phi, 0.77)
    np.testing.assert_allclose(m.evaluate(x, phi, 1.0), t.evaluate(x, -phi, 1.0), atol=1e-12)
    mm = m.mirror()
    assert mm.hand == "R"
    np.testing.assert_array_equal(mm.delta, t.delta)


def test_evaluate_reproduces_grid_and_is_periodic():
    t = _analytic()
    X, P = np.meshgrid(t.x[3:-3], t.phi, indexing="ij")
    np.testing.assert_allclose(t.evaluate(X * 0.5, P + 0.3, r_p=0.5, phi_p=0.3), t.delta[3:-3], atol=1e-12)
    np.testing.assert_allclose(t.evaluate(X, P + 2 * np.pi, 1.0), t.delta[3:-3], atol=1e-12)
    np.testing.assert_allclose(t.evaluate(X, P - 4 * np.pi, 1.0), t.delta[3:-3], atol=1e-12)


def test_evaluate_bilinear_in_log_r_and_phi():
    t = _analytic()
    # halfway in ln x and in φ between four grid nodes: mean of the four values
    i, j = 10, 71  # j = last azimuth: interpolation wraps to j = 0
    u = 0.5 * (np.log(t.x[i]) + np.log(t.x[i + 1]))
    ph = t.phi[j] + np.pi / t.phi.size
    want = 0.25 * (t.delta[i, j] + t.delta[i + 1, j] + t.delta[i, 0] + t.delta[i + 1, 0])
    assert t.evaluate(np.exp(u), ph, 1.0) == pytest.approx(want, abs=1e-12)


def test_evaluate_zero_outside_and_scale_free(linear_r):
    t = linear_r
    r_in = np.array([0.1, 0.19, 2.3, 5.0])
    assert np.all(t.evaluate(r_in, np.zeros(4), 1.0) == 0)
    rng = np.random.default_rng(1)
    x = rng.uniform(0.25, 2.1, 500)
    phi = rng.uniform(-np.pi, np.pi, 500)
    d1 = t.evaluate(x * 0.37, phi + 1.1, r_p=0.37, phi_p=1.1)  # arcsec
    d2 = t.evaluate(x * 80.0, phi - 2.0, r_p=80.0, phi_p=-2.0)  # au
    np.testing.assert_allclose(d1, d2, atol=1e-6)
    assert np.std(d1) > 0.005


def test_on_grid_resamples():
    t = _analytic(n_x=200, n_phi=720)
    x_new = np.geomspace(0.3, 2.0, 64)
    r = t.on_grid(x_new, 180)
    assert r.delta.shape == (64, 180)
    P = 2 * np.pi * np.arange(180) / 180
    exact = np.sin(P)[None, :] * np.log(x_new)[:, None] + 0.1 * np.cos(2 * P)[None, :]
    assert np.max(np.abs(r.delta - exact)) < 2e-3


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(hand="X"), "unknown hand"),
        (dict(delta=np.zeros((3, 4))), "shape"),
        (dict(x=np.linspace(2, 0.5, 50)), "increasing"),
        (dict(phi=np.linspace(0, 1, 72)), "uniform"),
        (dict(delta=np.full((50, 72), np.nan)), "NaN"),
    ],
)
def test_bad_templates_raise(kwargs, match):
    base = dict(x=np.geomspace(0.2, 2.2, 50), phi=2 * np.pi * np.arange(72) / 72, delta=np.zeros((50, 72)))
    base.update(kwargs)
    with pytest.raises(ValueError, match=match):
        SpiralTemplate(**base)


def test_evaluate_bad_rp():
    with pytest.raises(ValueError, match="r_p"):
        _analytic().evaluate(1.0, 0.0, r_p=-1.0)
