"""Tests of the Visibilities container, its readers/writers, binning and weight estimation."""

from __future__ import annotations

import hashlib
import logging
import re
from pathlib import Path

import numpy as np
import pytest

from spiralbayes.io import (
    load_visibilities,
    read_uvtable,
    save_visibilities,
    write_uvtable,
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


def _assert_same(a: Visibilities, b: Visibilities):
    np.testing.assert_array_equal(a.u, b.u)
    np.testing.assert_array_equal(a.v, b.v)
    np.testing.assert_array_equal(a.V, b.V)
    np.testing.assert_array_equal(a.weights, b.weights)
    assert a.wavelength == b.wavelength
    assert a.conjugated == b.conjugated


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
    rows = rows.copy()
    rows[:, :2] /= 0.87e-3  # the header says metres but the numbers are wavelengths
    lam = _write_rows(tmp_path / "lam.txt", "wavelength[m] = 0.00087\nColumns: u[m] v[m] Re(V)[Jy] Im(V)[Jy] weight",
                      rows, fmt="%.17g")
    with caplog.at_level(logging.WARNING, logger="spiralbayes"):
        vis = read_uvtable(lam, uv_units="lambda")
    np.testing.assert_array_equal(vis.u, rows[:, 0])
    assert "header declares u, v in m" in caplog.text
    with pytest.raises(ValueError, match="look like metres"):  # a false override of real metres is refused
        read_uvtable(path, uv_units="lambda")


def test_short_baselines_in_lambda_warn_about_metres(tmp_path):
    from spiralbayes.exceptions import DataWarning

    rows = np.column_stack([np.full(4, 300.0), np.zeros(4), np.ones(4), np.zeros(4), np.ones(4)])
    path = _write_rows(tmp_path / "short.txt", "", rows)
    with pytest.warns(DataWarning, match="if u, v are in metres, pass uv_units='m'"):
        read_uvtable(path)


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
    path.write_text("1e5 2e5 1 0\n1e5 2e5 1 0 1\n1e5 2e5 1 0 1\n")
    with pytest.raises(ValueError, match=r"ragged\.txt: could not parse the table"):
        read_uvtable(path)
    path.write_text("1e5 2e5 1 0 1\n1e5 2e5 1 0\n")  # a short last row: cut, named by its line
    with pytest.raises(ValueError, match=r"ragged\.txt, line 2: the last row has 4 numbers where the rows before "
                                         "have 5"):
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
    with caplog.at_level(logging.INFO, logger="spiralbayes"):
        vis = read_uvtable(path)
    assert vis.n == 1 and vis.provenance["dropped_zero_weight"] == 2
    assert "dropped 2 visibilities with zero weight" in caplog.text


@pytest.mark.parametrize("fmt", ["%.10g", "%.17g", "%.6e", "%g", "%.8f"])
def test_whole_tables_in_common_formats_are_not_called_cut(tmp_path, fmt):
    """The cut-row checks compare the last row with the rows before: tables written whole in the usual
    formats, with a flagged (all-zero) last row or whole-number weights, must pass (300 random tables each)."""
    from spiralbayes.io.data_checks import check_last_row

    rng = np.random.default_rng(11)
    path = tmp_path / "t.txt"
    for trial in range(300):
        n = 30
        weights = rng.uniform(1e3, 3e4, n) if trial % 2 else np.full(n, 4e6)
        if trial % 5 == 0:
            weights = np.round(weights)
        table = np.column_stack([rng.uniform(-1e6, 1e6, n), rng.uniform(-1e6, 1e6, n), rng.normal(0, 0.01, n),
                                 rng.normal(0, 0.01, n), weights])
        if trial % 3 == 0:
            table[-1, 2:] = 0.0
        np.savetxt(path, table, fmt=fmt, header="wavelength[m] = 1.3e-3", delimiter="," if trial % 7 == 0 else " ")
        check_last_row(path)


@pytest.mark.parametrize("text,expected", [
    ("1.5e5 2e5 1 0 3.4e-3\n1.6e5 2e5 1 0 3.5e-3\n1.7e5 2e5 1 0 3.4\n", "('3.4') has no exponent"),
    ("1.5e5 2e5 1 0 3.4e-3\n1.6e5 2e5 1 0 3.5e-3\n1.7e5 2e5 1 0 3.4e-\n", "('3.4e-') ends inside its exponent"),
    ("1.5e5 2e5 1 0 3.4e-03\n1.6e5 2e5 1 0 3.5e-03\n1.7e5 2e5 1 0 3.4e-0\n", "('3.4e-0') has a shorter exponent"),
])
def test_a_last_row_cut_at_its_exponent_is_refused_naming_the_line(tmp_path, text, expected):
    path = tmp_path / "cut.txt"
    path.write_text("# u v Re Im weight\n" + text)
    with pytest.raises(ValueError, match=rf"cut\.txt, line 4: the last row's column 5 {re.escape(expected)}"):
        read_uvtable(path)
