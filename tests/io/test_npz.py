"""Tests of the Visibilities container, its readers/writers, binning and weight estimation."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

from spiralbayes.io import (
    load_visibilities,
    read_npz,
    write_npz,
)
from spiralbayes.units import C_LIGHT
from spiralbayes.visibilities import (
    Visibilities,
)


def _sha(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _random_vis(n=64, seed=0, **kw) -> Visibilities:
    rng = np.random.default_rng(seed)
    return Visibilities(
        u=rng.uniform(-2e6, 2e6, n), v=rng.uniform(-2e6, 2e6, n),
        V=rng.normal(size=n) + 1j * rng.normal(size=n), weights=rng.uniform(0.5, 50.0, n), **kw,
    )


def _assert_same(a: Visibilities, b: Visibilities):
    np.testing.assert_array_equal(a.u, b.u)
    np.testing.assert_array_equal(a.v, b.v)
    np.testing.assert_array_equal(a.V, b.V)
    np.testing.assert_array_equal(a.weights, b.weights)
    assert a.wavelength == b.wavelength
    assert a.conjugated == b.conjugated


# ----------------------------------------------------------------------------------
# npz
# ----------------------------------------------------------------------------------
def test_npz_round_trip(tmp_path):
    vis = _random_vis(wavelength=1.3e-3, conjugated=True, provenance={"k": [1, 2]})
    path = write_npz(vis, tmp_path / "v.npz")
    before = _sha(path)
    back = load_visibilities(path)
    assert _sha(path) == before
    _assert_same(vis, back)
    assert back.provenance["written_provenance"] == {"k": [1, 2]}
    assert list(tmp_path.iterdir()) == [path]


def test_npz_frank_keys_only(tmp_path):
    vis = _random_vis()
    np.savez(tmp_path / "f.npz", u=vis.u, v=vis.v, V=vis.V, weights=vis.weights)
    back = read_npz(tmp_path / "f.npz")
    _assert_same(vis, back)


def test_npz_dsharp_per_channel_converted_with_freq(tmp_path):
    rng = np.random.default_rng(7)
    nrow, freq = 30, np.array([2.30e11, 2.32e11, 2.34e11])
    um, vm = rng.uniform(-2000, 2000, (2, nrow))
    Vis = rng.normal(size=(3, nrow)) + 1j * rng.normal(size=(3, nrow))
    Wgt = rng.uniform(1, 2, (3, nrow))
    np.savez(tmp_path / "d.vis.npz", u=um, v=vm, Vis=Vis, Wgt=Wgt, freq=freq)
    vis = read_npz(tmp_path / "d.vis.npz")
    assert vis.n == 3 * nrow
    for c in range(3):  # channel c occupies rows c*nrow ... (c+1)*nrow
        sl = slice(c * nrow, (c + 1) * nrow)
        np.testing.assert_allclose(vis.u[sl], um * freq[c] / C_LIGHT, rtol=1e-14)
        np.testing.assert_allclose(vis.v[sl], vm * freq[c] / C_LIGHT, rtol=1e-14)
        np.testing.assert_array_equal(vis.V[sl], Vis[c])
        np.testing.assert_array_equal(vis.weights[sl], Wgt[c])
    assert vis.wavelength == pytest.approx(np.mean(C_LIGHT / freq))
    assert "per channel" in vis.provenance["conversions"][0]
    assert vis.provenance["format"] == "npz (dsharp layout)"


def test_npz_dsharp_without_freq_is_ambiguous(tmp_path):
    np.savez(tmp_path / "d.npz", u=[1e5, 2e5], v=[0.0, 1e5], Vis=[1 + 0j, 2], Wgt=[1.0, 1])
    with pytest.raises(ValueError, match=r"d\.npz: .*ambiguous.*uv_units='lambda'"):
        read_npz(tmp_path / "d.npz")
    vis = read_npz(tmp_path / "d.npz", uv_units="lambda")
    np.testing.assert_array_equal(vis.u, [1e5, 2e5])
    vis_m = read_npz(tmp_path / "d.npz", uv_units="m", wavelength=1e-3)
    np.testing.assert_allclose(vis_m.u, [1e8, 2e8])


def test_npz_unknown_keys(tmp_path):
    np.savez(tmp_path / "x.npz", uu=[1.0], vv=[1.0])
    with pytest.raises(ValueError, match=r"x\.npz: keys \['uu', 'vv'\] match no known layout"):
        read_npz(tmp_path / "x.npz")
    np.savez(tmp_path / "y.npz", u=[1.0], v=[1.0], V=[1 + 0j])
    with pytest.raises(ValueError, match=r"y\.npz: layout 'frank' needs keys.*missing \['weights'\]"):
        read_npz(tmp_path / "y.npz", layout="frank")


def test_npz_mismatched_lengths_names_file(tmp_path):
    np.savez(tmp_path / "m.npz", u=[1e5, 2e5], v=[0.0, 1e5], V=[1 + 0j], weights=[1.0, 1])
    with pytest.raises(ValueError, match=r"m\.npz: u, v, V and weights must have the same length"):
        read_npz(tmp_path / "m.npz")
