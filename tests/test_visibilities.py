"""Tests of the Visibilities container, its readers/writers, binning and weight estimation."""

from __future__ import annotations

import hashlib
import logging
from pathlib import Path

import h5py
import numpy as np
import pytest

from spiralbayes._provenance import FORMAT_VERSION
from spiralbayes.geometry import ARCSEC, DiscGeometry
from spiralbayes.visibilities import (
    C_LIGHT,
    BinnedVisibilities,
    Visibilities,
    bin_deprojected,
    estimate_weight_factor,
    estimate_weights,
    load_visibilities,
    read_hdf5,
    read_npz,
    read_uvtable,
    save_visibilities,
    write_hdf5,
    write_npz,
    write_uvtable,
)

DATA = Path(__file__).parent / "data"
AS209 = DATA / "AS209_DSHARP_subsample_uvtable.txt"


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


# ----------------------------------------------------------------------------------
# real data: AS 209
# ----------------------------------------------------------------------------------
def test_as209_subsample_loads_with_the_right_numbers():
    before = _sha(AS209)
    vis = load_visibilities(AS209)
    assert _sha(AS209) == before, "loading must not modify the file"
    assert vis.n == 196
    assert vis.u[0] == 6.389651882002101047e04
    assert vis.v[0] == -2.058540942542955454e05
    assert vis.V[0] == 8.765532989316400514e-02 - 8.743703676857957074e-02j
    assert vis.weights[0] == 3.935939968110825760e01
    assert vis.u[-1] == -2.250726005949392274e05
    assert vis.weights[-1] == 1.868071305516029679e04
    q = vis.uv_distance
    assert 16e3 <= q.min() < 17e3
    assert q.max() == pytest.approx(6.06e6, rel=1e-3)
    assert vis.wavelength is None and not vis.conjugated
    assert vis.provenance["sha256"] == before
    assert vis.provenance["reader"] == "read_uvtable"


def test_as209_profile_file_has_radius_and_intensity_columns():
    r, intensity = np.genfromtxt(DATA / "AS209_clean_profile_frank.txt").T
    assert r.size == intensity.size == 300
    assert np.all(np.diff(r) > 0) and r.max() < 3.0  # arcsec (to 2.48)
    assert intensity[0] > 1e10  # Jy/sr


def test_as209_binned_profile_falls_with_baseline():
    vis = read_uvtable(AS209)
    geom = DiscGeometry(inc=34.97, PA=85.76, dRA=-1.9e-3, dDec=2.5e-3)
    binned = bin_deprojected(vis, geom, bins=[0, 2e5, 1e6, 7e6])
    assert binned.counts.sum() == 196
    assert binned.re[0] > binned.re[1] > abs(binned.re[2])  # a resolved disc


# ----------------------------------------------------------------------------------
# uvtable reader / writer
# ----------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["vis.txt", "vis.dat", "vis.csv", "vis.txt.gz"])
def test_uvtable_round_trip(tmp_path, name):
    vis = _random_vis(wavelength=8.7e-4, conjugated=True, provenance={"origin": "test"})
    path = save_visibilities(vis, tmp_path / name)
    back = load_visibilities(path)
    _assert_same(vis, back)
    assert back.provenance["written_provenance"] == {"origin": "test"}
    assert list(tmp_path.iterdir()) == [tmp_path / name], "no temporary files left behind"


def test_uvtable_without_wavelength_round_trips(tmp_path):
    vis = _random_vis()
    write_uvtable(vis, tmp_path / "a.txt")
    back = read_uvtable(tmp_path / "a.txt")
    _assert_same(vis, back)


def _write_rows(path: Path, header: str, rows: np.ndarray, fmt="%.10g", delimiter="\t") -> Path:
    np.savetxt(path, rows, fmt=fmt, delimiter=delimiter, header=header)
    return path


def _uvplot_file(tmp_path, wle=8.7e-4, header_wle=True):
    rng = np.random.default_rng(3)
    um, vm = rng.uniform(-3000, 3000, (2, 20))  # metres
    rows = np.column_stack([um, vm, rng.normal(size=20), rng.normal(size=20), rng.uniform(1, 2, 20)])
    lines = ["Extracted from mstable.ms."]
    if header_wle:
        lines.append(f"wavelength[m] = {wle}")
    lines.append("Columns:\tu[m]\tv[m]\tRe(V)[Jy]\tIm(V)[Jy]\tweight")
    return _write_rows(tmp_path / "uvplot.txt", "\n".join(lines), rows, fmt="%.17g"), rows


