"""Tests of the Visibilities container, its readers/writers, binning and weight estimation."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

from spiralbayes.io import (
    load_visibilities,
    read_uvtable,
    save_visibilities,
    write_hdf5,
)
from spiralbayes.visibilities import (
    Visibilities,
)
from tests._support.helpers import DATA

AS209 = DATA / "AS209_DSHARP_subsample_uvtable.txt"

def _sha(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _random_vis(n=64, seed=0, **kw) -> Visibilities:
    rng = np.random.default_rng(seed)
    return Visibilities(
        u=rng.uniform(-2e6, 2e6, n), v=rng.uniform(-2e6, 2e6, n),
        V=rng.normal(size=n) + 1j * rng.normal(size=n), weights=rng.uniform(0.5, 50.0, n), **kw,
    )


def test_missing_file():
    with pytest.raises(FileNotFoundError, match="nope.txt"):
        load_visibilities("nope.txt")


def test_unknown_extension(tmp_path):
    path = tmp_path / "data.fits"
    path.write_bytes(b"x")
    with pytest.raises(ValueError, match=r"data\.fits: unknown visibility format '.fits'; supported"):
        load_visibilities(path)


def test_failed_write_leaves_existing_file_intact(tmp_path, monkeypatch):
    import spiralbayes.io.hdf5 as sv

    path = write_hdf5(_random_vis(seed=1), tmp_path / "keep.h5")
    before = _sha(path)

    def boom(vis, group):
        group.create_dataset("u", data=vis.u)
        raise RuntimeError("disk full")

    monkeypatch.setattr(sv, "visibilities_to_hdf5_group", boom)
    with pytest.raises(RuntimeError, match="disk full"):
        write_hdf5(_random_vis(seed=2), path)
    assert _sha(path) == before
    assert list(tmp_path.iterdir()) == [path]


@pytest.mark.parametrize("name", ["f.txt", "f.npz"])
def test_frank_reads_what_we_write(tmp_path, name):
    frank_io = pytest.importorskip("frank.io")
    vis = _random_vis(wavelength=1.3e-3)
    u, v, V, w = frank_io.load_uvtable(str(save_visibilities(vis, tmp_path / name)))
    np.testing.assert_array_equal(u, vis.u)
    np.testing.assert_array_equal(v, vis.v)
    np.testing.assert_array_equal(V, vis.V)
    np.testing.assert_array_equal(w, vis.weights)


def test_frank_and_we_read_as209_identically():
    frank_io = pytest.importorskip("frank.io")
    u, v, V, w = frank_io.load_uvtable(str(AS209))
    vis = read_uvtable(AS209)
    np.testing.assert_array_equal(vis.u, u)
    np.testing.assert_array_equal(vis.V, V)
    np.testing.assert_array_equal(vis.weights, w)
