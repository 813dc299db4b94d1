"""Hostile inputs, third pass: each case is one line naming the option or argument and the fix.

Same style as :mod:`tests.test_faults_hostile`: cases that touch files hash every input and the
output folder before and after (``Unchanged``) — a refused call loses and overwrites nothing.

Cases: ``simulate --out`` onto an existing file; a scan of other data into an output folder (with
``[scan] checkpoint = false``), a frank fit of other data into ``axisym --out``, a demo into a
folder holding the scan of real data; a path, a name or None where ``sb.scan``/``sb.detect`` expect
objects; non-finite template metadata; a frank fit of 2 visibilities; a uvtable whose last row
was cut and still ends in a newline, or lost its exponent.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from spiralbayes.exceptions import DataWarning, InputError
from spiralbayes.io import load_visibilities, save_visibilities

from .test_faults import GEOMETRY, GRID, _config, setup
from .test_faults_hostile import Unchanged, _inputs


# --- no command replaces a file it did not write unless asked -------------------------------------
def test_simulate_refuses_to_replace_an_existing_file_without_overwrite(tmp_path, capsys):
    from spiralbayes.cli import main

    table = tmp_path / "observation.txt"
    table.write_text("# a real uvtable\n1e5 2e5 1 0 1\n2e5 1e5 1 0 1\n")
    with Unchanged(tmp_path):
        assert main(["-q", "simulate", "--preset", "taurus", "--out", str(table)]) == 2
    err = capsys.readouterr().err
    assert f"--out {table} already exists: refusing to replace it; give another --out or add --overwrite" in err
    assert err.count("\n") == 1
    assert main(["-q", "simulate", "--preset", "taurus", "--out", str(table), "--overwrite"]) == 0
    assert load_visibilities(table).n > 1000  # replaced when asked


# --- an output folder belongs to one dataset ------------------------------------------------------
def _previous_run(setup, out):
    """The 7 results a scan of ``setup``'s data leaves with plots off."""
    from spiralbayes.inference.detection import detect
    from spiralbayes.pipeline.outputs import write_scan_outputs

    files = write_scan_outputs(setup.result, detect(setup.result), out, plots=False)
    files.append(setup.model.save(out / "axisymmetric.h5"))
    (out / "config_used.toml").write_text("# the previous run\n")
    return files


def _other_data(setup, tmp_path):
    vis = setup.vis.with_weights(setup.vis.weights * 1.01, "other data")
    return save_visibilities(vis, tmp_path / "other.h5")


def test_scan_of_other_data_into_an_output_folder_is_refused_before_frank(setup, tmp_path, monkeypatch):
    import spiralbayes.pipeline.inputs as inputs
    import spiralbayes.pipeline.scan_command as scan_command
    from spiralbayes.config import load_config

    out = tmp_path / "out"
    _previous_run(setup, out)
    other = _other_data(setup, tmp_path)
    monkeypatch.setattr(inputs, "fit_axisymmetric", lambda *a, **k: pytest.fail("frank must not run"))
    monkeypatch.setattr(scan_command, "scan", lambda *a, **k: pytest.fail("the scan must not run"))
    cfg = _config(tmp_path / "c.toml", setup, out, data=f'path = "{other}"', frank="",
                  geometry="inc = 30.0\nPA = 60.0", scan="checkpoint = false")
    with Unchanged(out, other, *_inputs(setup)), pytest.raises(
            InputError, match=rf"{out} holds the results of a run on other data \(scan.h5: data hash \w+; this run's "
                              r"data: \w+\): refusing to overwrite them; give another \[output\] dir, or --overwrite"):
        scan_command.run_scan(load_config(cfg), progress=False)


def test_cli_scan_of_other_data_exits_2_and_overwrite_replaces(setup, tmp_path, capsys):
    from spiralbayes._provenance import data_hash
    from spiralbayes.cli import main
    from spiralbayes.inference.scan import ScanResult

    out = tmp_path / "out"
    _previous_run(setup, out)
    other = _other_data(setup, tmp_path)
    cfg = _config(tmp_path / "c.toml", setup, out, data=f'path = "{other}"', scan="checkpoint = false",
                  alternatives="fit = false")
    with Unchanged(out, other, *_inputs(setup)):
        assert main(["-q", "scan", str(cfg)]) == 2
    err = capsys.readouterr().err
    assert "holds the results of a run on other data" in err and "--overwrite" in err and err.count("\n") == 1
    assert main(["-q", "scan", "--overwrite", str(cfg)]) == 0
    vis = load_visibilities(other).standardised()
    assert ScanResult.load(out / "scan.h5").provenance["data_hash"] == data_hash(vis.u, vis.v, vis.V, vis.weights)