def test_uvplot_metres_converted_with_header_wavelength(tmp_path):
    path, rows = _uvplot_file(tmp_path, wle=8.7e-4)
    vis = read_uvtable(path)
    np.testing.assert_allclose(vis.u, rows[:, 0] / 8.7e-4, rtol=1e-15)
    np.testing.assert_allclose(vis.v, rows[:, 1] / 8.7e-4, rtol=1e-15)
    assert vis.wavelength == 8.7e-4
    assert vis.provenance["uv_units"] == "m"
    assert "metres" in vis.provenance["conversions"][0]


def test_uvplot_weight_factor_recorded(tmp_path):
    path, rows = _uvplot_file(tmp_path)
    vis = read_uvtable(path, weight_factor=2.0)
    np.testing.assert_allclose(vis.weights, 2 * rows[:, 4])
    assert any("weight_factor" in c for c in vis.provenance["conversions"])


def test_metres_without_wavelength_is_an_error_naming_the_fix(tmp_path):
    path, _ = _uvplot_file(tmp_path, header_wle=False)
    with pytest.raises(ValueError, match=r"uvplot\.txt: u, v are in metres but no wavelength.*wavelength="):
        read_uvtable(path)
    plain = _write_rows(tmp_path / "plain.txt", "", np.ones((3, 5)))
    with pytest.raises(ValueError, match=r"plain\.txt: u, v are in metres.*pass wavelength="):
        read_uvtable(plain, uv_units="m")


def test_metres_with_given_wavelength(tmp_path):
    rows = np.column_stack([np.arange(1.0, 6.0) * 100, np.zeros(5), np.ones(5), np.zeros(5), np.ones(5)])
    path = _write_rows(tmp_path / "m.txt", "", rows)
    vis = read_uvtable(path, uv_units="m", wavelength=1e-3)
    np.testing.assert_allclose(vis.u, rows[:, 0] / 1e-3)
    assert vis.wavelength == 1e-3


def test_klambda_units(tmp_path):
    rows = np.column_stack([np.arange(1.0, 6.0) * 100, np.zeros(5), np.ones(5), np.zeros(5), np.ones(5)])
    path = _write_rows(tmp_path / "k.txt", "Columns: u[klambda] v[klambda] Re Im weight", rows)
    np.testing.assert_allclose(read_uvtable(path).u, rows[:, 0] * 1e3)


def test_explicit_units_override_header_with_warning(tmp_path, caplog):
    path, rows = _uvplot_file(tmp_path)
    with caplog.at_level(logging.WARNING, logger="spiralbayes.visibilities"):
        vis = read_uvtable(path, uv_units="lambda")
    np.testing.assert_array_equal(vis.u, rows[:, 0])
    assert "header declares u, v in m" in caplog.text
    assert "look" not in caplog.text or "metres" in caplog.text


def test_short_baselines_in_lambda_warn_about_metres(tmp_path, caplog):
    rows = np.column_stack([np.full(4, 300.0), np.zeros(4), np.ones(4), np.zeros(4), np.ones(4)])
    path = _write_rows(tmp_path / "short.txt", "", rows)
    with caplog.at_level(logging.WARNING, logger="spiralbayes.visibilities"):
        read_uvtable(path)
    assert "if u, v are in metres pass uv_units='m'" in caplog.text


def test_comma_separated_and_comments(tmp_path):
    path = tmp_path / "c.txt"
    path.write_text("# a comment\n# another\n1e5, 2e5, 0.5, -0.25, 10\n# mid comment\n3e5,4e5,1,0,20\n")
    vis = read_uvtable(path)
    np.testing.assert_array_equal(vis.u, [1e5, 3e5])
    np.testing.assert_array_equal(vis.V, [0.5 - 0.25j, 1])


@pytest.mark.parametrize("ncols", [4, 6, 7])
def test_wrong_number_of_columns(tmp_path, ncols):
    path = _write_rows(tmp_path / f"bad{ncols}.txt", "", np.ones((3, ncols)) * 1e5)
    with pytest.raises(ValueError, match=rf"bad{ncols}\.txt: found {ncols} columns.*expected 5: u \[lambda\]"):
        read_uvtable(path)


