"""Tests of the Visibilities container, its readers/writers, binning and weight estimation."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest

from spiralbayes.exceptions import InputError
from spiralbayes.geometry import ARCSEC, DiscGeometry
from spiralbayes.io import (
    read_uvtable,
)
from spiralbayes.units import C_LIGHT
from spiralbayes.visibilities import (
    BinnedVisibilities,
    Visibilities,
    bin_deprojected,
    estimate_weight_factor,
    estimate_weights,
    neighbour_weight_factor,
)

DATA = Path(__file__).parent / "data"
AS209 = DATA / "AS209_DSHARP_subsample_uvtable.txt"

def _random_vis(n=64, seed=0, **kw) -> Visibilities:
    rng = np.random.default_rng(seed)
    return Visibilities(
        u=rng.uniform(-2e6, 2e6, n), v=rng.uniform(-2e6, 2e6, n),
        V=rng.normal(size=n) + 1j * rng.normal(size=n), weights=rng.uniform(0.5, 50.0, n), **kw,
    )


# ----------------------------------------------------------------------------------
# container validation (bad input)
# ----------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["u", "v", "V", "weights"])
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_nan_and_inf_rejected(name, bad):
    kw = dict(u=[1e5, 2e5, 3e5], v=[0.0, 1e5, 2e5], V=[1 + 0j, 1, 1], weights=[1.0, 1, 1])
    kw[name] = np.array(kw[name], dtype=complex if name == "V" else float)
    kw[name][1] = bad
    with pytest.raises(ValueError, match=rf"{name} has 1 NaN/inf values \(first at index 1\).*remove or flag"):
        Visibilities(**kw)


def test_negative_weights_rejected():
    with pytest.raises(ValueError, match=r"weights has 1 negative values.*must be >= 0"):
        Visibilities(u=[1e5, 2e5], v=[0, 0], V=[1, 1], weights=[1.0, -1.0])


def test_mismatched_lengths_rejected():
    with pytest.raises(ValueError, match=r"same length.*'V': 2"):
        Visibilities(u=[1e5, 2e5, 3e5], v=[0, 0, 0], V=[1, 1], weights=[1, 1, 1])


def test_empty_rejected():
    with pytest.raises(ValueError, match="no visibilities"):
        Visibilities(u=[], v=[], V=[], weights=[])


def test_complex_u_rejected():
    with pytest.raises(ValueError, match="u must be real"):
        Visibilities(u=[1e5 + 1j], v=[0], V=[1], weights=[1])


def test_zero_weights_dropped_with_logged_count(caplog):
    with caplog.at_level(logging.INFO, logger="spiralbayes.visibilities"):
        vis = Visibilities(u=[1e5, 2e5, 3e5, 4e5], v=[0, 0, 0, 0], V=[1, 2, 3, 4], weights=[1.0, 0, 2, 0])
    assert vis.n == 2
    np.testing.assert_array_equal(vis.V, [1, 3])
    assert vis.provenance["dropped_zero_weight"] == 2
    assert "dropped 2 visibilities with zero weight" in caplog.text


def test_all_zero_weights_rejected():
    with pytest.raises(ValueError, match="every visibility has zero weight"):
        Visibilities(u=[1e5], v=[0], V=[1], weights=[0.0])


def test_bad_wavelength_rejected():
    with pytest.raises(ValueError, match="wavelength must be a positive number of metres"):
        _random_vis(wavelength=-1.0)


def test_container_helpers():
    vis = _random_vis(wavelength=1.25e-3, conjugated=True)
    assert vis.frequency == pytest.approx(C_LIGHT / 1.25e-3)
    std = vis.standardised()
    np.testing.assert_array_equal(std.V, np.conj(vis.V))
    assert not std.conjugated and std.provenance["conjugated_on_load"]
    assert "n=64" in repr(vis)
    assert vis.subset(slice(0, 10)).n == 10
    np.testing.assert_allclose(vis.sigma, 1 / np.sqrt(vis.weights))


def _with_antennas(n=64, **kw) -> Visibilities:
    rng = np.random.default_rng(7)
    return _random_vis(n, antenna1=rng.integers(0, 6, n), antenna2=rng.integers(6, 12, n),
                       time=np.repeat(np.arange(n // 8) * 60.0, 8), **kw)


def test_antennas_and_times_follow_every_row_operation():
    vis = _with_antennas(conjugated=True)
    rows = np.array([5, 2, 40, 33])
    sub = vis.subset(rows)
    for name in ("antenna1", "antenna2", "time"):
        np.testing.assert_array_equal(getattr(sub, name), getattr(vis, name)[rows])
    for copy in (vis.standardised(), vis.with_V(vis.V * 2), vis.with_weights(vis.weights * 3, "x3")):
        np.testing.assert_array_equal(copy.antenna1, vis.antenna1)
        np.testing.assert_array_equal(copy.time, vis.time)
    # flagged (zero-weight) rows are dropped with their antennas and times
    weights = vis.weights.copy()
    weights[[0, 9]] = 0.0
    kept = Visibilities(vis.u, vis.v, vis.V, weights, antenna1=vis.antenna1, antenna2=vis.antenna2, time=vis.time)
    np.testing.assert_array_equal(kept.antenna2, np.delete(vis.antenna2, [0, 9]))
    np.testing.assert_array_equal(kept.time, np.delete(vis.time, [0, 9]))
    assert vis.has_antennas and not _random_vis().has_antennas


def test_data_hash_ignores_antennas():
    from spiralbayes._provenance import data_hash

    plain, with_rows = _random_vis(), _with_antennas()
    assert data_hash(plain.u, plain.v, plain.V, plain.weights) == data_hash(with_rows.u, with_rows.v, with_rows.V,
                                                                         with_rows.weights)


@pytest.mark.parametrize("kw, word", [
    ({"antenna1": np.zeros(64, int)}, "antenna1 and antenna2 together"),
    ({"time": np.zeros(64)}, "time needs antenna1"),
    ({"antenna1": np.zeros(63, int), "antenna2": np.ones(63, int)}, "antenna1 has 63 entries"),
    ({"antenna1": -np.ones(64, int), "antenna2": np.ones(64, int)}, ">= 0"),
    ({"antenna1": np.zeros(64, int), "antenna2": np.ones(64, int), "time": np.full(64, np.nan)}, "time has NaN"),
])
def test_bad_antennas_rejected(kw, word):
    with pytest.raises(InputError, match=word):
        _random_vis(**kw)


def test_as209_binned_profile_falls_with_baseline():
    vis = read_uvtable(AS209)
    geom = DiscGeometry(inc=34.97, PA=85.76, dRA=-1.9e-3, dDec=2.5e-3)
    binned = bin_deprojected(vis, geom, bins=[0, 2e5, 1e6, 7e6])
    assert binned.counts.sum() == 196
    assert binned.re[0] > binned.re[1] > abs(binned.re[2])  # a resolved disc


# ----------------------------------------------------------------------------------
# deprojected binning
# ----------------------------------------------------------------------------------
def _gaussian_disc(n, geom: DiscGeometry, sigma_arcsec=0.1, flux=1.0, noise=0.0, seed=0):
    """Visibilities of a circular Gaussian disc seen with ``geom`` (closed form)."""
    rng = np.random.default_rng(seed)
    u, v = rng.uniform(-1.5e6, 1.5e6, (2, n))
    up, vp = geom.deproject_uv(u, v)
    s = sigma_arcsec * ARCSEC
    V = flux * np.exp(-2 * np.pi**2 * s**2 * (up**2 + vp**2)) * geom.phase_factor(u, v)
    V = V + noise * (rng.normal(size=n) + 1j * rng.normal(size=n))
    return u, v, V


def test_bin_deprojected_matches_direct_weighted_means_and_model():
    geom = DiscGeometry(inc=40.0, PA=30.0, dRA=0.05, dDec=-0.03)
    u, v, V = _gaussian_disc(4000, geom)
    w = np.random.default_rng(1).uniform(1, 3, u.size)
    vis = Visibilities(u=u, v=v, V=V, weights=w)
    binned = bin_deprojected(vis, geom, bin_width=2e4)
    assert isinstance(binned, BinnedVisibilities)
    assert binned.counts.sum() == vis.n
    # independent reference: explicit loop over bins
    up, vp = geom.deproject_uv(u, v)
    q = np.hypot(up, vp)
    Vc = V * np.exp(-2j * np.pi * (u * geom.dRA + v * geom.dDec) * ARCSEC)
    for k in range(0, len(binned), 7):
        sel = (q >= binned.q_low[k]) & (q < binned.q_high[k])
        assert sel.sum() == binned.counts[k]
        np.testing.assert_allclose(binned.re[k], np.sum(w[sel] * Vc[sel].real) / w[sel].sum(), rtol=1e-12)
        np.testing.assert_allclose(binned.re_err[k], 1 / np.sqrt(w[sel].sum()), rtol=1e-12)
    # physics: the re-centred, deprojected Gaussian is real and a function of q only, so each
    # bin holds the weighted mean of the closed form at its points' q
    model = np.exp(-2 * np.pi**2 * (0.1 * ARCSEC) ** 2 * q**2)
    idx = np.digitize(q, np.r_[binned.q_low, binned.q_high[-1]]) - 1
    expected = np.bincount(idx, weights=w * model) / np.bincount(idx, weights=w)
    np.testing.assert_allclose(binned.re, expected, rtol=1e-10)
    np.testing.assert_allclose(binned.im, 0, atol=1e-12)
    np.testing.assert_allclose(binned.re, np.exp(-2 * np.pi**2 * (0.1 * ARCSEC) ** 2 * binned.q**2), atol=1e-2)


def test_bin_deprojected_bins_argument():
    vis = _random_vis(200)
    b1 = bin_deprojected(vis, DiscGeometry(), bins=10)
    assert b1.counts.sum() == 200 and len(b1) <= 10
    b2 = bin_deprojected(vis, None, bins=[0, 1e6, 2e6])
    assert b2.counts.sum() == np.sum(vis.uv_distance < 2e6)
    np.testing.assert_array_equal(b2.V, b2.re + 1j * b2.im)
    with pytest.raises(ValueError, match="either bin_width or bins"):
        bin_deprojected(vis, None, bins=10, bin_width=1e4)
    with pytest.raises(ValueError, match="increasing"):
        bin_deprojected(vis, None, bins=[0, 2e6, 1e6])
    with pytest.raises(ValueError, match="bin_width must be a positive"):
        bin_deprojected(vis, None, bin_width=-1.0)


# ----------------------------------------------------------------------------------
# weight estimation
# ----------------------------------------------------------------------------------
@pytest.mark.parametrize("use_geometry", [False, True])
def test_estimate_weights_recovers_factor_two(use_geometry, caplog):
    geom = DiscGeometry(inc=35.0, PA=60.0, dRA=0.02, dDec=0.01)
    sigma = 0.05
    u, v, V = _gaussian_disc(20000, geom, noise=sigma, seed=11)
    wrong = np.full(u.size, 0.5 / sigma**2)  # weights too small by a factor 2
    vis = Visibilities(u=u, v=v, V=V, weights=wrong)
    with caplog.at_level(logging.INFO, logger="spiralbayes.visibilities"):
        fixed = estimate_weights(vis, geom if use_geometry else None)
    record = fixed.provenance["weight_rescaling"]
    assert record["factor"] == pytest.approx(2.0, rel=0.1)
    assert record["factor_error"] < 0.05
    np.testing.assert_allclose(fixed.weights, wrong * record["factor"])
    np.testing.assert_array_equal(vis.weights, wrong), "input untouched"
    assert "weights rescaled by" in caplog.text
    assert record["binning"] == ("deprojected annuli" if use_geometry else "uv cells")


def test_estimate_weights_correct_weights_give_factor_one():
    sigma = 0.1
    u, v, V = _gaussian_disc(10000, DiscGeometry(), noise=sigma, seed=3)
    res = estimate_weight_factor(Visibilities(u=u, v=v, V=V, weights=np.full(u.size, sigma**-2)))
    assert res.factor == pytest.approx(1.0, abs=3 * res.factor_error)


def test_estimate_weights_bad_options():
    vis = _random_vis(10)
    with pytest.raises(ValueError, match="method='mad' is not known"):
        estimate_weights(vis, method="mad")
    with pytest.raises(ValueError, match="degrees of freedom.*increase bin_width"):
        estimate_weights(vis, bin_width=1.0)
    with pytest.raises(ValueError, match="bin_width must be a positive"):
        estimate_weight_factor(vis, bin_width=0.0)


@pytest.mark.parametrize("flux,true_factor", [(0.0, 1.0), (0.0, 40.0), (1.0, 40.0), (1.0, 0.5)])
def test_neighbour_estimate_recovers_the_true_noise(flux, true_factor):
    """Weights off by a known factor, noise of known sigma: the factor comes back within its
    stated error (pure noise) or 5 % (a bright inclined, offset disc, S/N 30 at the peak)."""
    sigma = 0.03
    geom = DiscGeometry(inc=50.0, PA=20.0, dRA=0.02)
    u, v, V = _gaussian_disc(8000, geom, sigma_arcsec=0.2, flux=flux, noise=sigma, seed=4)
    vis = Visibilities(u=u, v=v, V=V, weights=np.full(u.size, sigma**-2 / true_factor))
    res = neighbour_weight_factor(vis)
    assert res.factor_error == pytest.approx(res.factor * 1.443 / np.sqrt(res.dof), rel=1e-3)
    tolerance = 4 * res.factor_error if flux == 0 else 0.05 * true_factor
    assert res.factor == pytest.approx(true_factor, abs=tolerance)
    fixed = estimate_weights(vis, method="neighbours")
    assert fixed.provenance["weight_rescaling"]["binning"] == "uv neighbour planes"
    np.testing.assert_allclose(fixed.weights, vis.weights * res.factor)