def test_the_same_data_may_be_scanned_again_into_its_folder(setup, tmp_path):
    from spiralbayes.pipeline.outputs import check_output_folder

    out = tmp_path / "out"
    _previous_run(setup, out)
    check_output_folder(out, setup.result.provenance["data_hash"])  # a rerun: accepted
    check_output_folder(tmp_path / "new", "0" * 16)  # no scan.h5: accepted
    with pytest.raises(InputError, match="run on other data"):
        check_output_folder(out, "0" * 16)
    check_output_folder(out, "0" * 16, overwrite=True)


# --- the notebook's first arguments ----------------------------------------------------------------
@pytest.mark.parametrize("case,match", [
    ("name", r"templates = 'wake_m1_tau3_b10_R' \(a str\): pass a TemplateBank or a list of SpiralTemplate"),
    ("none_item", r"templates\[0\] = None \(a NoneType\) is not a SpiralTemplate"),
    ("path_vis", (r"vis = '.*obs.h5' \(a str\) is a file name, not visibilities: load it first, "
                  r"vis = sb.load_visibilities\('.*obs.h5'\)")),
    ("none_model", r"axisymmetric = None \(a NoneType\): pass the disc's axisymmetric model"),
    ("none_templates", r"templates = None: pass a TemplateBank"),
])
def test_scan_names_the_argument_of_the_wrong_kind(setup, case, match):
    import spiralbayes as sb

    args = {"vis": setup.vis, "axisymmetric": setup.model, "templates": setup.templates[:1]}
    args.update({"name": {"templates": "wake_m1_tau3_b10_R"}, "none_item": {"templates": [None]},
                 "path_vis": {"vis": str(setup.files.data)}, "none_model": {"axisymmetric": None},
                 "none_templates": {"templates": None}}[case])
    with pytest.raises(InputError, match=match) as info:
        sb.scan(args["vis"], args["axisymmetric"], args["templates"], progress=False, **GRID)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("value,match", [
    (None, r"scan_result = None \(a NoneType\) is not a scan result: pass the ScanResult returned by sb.scan"),
    ("scan.h5", r"scan_result = 'scan.h5' \(a str\) is a file name: load it first, ScanResult.load\('scan.h5'\)"),
    ({"cross": 1}, r"is not a scan result"),
])
def test_detect_names_the_argument_of_the_wrong_kind(value, match):
    import spiralbayes as sb

    with pytest.raises(InputError, match=match):
        sb.detect(value)


# --- nonsense numbers -------------------------------------------------------------------------------
@pytest.mark.parametrize("change,match", [
    ({"brightness": "nan"}, r"SpiralTemplate.brightness contains NaN or inf"),
    ({"mass": float("inf")}, r"SpiralTemplate.mass = inf must be positive and finite"),
    ({"mass": -1.0}, r"SpiralTemplate.mass = -1.0 must be positive"),
    ({"tau0": 0.0}, r"SpiralTemplate.tau0 = 0.0 must be positive"),
    ({"beta": float("-inf")}, r"SpiralTemplate.beta = -inf must be >= 0"),
    ({"h_p": float("nan")}, r"SpiralTemplate.h_p = nan must be positive and finite"),
    ({"wavelength": 0.0}, r"SpiralTemplate.wavelength = 0.0 must be positive and finite \(in metres"),
])
def test_template_metadata_must_be_finite(setup, change, match):
    from spiralbayes.templates.template import SpiralTemplate

    t = setup.templates[2]
    fields = {"x": t.x, "phi": t.phi, "delta": t.delta, "mass": t.mass, "tau0": t.tau0, "beta": t.beta,
              "hand": t.hand, "brightness": np.ones(t.delta.shape)}
    if change.get("brightness") == "nan":
        change = {"brightness": np.where(np.eye(*t.delta.shape, dtype=bool), np.nan, 1.0)}
    with pytest.raises(InputError, match=match):
        SpiralTemplate(**{**fields, **change})
    assert np.isnan(SpiralTemplate(**{**fields, "mass": float("nan")}).mass)  # NaN: unknown, as documented


def test_frank_refuses_two_visibilities_saying_how_many_it_needs(setup):
    from spiralbayes.axisymmetric import fit_axisymmetric
    from spiralbayes.io.data_checks import MIN_SEARCH_VISIBILITIES

    with pytest.raises(InputError, match=rf"only 2 visibilities: frank's profile needs at least "
                                         rf"{MIN_SEARCH_VISIBILITIES} .*flux can come out negative"):
        fit_axisymmetric(setup.vis.subset([0, 1]), GEOMETRY, progress=False)