def test_six_columns_with_w_column(tmp_path):
    rng = np.random.default_rng(5)
    rows = np.column_stack([rng.uniform(-1e3, 1e3, (3, 8)).T, rng.normal(size=(8, 2)), np.ones(8)])
    header = "wavelength[m] = 0.00132940778422\nColumns:\tu[m]\tv[m]\tw[m]\tRe(V)[Jy]\tIm(V)[Jy]\tweight"
    path = _write_rows(tmp_path / "w.txt", header, rows, fmt="%.17g")
    vis = read_uvtable(path)
    np.testing.assert_allclose(vis.u, rows[:, 0] / 0.00132940778422)
    np.testing.assert_array_equal(vis.V, rows[:, 3] + 1j * rows[:, 4])


def test_six_columns_with_per_row_wavelength(tmp_path):
    rows = np.column_stack([[1e5, 2e5], [0, 1e5], [1, 2], [0, 0], [1, 1], [1.2e-3, 1.3e-3]])
    header = "Columns:\tu[lambda]\tv[lambda]\tRe(V)[Jy]\tIm(V)[Jy]\tweight\tlambda[m]"
    vis = read_uvtable(_write_rows(tmp_path / "l.txt", header, rows))
    np.testing.assert_array_equal(vis.u, rows[:, 0])
    assert vis.wavelength == pytest.approx(1.25e-3)


def test_ragged_rows(tmp_path):
    path = tmp_path / "ragged.txt"
    path.write_text("1e5 2e5 1 0 1\n1e5 2e5 1 0\n")
    with pytest.raises(ValueError, match=r"ragged\.txt: could not parse the table"):
        read_uvtable(path)


def test_empty_table(tmp_path):
    path = tmp_path / "empty.txt"
    path.write_text("# only a header\n\n")
    with pytest.raises(ValueError, match=r"empty\.txt: no data rows"):
        read_uvtable(path)


def test_nan_in_file_names_the_file(tmp_path):
    path = tmp_path / "nan.txt"
    path.write_text("1e5 2e5 nan 0 1\n")
    with pytest.raises(ValueError, match=r"nan\.txt: V has 1 NaN/inf"):
        read_uvtable(path)


def test_negative_weight_in_file_names_the_file(tmp_path):
    path = tmp_path / "neg.txt"
    path.write_text("1e5 2e5 1 0 -1\n")
    with pytest.raises(ValueError, match=r"neg\.txt: weights has 1 negative"):
        read_uvtable(path)


def test_zero_weight_rows_in_file_dropped(tmp_path, caplog):
    path = tmp_path / "zero.txt"
    path.write_text("1e5 2e5 1 0 0\n2e5 2e5 1 0 3\n3e5 2e5 1 0 0\n")
    with caplog.at_level(logging.INFO, logger="spiralbayes.visibilities"):
        vis = read_uvtable(path)
    assert vis.n == 1 and vis.provenance["dropped_zero_weight"] == 2
    assert "dropped 2 visibilities with zero weight" in caplog.text


def test_missing_file():
    with pytest.raises(FileNotFoundError, match="nope.txt"):
        load_visibilities("nope.txt")


def test_unknown_extension(tmp_path):
    path = tmp_path / "data.fits"
    path.write_bytes(b"x")
    with pytest.raises(ValueError, match=r"data\.fits: unknown visibility format '.fits'; supported"):
        load_visibilities(path)


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


def test_failed_write_leaves_existing_file_intact(tmp_path, monkeypatch):
    import spiralbayes.visibilities as sv

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


def test_measurement_set_without_casacore_names_the_extra(tmp_path, monkeypatch):
    import sys

    from spiralbayes.measurement_set import read_ms

    monkeypatch.setitem(sys.modules, "casacore", None)
    monkeypatch.setitem(sys.modules, "casacore.tables", None)
    (tmp_path / "x.ms").mkdir()
    with pytest.raises(ImportError, match=r'pip install "spiralbayes\[ms\]"'):
        read_ms(tmp_path / "x.ms")
    with pytest.raises(ImportError, match=r'pip install "spiralbayes\[ms\]"'):
        save_visibilities(_random_vis(wavelength=1e-3), tmp_path / "y.ms")


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
