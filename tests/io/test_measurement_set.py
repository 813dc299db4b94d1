"""Tests of the Measurement Set reader/writer (skipped when python-casacore is missing)."""

from __future__ import annotations

import hashlib
import logging
from pathlib import Path

import numpy as np
import pytest

tables = pytest.importorskip("casacore.tables")


from spiralbayes.io import load_visibilities, save_visibilities  # noqa: E402
from spiralbayes.io.measurement_set import read_ms, write_ms  # noqa: E402
from spiralbayes.units import C_LIGHT  # noqa: E402
from spiralbayes.visibilities import (  # noqa: E402
    Visibilities,
    )

# spectral windows: spw 0 at 230 GHz, spw 1 at 345 GHz, two channels each. The data
# descriptions map DDID 0 -> spw 1 and DDID 1 -> spw 0, so a reader that confuses the two fails.
SPW_FREQ = [np.array([230.0e9, 231.0e9]), np.array([345.0e9, 346.5e9])]
DD_SPW = [1, 0]


def _tree_digest(path: Path) -> dict:
    return {str(p.relative_to(path)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(path.rglob("*")) if p.is_file()}


def _make_ms(path: Path, nrow=6, seed=0, corrected=False, weight_spectrum=False, corr=(9, 12),
             drop=(), flag_row=None, fields=("AS_209",), field_id=None, wsigma=None):
    """Write a small MS with casacore.tables and return the arrays written (numpy order)."""
    rng = np.random.default_rng(seed)
    ncorr = len(corr)
    uvw = rng.uniform(-500.0, 500.0, (nrow, 3))
    data = (rng.normal(size=(nrow, 2, ncorr)) + 1j * rng.normal(size=(nrow, 2, ncorr))).astype(np.complex64)
    weight = rng.uniform(1.0, 5.0, (nrow, ncorr)).astype(np.float32)
    if wsigma is not None:
        weight[:] = 1.0 / np.asarray(wsigma, dtype=np.float32) ** 2
    flag = np.zeros((nrow, 2, ncorr), dtype=bool)
    flag[1, 0, 0] = True  # one hand of one channel
    flag[2, :, :] = True  # a whole row, via FLAG
    ddid = np.arange(nrow) % 2
    cols = [tables.makearrcoldesc("DATA", 0j, ndim=2, shape=[2, ncorr], valuetype="complex")]
    if corrected:
        cols.append(tables.makearrcoldesc("CORRECTED_DATA", 0j, ndim=2, shape=[2, ncorr], valuetype="complex"))
    if weight_spectrum:
        cols.append(tables.makearrcoldesc("WEIGHT_SPECTRUM", 0.0, ndim=2, shape=[2, ncorr], valuetype="float"))
    with tables.default_ms(str(path), tables.maketabdesc(cols)) as ms:
        ms.addrows(nrow)
        ms.putcol("UVW", uvw)
        ms.putcol("DATA", data)
        ms.putcol("WEIGHT", weight)
        ms.putcol("FLAG", flag)
        ms.putcol("DATA_DESC_ID", ddid.astype(np.int32))
        ms.putcol("FIELD_ID", (np.zeros(nrow) if field_id is None else field_id).astype(np.int32))
        if flag_row is not None:
            ms.putcol("FLAG_ROW", flag_row)
        corrected_data = None
        if corrected:
            corrected_data = (2 * data).astype(np.complex64)
            ms.putcol("CORRECTED_DATA", corrected_data)
        wspec = None
        if weight_spectrum:
            wspec = rng.uniform(1.0, 5.0, (nrow, 2, ncorr)).astype(np.float32)
            ms.putcol("WEIGHT_SPECTRUM", wspec)
        if drop:
            ms.removecols(list(drop))
    with tables.table(str(path / "SPECTRAL_WINDOW"), readonly=False, ack=False) as spw:
        spw.addrows(2)
        for i, f in enumerate(SPW_FREQ):
            spw.putcell("CHAN_FREQ", i, f)
            spw.putcell("NUM_CHAN", i, 2)
    with tables.table(str(path / "POLARIZATION"), readonly=False, ack=False) as pol:
        pol.addrows(1)
        pol.putcell("CORR_TYPE", 0, np.array(corr, dtype=np.int32))
        pol.putcell("NUM_CORR", 0, ncorr)
    with tables.table(str(path / "DATA_DESCRIPTION"), readonly=False, ack=False) as dd:
        dd.addrows(2)
        dd.putcol("SPECTRAL_WINDOW_ID", np.array(DD_SPW, dtype=np.int32))
        dd.putcol("POLARIZATION_ID", np.zeros(2, dtype=np.int32))
    with tables.table(str(path / "FIELD"), readonly=False, ack=False) as fld:
        fld.addrows(len(fields))
        fld.putcol("NAME", list(fields))
    return dict(uvw=uvw, data=data, weight=weight, flag=flag, ddid=ddid, corrected=corrected_data, wspec=wspec)


def _expected(m: dict, use=None, weights=None, rows=None):
    """Stokes I by explicit loops: (XX+YY)/2, w = 4/(1/wXX + 1/wYY), u per channel."""
    data = m["data"] if use is None else use
    out = {"u": [], "v": [], "V": [], "w": []}
    nrow = data.shape[0]
    for r in range(nrow) if rows is None else rows:
        freq = SPW_FREQ[DD_SPW[m["ddid"][r]]]
        for c in range(2):
            if m["flag"][r, c].any():
                continue
            wx, wy = (m["weight"][r] if weights is None else weights[r, c]).astype(float)
            out["u"].append(m["uvw"][r, 0] * freq[c] / C_LIGHT)
            out["v"].append(m["uvw"][r, 1] * freq[c] / C_LIGHT)
            out["V"].append(0.5 * (complex(data[r, c, 0]) + complex(data[r, c, 1])))
            out["w"].append(4.0 / (1.0 / wx + 1.0 / wy))
    return {k: np.array(v) for k, v in out.items()}


def _sort(u, *arrays):
    order = np.argsort(u)
    return [np.asarray(a)[order] for a in (u, *arrays)]


def _check(vis: Visibilities, exp: dict):
    assert vis.n == exp["u"].size
    got = _sort(vis.u, vis.v, vis.V, vis.weights)
    want = _sort(exp["u"], exp["v"], exp["V"], exp["w"])
    for g, w in zip(got, want):
        np.testing.assert_allclose(g, w, rtol=1e-12)


def test_read_ms_per_channel_wavelengths_flags_and_stokes_i(tmp_path):
    path = tmp_path / "small.ms"
    m = _make_ms(path)
    before = _tree_digest(path)
    vis = read_ms(path)
    assert _tree_digest(path) == before, "reading must not modify the MS"
    exp = _expected(m)
    assert vis.n == 6 * 2 - 1 - 2  # 12 (row, channel) points, one with a flagged hand, one row flagged
    _check(vis, exp)
    # the same baseline in two channels gives two different u: per-channel wavelengths
    r0 = m["uvw"][0, 0]  # row 0 is DDID 0 -> spw 1
    for c in range(2):
        assert np.any(np.isclose(vis.u, r0 * SPW_FREQ[DD_SPW[0]][c] / C_LIGHT, rtol=1e-14, atol=0))
    assert not vis.conjugated
    assert vis.wavelength == pytest.approx(C_LIGHT / np.mean(np.concatenate(SPW_FREQ)))
    assert vis.provenance["column"] == "DATA" and vis.provenance["weights_from"] == "WEIGHT"
    assert vis.provenance["n_flagged_dropped"] == 3


def test_read_ms_prefers_corrected_data(tmp_path):
    path = tmp_path / "corr.ms"
    m = _make_ms(path, corrected=True)
    _check(read_ms(path), _expected(m, use=m["corrected"]))
    _check(read_ms(path, column="DATA"), _expected(m))


def test_read_ms_uses_weight_spectrum(tmp_path):
    path = tmp_path / "ws.ms"
    m = _make_ms(path, weight_spectrum=True)
    vis = read_ms(path)
    assert vis.provenance["weights_from"] == "WEIGHT_SPECTRUM"
    _check(vis, _expected(m, weights=m["wspec"]))


def test_read_ms_flag_row(tmp_path):
    path = tmp_path / "fr.ms"
    flag_row = np.zeros(6, dtype=bool)
    flag_row[4] = True
    m = _make_ms(path, flag_row=flag_row)
    _check(read_ms(path), _expected(m, rows=[0, 1, 2, 3, 5]))


def test_read_ms_spw_and_field_selection(tmp_path):
    path = tmp_path / "sel.ms"
    m = _make_ms(path, fields=("other", "AS_209"), field_id=np.array([0, 1, 1, 1, 0, 1]))
    # spw 0 is DDID 1: rows 1, 3, 5
    _check(read_ms(path, spw=0), _expected(m, rows=[1, 3, 5]))
    _check(read_ms(path, field="AS_209"), _expected(m, rows=[1, 2, 3, 5]))
    _check(read_ms(path, field=[0], spw=[1]), _expected(m, rows=[0, 4]))
    with pytest.raises(ValueError, match=r"sel\.ms: no field named 'nope'"):
        read_ms(path, field="nope")
    with pytest.raises(ValueError, match=r"sel\.ms: no spectral window\(s\) \[7\]"):
        read_ms(path, spw=7)


def test_read_ms_separate_polarisations(tmp_path):
    path = tmp_path / "pol.ms"
    m = _make_ms(path)
    vis = read_ms(path, average_polarisations=False)
    n_expected = int((~m["flag"]).sum())
    assert vis.n == n_expected
    w_in = np.sort(np.broadcast_to(m["weight"][:, None, :], m["flag"].shape)[~m["flag"]].astype(float))
    np.testing.assert_allclose(np.sort(vis.weights), w_in)


def test_read_ms_single_correlation(tmp_path):
    path = tmp_path / "xx.ms"
    m = _make_ms(path, corr=(9,))
    vis = read_ms(path)
    assert vis.n == int((~m["flag"]).sum())


def test_stokes_i_weight_is_the_statistical_one(tmp_path):
    """Noise of (XX+YY)/2 with unequal sigma matches the weight 4/(1/wXX + 1/wYY)."""
    path = tmp_path / "noise.ms"
    nrow = 3000
    m = _make_ms(path, nrow=nrow, seed=4, wsigma=[0.1, 0.3])
    rng = np.random.default_rng(9)
    noise = np.stack([0.1 * rng.normal(size=(nrow, 2)), 0.3 * rng.normal(size=(nrow, 2))], axis=-1)
    with tables.table(str(path), readonly=False, ack=False) as ms:
        ms.putcol("DATA", noise.astype(np.complex64))
        ms.putcol("FLAG", np.zeros_like(m["flag"]))
    vis = read_ms(path)
    w_expected = 4.0 / (0.1**2 + 0.3**2)
    np.testing.assert_allclose(vis.weights, w_expected, rtol=1e-6)
    assert np.var(vis.V.real) * w_expected == pytest.approx(1.0, rel=0.05)


@pytest.mark.parametrize("column", ["WEIGHT", "UVW", "FLAG"])
def test_missing_columns_are_named(tmp_path, column):
    path = tmp_path / "broken.ms"
    _make_ms(path, drop=(column,))
    with pytest.raises(ValueError, match=rf"broken\.ms: .*{column}"):
        read_ms(path)


def test_missing_data_column_is_named(tmp_path):
    path = tmp_path / "nodata.ms"
    _make_ms(path)
    with pytest.raises(ValueError,
                       match=r"nodata\.ms: Measurement Set has no \(filled\) column CORRECTED_DATA.*'DATA'"):
        read_ms(path, column="CORRECTED_DATA")


def test_missing_subtable_is_named(tmp_path):
    import shutil

    path = tmp_path / "nospw.ms"
    _make_ms(path)
    shutil.rmtree(path / "SPECTRAL_WINDOW")
    with pytest.raises(ValueError, match=r"nospw\.ms: Measurement Set lacks the SPECTRAL_WINDOW subtable"):
        read_ms(path)


def test_all_flagged(tmp_path):
    path = tmp_path / "flagged.ms"
    _make_ms(path)
    with tables.table(str(path), readonly=False, ack=False) as ms:
        ms.putcol("FLAG", np.ones((6, 2, 2), dtype=bool))
    with pytest.raises(ValueError, match=r"flagged\.ms: no unflagged data"):
        read_ms(path)


def test_not_an_ms(tmp_path):
    (tmp_path / "empty.ms").mkdir()
    with pytest.raises(FileNotFoundError, match="not a Measurement Set"):
        read_ms(tmp_path / "empty.ms")


def test_write_ms_round_trip(tmp_path):
    rng = np.random.default_rng(2)
    n = 40
    vis = Visibilities(u=rng.uniform(-1e6, 1e6, n), v=rng.uniform(-1e6, 1e6, n),
                       V=rng.normal(size=n) + 1j * rng.normal(size=n), weights=rng.uniform(1, 100, n),
                       wavelength=1.25e-3, provenance={"origin": "synthetic"})
    path = save_visibilities(vis, tmp_path / "rt.ms")
    before = _tree_digest(path)
    back = load_visibilities(path)
    assert _tree_digest(path) == before
    np.testing.assert_allclose(back.u, vis.u, rtol=1e-14)
    np.testing.assert_allclose(back.v, vis.v, rtol=1e-14)
    np.testing.assert_allclose(back.V, vis.V, rtol=1e-6, atol=1e-7)  # DATA is complex64, as in CASA
    np.testing.assert_allclose(back.weights, vis.weights, rtol=1e-6)  # WEIGHT is float32
    assert back.wavelength == pytest.approx(1.25e-3, rel=1e-15)
    assert back.provenance["written_provenance"] == {"origin": "synthetic"}
    # overwrite in place, no temporary directories left
    save_visibilities(vis.subset(slice(0, 5)), path)
    assert read_ms(path).n == 5
    assert [p.name for p in tmp_path.iterdir()] == ["rt.ms"]


def test_write_ms_conjugated_data_written_in_ms_convention(tmp_path):
    vis = Visibilities(u=[1e5, 2e5], v=[0.0, 1e5], V=[1 + 1j, 2 - 1j], weights=[1.0, 2.0],
                       wavelength=1e-3, conjugated=True)
    back = read_ms(write_ms(vis, tmp_path / "c.ms"))
    assert not back.conjugated
    np.testing.assert_allclose(back.V, [1 - 1j, 2 + 1j], rtol=1e-7)


def test_write_ms_needs_wavelength(tmp_path):
    vis = Visibilities(u=[1e5], v=[0.0], V=[1], weights=[1.0])
    with pytest.raises(ValueError, match="write_ms needs the observing wavelength"):
        write_ms(vis, tmp_path / "x.ms")
    assert not (tmp_path / "x.ms").exists()


def test_flagged_points_logged(tmp_path, caplog):
    path = tmp_path / "log.ms"
    _make_ms(path)
    with caplog.at_level(logging.INFO, logger="spiralbayes.io.measurement_set"):
        read_ms(path)
    assert "dropped 3 flagged points" in caplog.text


def _random_vis(n=64, seed=0, **kw) -> Visibilities:
    rng = np.random.default_rng(seed)
    return Visibilities(
        u=rng.uniform(-2e6, 2e6, n), v=rng.uniform(-2e6, 2e6, n),
        V=rng.normal(size=n) + 1j * rng.normal(size=n), weights=rng.uniform(0.5, 50.0, n), **kw,
    )


def test_measurement_set_without_casacore_names_the_extra(tmp_path, monkeypatch):
    import sys

    from spiralbayes.io.measurement_set import read_ms

    monkeypatch.setitem(sys.modules, "casacore", None)
    monkeypatch.setitem(sys.modules, "casacore.tables", None)
    (tmp_path / "x.ms").mkdir()
    with pytest.raises(ImportError, match=r'pip install "spiralbayes\[ms\]"'):
        read_ms(tmp_path / "x.ms")
    with pytest.raises(ImportError, match=r'pip install "spiralbayes\[ms\]"'):
        save_visibilities(_random_vis(wavelength=1e-3), tmp_path / "y.ms")