def _table(path, vis, weight_format="%.10g"):
    """A uvtable with the weights in their own format (the others %.10g)."""
    rows = [f"{u:.10g} {v:.10g} {re:.10g} {im:.10g} {weight_format % w}"
            for u, v, re, im, w in zip(vis.u, vis.v, vis.V.real, vis.V.imag, vis.weights)]
    path.write_text("# wavelength[m] = 1.3e-3\n" + "\n".join(rows) + "\n")
    return path


@pytest.mark.parametrize("cut,match", [
    (lambda row: row[: row.rindex("e")] + "\n", r"column 5 \('[\d.]+'\) has no exponent where every row before has"),
    (lambda row: row[: row.rindex("e") + 2] + "\n", r"column 5 \('[\d.]+e-'\) ends inside its exponent"),
    (lambda row: row[: row.rindex("e") + 1] + "\n", r"column 5 \('[\d.]+e'\) ends inside its exponent"),
    (lambda row: row[: row.rindex(" ") - 4] + "\n", r"the last row has 4 numbers where the rows before have 5"),
])
def test_a_cut_last_row_ending_in_a_newline_is_refused_with_its_line(setup, tmp_path, cut, match):
    vis = setup.vis.with_weights(setup.vis.weights * 1e-9, "weights of order 1e-3")  # written as 4.000000e-03
    path = _table(tmp_path / "cut.txt", vis, "%.6e")
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(lines[:-1]) + cut(lines[-1].rstrip("\n")))
    with Unchanged(tmp_path), pytest.raises(InputError, match=rf"cut.txt, line {len(lines)}: .*{match}.*cut "
                                                               f"mid-number.*delete line {len(lines)}"):
        load_visibilities(path)


def test_a_weight_cut_inside_its_integer_digits_is_refused_with_a_newline(setup, tmp_path):
    vis = setup.vis.with_weights(np.linspace(29614.8, 31000.3, setup.vis.n), "float weights")
    path = _table(tmp_path / "cut.txt", vis)
    text = path.read_text()
    last = text.rstrip("\n").rsplit("\n", 1)[1]
    path.write_text(text[: len(text) - len(last) - 1] + last[: last.rindex(" ") + 5] + "\n")  # 31000.3 -> 3100
    with Unchanged(tmp_path), pytest.raises(InputError, match=r"column 5 \('3100'\) has fewer integer digits"):
        load_visibilities(path)
    whole = _table(tmp_path / "whole.txt", vis)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)  # these weights are not 1/sigma^2; only the cut matters here
        assert load_visibilities(whole).n == vis.n  # the same table uncut: accepted


def test_cli_axisym_of_other_data_into_a_fit_folder_is_refused(tmp_path, capsys):
    from spiralbayes._provenance import data_hash
    from spiralbayes.cli import main
    from spiralbayes.pipeline.outputs import check_output_folder

    from .test_faults_hostile import AS209, _table as write_table

    out = tmp_path / "fit"
    argv = ["-q", "axisym", "--inc", "34.97", "--pa", "85.76", "--out", str(out)]
    assert main([*argv[:2], str(AS209), *argv[2:]]) == 0
    vis = load_visibilities(AS209)
    check_output_folder(out, data_hash(vis.u, vis.v, vis.V, vis.weights), filename="axisym_model.h5")  # a rerun
    other = write_table(tmp_path / "other.txt", vis.with_weights(vis.weights * 2, "other"))
    capsys.readouterr()
    with Unchanged(out, other):
        assert main([*argv[:2], str(other), *argv[2:]]) == 2
    err = capsys.readouterr().err
    assert f"{out} holds the results of a run on other data (axisym_model.h5" in err
    assert "give another --out, or --overwrite" in err and err.count("\n") == 1


@pytest.mark.parametrize("command", [["demo"], ["limits", "--demo"]])
def test_demos_refuse_a_folder_holding_the_scan_of_real_data(setup, tmp_path, command, capsys, monkeypatch):
    import spiralbayes.pipeline as pipeline
    from spiralbayes.cli import main
    from spiralbayes.pipeline.outputs import SIMULATED_SOURCE, check_simulated_folder

    monkeypatch.setattr(pipeline, "run_demo", lambda *a, **k: pytest.fail("the demo must not run"))
    monkeypatch.setattr(pipeline, "run_limits_demo", lambda *a, **k: pytest.fail("the demo must not run"))
    out = tmp_path / "results"
    _previous_run(setup, out)
    with Unchanged(out):
        assert main(["-q", *command, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"--out {out} holds the scan of data the demo did not simulate" in err and "--overwrite" in err
    simulated = dataclasses.replace(setup.result, provenance={**setup.result.provenance,
                                                              "data": {"source": SIMULATED_SOURCE}})
    simulated.save(out / "scan.h5")
    check_simulated_folder(out)  # a demo's own folder: replaced
    check_simulated_folder(tmp_path / "new")
