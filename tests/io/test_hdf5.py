"""Tests of the Visibilities container, its readers/writers, binning and weight estimation."""

from __future__ import annotations

import hashlib
from pathlib import Path

import h5py
import numpy as np
import pytest

from spiralbayes._provenance import FORMAT_VERSION
from spiralbayes.io import (
    load_visibilities,
    read_hdf5,
    save_visibilities,
    write_hdf5,
)
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
# HDF5
# ----------------------------------------------------------------------------------
def test_hdf5_round_trip(tmp_path):
    vis = _random_vis(wavelength=1.3e-3, conjugated=True, provenance={"nested": {"a": 1}})
    path = save_visibilities(vis, tmp_path / "v.h5")
    before = _sha(path)
    back = load_visibilities(path)
    assert _sha(path) == before
    _assert_same(vis, back)
    assert back.provenance["nested"] == {"a": 1}
    assert back.provenance["loaded_from"]["sha256"] == before
    with h5py.File(path) as fh:
        assert fh.attrs["format_version"] == FORMAT_VERSION
        assert fh.attrs["spiralbayes_type"] == "spiralbayes.Visibilities"
    assert list(tmp_path.iterdir()) == [path]


def test_hdf5_unknown_wavelength_round_trips(tmp_path):
    vis = _random_vis()
    back = read_hdf5(write_hdf5(vis, tmp_path / "v.hdf5"))
    assert back.wavelength is None


def test_hdf5_missing_dataset(tmp_path):
    path = tmp_path / "bad.h5"
    with h5py.File(path, "w") as fh:
        fh["u"] = [1.0]
        fh["v"] = [1.0]
    with pytest.raises(ValueError, match=r"bad\.h5: missing dataset\(s\) \['V', 'weights'\]"):
        read_hdf5(path)


def test_hdf5_newer_format_version(tmp_path):
    path = write_hdf5(_random_vis(), tmp_path / "new.h5")
    with h5py.File(path, "a") as fh:
        fh.attrs["format_version"] = FORMAT_VERSION + 1
    with pytest.raises(ValueError, match=r"new\.h5: format_version .* upgrade spiralbayes"):
        read_hdf5(path)


def test_hdf5_keeps_antennas_and_times_only_when_present(tmp_path):
    rng = np.random.default_rng(1)
    rows = {"antenna1": rng.integers(0, 5, 64), "antenna2": rng.integers(5, 10, 64),
            "time": np.repeat(np.arange(8) * 30.0, 8)}
    vis = _random_vis(wavelength=1.3e-3, **rows)
    back = read_hdf5(write_hdf5(vis, tmp_path / "a.h5"))
    _assert_same(vis, back)
    for name, value in rows.items():
        np.testing.assert_array_equal(getattr(back, name), value)
    assert back.antenna1.dtype == np.int64
    plain = read_hdf5(write_hdf5(_random_vis(wavelength=1.3e-3), tmp_path / "p.h5"))
    assert plain.antenna1 is None and plain.time is None
    with h5py.File(tmp_path / "p.h5") as fh:
        assert sorted(fh.keys()) == ["V", "u", "v", "weights"]
