"""Every result class keeps one protocol (:mod:`spiralbayes.results`): ``summary() -> str``,
``to_dict()`` that ``json.dumps`` accepts, ``save``/``load`` that give the same content back, a
one-line ``repr``; and files written before the dataclass layout still load.

The instances are small and built from arrays with random numbers (or from the package's own
functions on such arrays): the protocol is about what comes back, not about the numbers' meaning.
The format-1 files in ``tests/data/format1`` were written by the code before the dataclass layout
(commit d7fe32b, ``tests/data/format1/make_format1.py``); their content is checked against the
same builders here, so a reader that mixes up fields fails.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import h5py
import numpy as np
import pytest

from spiralbayes.exceptions import DataFileError
from spiralbayes.inference.scan import ScanPeak, ScanResult
from spiralbayes.results import Result

from tests._support.result_builders import BUILDERS, alternatives_result, forecast, posterior_result, scan_result

FORMAT1 = Path(__file__).parent / "data" / "format1"


def assert_same(a, b, where: str = "") -> None:
    """Equal content: dataclasses field by field, arrays with NumPy (NaN equal to NaN)."""
    if dataclasses.is_dataclass(a):
        assert type(a) is type(b), where
        for f in dataclasses.fields(a):
            assert_same(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and a.dtype.kind == b.dtype.kind, where
        np.testing.assert_array_equal(a, b, err_msg=where)
    elif isinstance(a, dict):
        assert isinstance(b, dict) and list(a) == list(b), where
        for k in a:
            assert_same(a[k], b[k], f"{where}[{k!r}]")
    elif isinstance(a, (list, tuple)):
        assert isinstance(b, type(a)) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{where}[{i}]")
    elif isinstance(a, float) and math.isnan(a):
        assert isinstance(b, float) and math.isnan(b), where
    else:
        assert type(a) is type(b) and a == b, (where, a, b)


@pytest.mark.parametrize("name", sorted(BUILDERS))
def test_result_protocol(name, tmp_path):
    obj = BUILDERS[name]()
    assert type(obj).__name__ == name and isinstance(obj, Result)
    text = obj.summary()
    assert isinstance(text, str) and text.strip()
    d = obj.to_dict()
    assert isinstance(d, dict)
    assert json.loads(json.dumps(d, allow_nan=False)) == d  # strict JSON, and nothing lost on the way
    line = repr(obj)
    assert "\n" not in line and line.startswith(name + "(")
    path = obj.save(tmp_path / f"{name}.h5")
    assert path == tmp_path / f"{name}.h5"
    with h5py.File(path, "r") as f:
        assert f.attrs["kind"] == obj.KIND and int(f.attrs["format_version"]) == 2
    back = type(obj).load(path)
    assert_same(obj, back, name)
    assert back.to_dict() == d


def test_best_is_a_property_returning_an_object():
    scan = scan_result()
    assert isinstance(scan.best, ScanPeak)
    dchi2 = 2 * scan.cross - scan.power
    t, i, j = np.unravel_index(np.argmax(dchi2), dchi2.shape)  # independent of ScanResult.peak
    assert (scan.best.template_index, scan.best.i_rp, scan.best.i_phi) == (t, i, j)
    assert scan.best.delta_chi2 == pytest.approx(dchi2[t, i, j])
    assert scan.best.delta_bic == pytest.approx(dchi2[t, i, j] - 6 * np.log(scan.n_data))
    alts = alternatives_result()
    assert alts.best is alts.fits["arc"]  # 40.5 - 5 ln N > 3.25 - 4 ln N
    post = posterior_result()
    assert post.best is post.runs[1]  # ln Z = -8.5 beats -9.5 at equal prior


def test_units_of_the_scan_datasets(tmp_path):
    path = scan_result().save(tmp_path / "scan.h5")
    with h5py.File(path, "r") as f:
        assert f["r_p"].attrs["units"] == "arcsec" and f["phi_p"].attrs["units"] == "rad"
        assert f["cross"].fletcher32 and f["power"].fletcher32


def test_an_unknown_layout_version_is_refused_with_its_number(tmp_path):
    path = scan_result().save(tmp_path / "scan.h5")
    with h5py.File(path, "a") as f:
        f.attrs["format_version"] = 7
    with pytest.raises(DataFileError, match="format_version 7 .*newer"):
        ScanResult.load(path)


def test_a_file_of_another_kind_is_refused(tmp_path):
    path = forecast().save(tmp_path / "forecast.h5")
    with pytest.raises(DataFileError, match="not a spiralbayes scan result"):
        ScanResult.load(path)


FORMAT1_FILES = {"ScanResult": "scan.h5", "AlternativesResult": "alternatives.h5",
                 "ExclusionLimits": "limits.h5", "CompletenessResult": "completeness.h5",
                 "PosteriorResult": "posterior.h5"}


@pytest.mark.parametrize("name", sorted(FORMAT1_FILES))
def test_format1_files_still_load(name):
    path = FORMAT1 / FORMAT1_FILES[name]
    with h5py.File(path, "r") as f:
        assert int(f.attrs["format_version"]) == 1
    obj = BUILDERS[name]()
    back = type(obj).load(path)
    if name == "ExclusionLimits":  # written by the old compute_limits: provenance differs by its time stamp
        obj.provenance, back.provenance = {}, {}
    if name == "AlternativesResult":  # the old layout wrote the fits in the order of to_dict
        assert set(back.fits) == set(obj.fits)
        back.fits = {k: back.fits[k] for k in obj.fits}
    assert_same(obj, back, name)
