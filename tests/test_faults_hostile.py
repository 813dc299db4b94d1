"""Hostile inputs, second pass (issue 23): each case gives a one-line error, a warning or the documented behaviour.

Every case that touches files snapshots the SHA-256 of every file in the output folder and of the
inputs before the call and compares after it: a refused input must not lose or overwrite anything.

Cases: output names that leave the output folder or overwrite another kind of result; stale
intermediate files (``axisymmetric.h5``, ``scan.h5``, checkpoints) from other data or settings;
nonsense data (duplicate rows, a cut last row, too few visibilities, degenerate uv coverage,
non-positive distance, no geometry); the posterior's inconclusive band and the scan verdict's
alternative; command-line papercuts. The data are the small synthetic observation of
:mod:`tests.test_faults` (3000 baselines, a Gaussian disc with a planted spiral, coarse grids).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from spiralbayes._provenance import data_hash
from spiralbayes.exceptions import ConfigError, DataWarning, InputError, ResumeMismatchError
from spiralbayes.inference.detection import detect
from spiralbayes.inference.posterior.results import PosteriorResult
from spiralbayes.inference.scan import ScanResult
from spiralbayes.io import load_visibilities
from spiralbayes.io.data_checks import MIN_SEARCH_VISIBILITIES

from .test_faults import GEOMETRY, GRID, _config, setup


def _hashes(*roots) -> dict:
    """SHA-256 of every file under each root (a file or a folder)."""
    out = {}
    for root in roots:
        root = Path(root)
        files = [root] if root.is_file() else sorted(p for p in root.rglob("*") if p.is_file())
        for path in files:
            out[str(path)] = hashlib.sha256(path.read_bytes()).hexdigest()
    return out


class Unchanged:
    """``with Unchanged(out, inputs...):`` asserts that no file under the roots changed, appeared or vanished."""

    def __init__(self, *roots):
        self.roots = roots

    def __enter__(self):
        self.before = _hashes(*self.roots)
        return self

    def __exit__(self, *exc):
        assert _hashes(*self.roots) == self.before
        return False


def _inputs(setup):
    return (setup.files.data, setup.files.model, setup.files.bank)


# --- 1. output names stay in the output folder; no result overwrites another kind ----------------
@pytest.mark.parametrize("name", ["../scan", "../../evil", "a/b", "..", ".hidden", "", "c:\\x", "x\ny"])
def test_run_names_that_leave_the_output_folder_are_refused(tmp_path, name):
    from spiralbayes.config import load_config

    cfg = tmp_path / "c.toml"
    cfg.write_text(f"[sample]\nrun_name = {json.dumps(name)}\n")  # a JSON string is a TOML basic string
    with Unchanged(tmp_path), pytest.raises(ConfigError, match="sample.run_name = .* must be a plain name"):
        load_config(cfg)


def test_sample_api_refuses_a_run_name_outside_the_chains_folder(setup, tmp_path):
    from spiralbayes.inference.posterior.sampler import sample_posterior

    out = tmp_path / "out"
    setup.result.save(out / "scan.h5")
    with Unchanged(out, *_inputs(setup)), pytest.raises(InputError, match="run_name = '../scan' must be a plain name"):
        sample_posterior(setup.vis, setup.model, setup.templates[:1], run_name="../scan", chains_dir=out / "chains",
                         progress=False)


def test_no_writer_overwrites_a_result_of_another_kind(setup, tmp_path):
    from spiralbayes.inference.posterior.chains import ChainStore

    scan_file = setup.result.save(tmp_path / "scan.h5")
    with Unchanged(tmp_path), pytest.raises(InputError, match=r"holds another kind of result "
                                                              r"\(spiralbayes.ScanResult\), refusing to overwrite it "
                                                              r"with a spiralbayes.PosteriorRun"):
        ChainStore(scan_file, "t").read()
    with Unchanged(tmp_path), pytest.raises(InputError, match="holds another kind of result"):
        setup.model.save(scan_file)
    assert setup.result.save(scan_file) == scan_file  # the same kind is replaced as before


# --- 2. stale intermediate files are reused only when made from the same inputs -----------------
def _fitted(model, vis):
    """``model`` as if frank had fitted it to ``vis`` (the data hash a fit records)."""
    return dataclasses.replace(model, provenance={**model.provenance,
                                                  "data_hash": data_hash(vis.u, vis.v, vis.V, vis.weights)})


def _other(vis):
    return vis.with_weights(vis.weights * 1.01, "other data")


def test_scan_api_refuses_a_model_fitted_to_other_data(setup):
    from spiralbayes.inference.scan import scan

    stale = _fitted(setup.model, _other(setup.vis))
    with pytest.raises(InputError, match="was fitted to other data .*allow_other_data=True"):
        scan(setup.vis, stale, setup.templates[:1], progress=False, **GRID)
    ok = scan(setup.vis, _fitted(setup.model, setup.vis), setup.templates[:1], progress=False, **GRID)
    forced = scan(setup.vis, stale, setup.templates[:1], progress=False, allow_other_data=True, **GRID)
    np.testing.assert_array_equal(ok.cross, forced.cross)  # the check decides nothing else


def _sample_config(tmp_path, setup, out, **sections):
    sections.setdefault("frank", "")  # no [frank] model: OUTPUT/axisymmetric.h5 or a fit
    return _config(tmp_path / "c.toml", setup, out, geometry="inc = 30.0\nPA = 60.0", **sections)


def test_sample_refuses_an_axisymmetric_model_left_by_a_run_on_other_data(setup, tmp_path):
    from spiralbayes.config import load_config
    from spiralbayes.pipeline import run_sample_config

    out = tmp_path / "out"
    _fitted(setup.model, _other(setup.vis)).save(out / "axisymmetric.h5")
    cfg = _sample_config(tmp_path, setup, out)
    with Unchanged(out, *_inputs(setup)), pytest.raises(ResumeMismatchError, match=r"axisymmetric.h5 was fitted for "
                                                         r"other inputs — the data \(hash"):
        run_sample_config(load_config(cfg), progress=False)


def test_sample_refuses_a_scan_of_other_data_or_geometry(setup, tmp_path):
    from spiralbayes.config import load_config
    from spiralbayes.pipeline import run_sample_config

    out = tmp_path / "out"
    _fitted(setup.model, setup.vis).save(out / "axisymmetric.h5")
    key = setup.result.provenance["resume_key"]
    dataclasses.replace(setup.result, provenance={**setup.result.provenance, "data_hash": "0" * 16,
                                                  "resume_key": {**key, "data": "0" * 16}}).save(out / "scan.h5")
    cfg = _sample_config(tmp_path, setup, out)
    with Unchanged(out, *_inputs(setup)), pytest.raises(ResumeMismatchError, match=r"scan.h5 was computed for other "
                                                         r"inputs — the data"):
        run_sample_config(load_config(cfg), progress=False)
    dataclasses.replace(setup.result, geometry=GEOMETRY.replace(inc=31.0)).save(out / "scan.h5")
    with Unchanged(out), pytest.raises(ResumeMismatchError, match=r"geometry \(inc: 31.0 -> 30.0\)"):
        run_sample_config(load_config(cfg), progress=False)


def test_limits_refuses_a_scan_of_other_data_or_templates_instead_of_relabelling_or_rescanning(setup, tmp_path,
                                                                                             monkeypatch):
    import spiralbayes.pipeline.limits as limits_module
    from spiralbayes.config import load_config

    monkeypatch.setattr(limits_module, "run_scan_config", lambda *a, **k: pytest.fail("must not rescan"))
    out = tmp_path / "out"
    _fitted(setup.model, setup.vis).save(out / "axisymmetric.h5")
    key = setup.result.provenance["resume_key"]
    dataclasses.replace(setup.result, provenance={**setup.result.provenance,
                                                  "resume_key": {**key, "data": "0" * 16}}).save(out / "scan.h5")
    cfg = _sample_config(tmp_path, setup, out)
    with Unchanged(out, *_inputs(setup)), pytest.raises(ResumeMismatchError, match="scan.h5 was computed for other "
                                                         "inputs — the data"):
        limits_module.run_limits_config(load_config(cfg), progress=False)
    setup.result.save(out / "scan.h5")
    cfg = _sample_config(tmp_path, setup, out, templates=f'bank = "{setup.files.bank}"\nmass = [0.3]')
    with Unchanged(out), pytest.raises(ResumeMismatchError, match=r"the templates \(names\)"):
        limits_module.run_limits_config(load_config(cfg), progress=False)


def test_force_resume_records_the_checkpoints_geometry_not_the_requested_one(setup, tmp_path):
    from spiralbayes.inference.scan import scan

    checkpoint = tmp_path / "checkpoint.h5"
    checkpoint.write_bytes(setup.checkpoint.read_bytes())  # complete, at inc = 30
    forced = scan(setup.vis, setup.model, setup.templates, GEOMETRY.replace(inc=31.0), checkpoint=checkpoint,
                  progress=False, force_resume=True, **GRID)
    record = forced.provenance["forced_resume"]
    assert forced.geometry.inc == 30.0 and record["requested"]["geometry"]["inc"] == 31.0
    assert forced.provenance["resume_key"] == setup.result.provenance["resume_key"]
    assert record["templates_from_checkpoint"] == [t.name for t in setup.templates]
    np.testing.assert_array_equal(forced.cross, setup.result.cross)


def test_cli_force_resume_says_so_in_config_used(setup, tmp_path):
    from spiralbayes.cli import main

    out = tmp_path / "out"
    out.mkdir()
    (out / "scan_checkpoint.h5").write_bytes(setup.checkpoint.read_bytes())
    cfg = _config(tmp_path / "c.toml", setup, out, alternatives="fit = false",
                  frank=f'model = "{setup.model.save(tmp_path / "m.h5")}"\nalpha = 1.3')
    refit = dataclasses.replace(setup.model, hyperparameters={**setup.model.hyperparameters, "alpha": 1.3})
    cfg = _config(tmp_path / "c.toml", setup, out, alternatives="fit = false",
                  frank=f'model = "{refit.save(tmp_path / "refit.h5")}"')
    assert main(["-q", "scan", "--force-resume", str(cfg)]) == 0
    assert (out / "config_used.toml").read_text().startswith("# FORCED RESUME (--force-resume)")
    assert ScanResult.load(out / "scan.h5").provenance["forced_resume"]["differences"]


# --- 3. nonsense data -----------------------------------------------------------------------------
def _table(path: Path, vis, rows=None) -> Path:
    """A uvtable of ``vis`` written with numpy (5 columns, %.10g)."""
    table = np.column_stack([vis.u, vis.v, vis.V.real, vis.V.imag, vis.weights])
    np.savetxt(path, table if rows is None else table[rows], fmt="%.10g", header="wavelength[m] = 1.3e-3")
    return path


def test_exactly_duplicated_rows_warn_with_the_count_and_the_fix(setup, tmp_path):
    path = _table(tmp_path / "twice.txt", setup.vis, np.r_[np.arange(setup.vis.n), np.arange(setup.vis.n)])
    with Unchanged(tmp_path), pytest.warns(DataWarning, match=f"{setup.vis.n} of {2 * setup.vis.n} rows repeat "
                                                                "another row exactly.*remove them"):
        load_visibilities(path)


def test_a_last_row_cut_mid_number_is_refused(setup, tmp_path):
    path = _table(tmp_path / "cut.txt", setup.vis)
    text = path.read_text()
    path.write_text(text[: len(text) - 6])  # cut inside the last weight
    with Unchanged(tmp_path), pytest.raises(InputError, match=r"line \d+: the last row's column 5 \('40'\) has fewer "
                                                               "integer digits.*cut mid-number"):
        load_visibilities(path)
    whole = _table(tmp_path / "whole.txt", setup.vis)
    whole.write_text(whole.read_text().rstrip("\n"))  # no final newline but nothing cut: accepted
    assert load_visibilities(whole).n == setup.vis.n


@pytest.mark.parametrize("case,match", [
    ("zero", "every baseline has u = v = 0"),
    ("line", "lie on one line through the origin"),
    ("one", "lie on one line through the origin"),
])
def test_degenerate_uv_coverage_is_refused_on_load(setup, tmp_path, case, match):
    vis = setup.vis
    if case == "zero":
        vis = dataclasses.replace(vis, u=0 * vis.u, v=0 * vis.v)
    elif case == "line":
        vis = dataclasses.replace(vis, v=0.5 * vis.u)
    else:
        vis = vis.subset([0])
    path = _table(tmp_path / "bad.txt", vis)
    with Unchanged(tmp_path), warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        with pytest.raises(InputError, match=match):
            load_visibilities(path)


def test_scan_refuses_too_few_visibilities_and_a_non_positive_distance(setup):
    from spiralbayes.inference.scan import scan

    for distance in (-1.0, 0.0, float("nan")):
        with pytest.raises(InputError, match="distance = .* must be a positive, finite distance in pc"):
            scan(setup.vis, setup.model, setup.templates[:1], distance=distance, progress=False, **GRID)
    few = setup.vis.subset(np.arange(MIN_SEARCH_VISIBILITIES - 1))
    with pytest.raises(InputError, match=f"only {MIN_SEARCH_VISIBILITIES - 1} visibilities: a search needs at least "
                                         f"{MIN_SEARCH_VISIBILITIES}"):
        scan(few, setup.model, setup.templates[:1], progress=False, **GRID)


def test_frank_with_fewer_visibilities_than_collocation_points_warns(setup):
    from spiralbayes.axisymmetric import fit_axisymmetric

    few = setup.vis.subset(np.argsort(np.hypot(setup.vis.u, setup.vis.v))[:60])  # the shortest baselines
    with pytest.warns(DataWarning, match="frank's N = 80 exceeds the 60 visibilities.*N = 0 in \\[frank\\]"):
        fit_axisymmetric(few, GEOMETRY, N=80, Rmax=1.2, progress=False, max_iter=20, convergence_failure="ignore")


def test_frank_that_does_not_converge_is_one_error_of_ours(setup):
    """Not a bare RuntimeError (the CLI printed a traceback): ConvergenceError naming what to check."""
    from spiralbayes.axisymmetric import fit_axisymmetric
    from spiralbayes.exceptions import ConvergenceError, SpiralbayesError

    with pytest.raises(ConvergenceError, match=r"max_iter = 3 iterations.*\[frank\] Rmax = 1.2 arcsec") as info:
        fit_axisymmetric(setup.vis, GEOMETRY, N=80, Rmax=1.2, progress=False, max_iter=3)
    assert isinstance(info.value, SpiralbayesError) and "\n" not in str(info.value)


def test_a_config_without_geometry_refuses_to_fit_frank_face_on(setup, tmp_path, monkeypatch):
    import spiralbayes.pipeline.inputs as inputs
    from spiralbayes.config import load_config
    from spiralbayes.pipeline import run_scan

    monkeypatch.setattr(inputs, "fit_axisymmetric", lambda *a, **k: pytest.fail("frank must not run"))
    out = tmp_path / "out"
    cfg = _config(tmp_path / "c.toml", setup, out, frank="")
    with Unchanged(tmp_path, *_inputs(setup)), pytest.raises(ConfigError, match=r"no \[geometry\] inc and PA.*fit = "
                                                                                  "true"):
        run_scan(load_config(cfg), progress=False)


def test_cli_axisym_without_inc_and_pa_refuses(setup, tmp_path, capsys):
    from spiralbayes.cli import main

    with Unchanged(tmp_path, *_inputs(setup)):
        assert main(["axisym", str(setup.files.data), "--out", str(tmp_path / "ax")]) == 2
    err = capsys.readouterr().err
    assert "give --inc and --pa [deg]" in err and "--fit-geometry" in err and err.count("\n") == 1


# --- 4. a coin flip is not a result ---------------------------------------------------------------
class _Posterior(PosteriorResult):
    """A PosteriorResult reduced to its Bayes factor (the verdict's only input on these branches)."""

    def __init__(self, ln_b: float, planet_prior: float = 0.5):
        self._ln_b, self.planet_prior, self.null = ln_b, planet_prior, object()
        self.alternative_runs = []  # planet against no planet only

    @property
    def ln_bayes_factor(self) -> float:
        return self._ln_b


@pytest.mark.parametrize("ln_b,expected", [
    (0.01, "inconclusive"),  # AS 209: P(planet | data) = 0.5035
    (-0.99, "inconclusive"),
    (0.99, "inconclusive"),
    (-1.01, "no planet preferred"),
    (-3.6, "no planet preferred"),  # P = 0.027, a planet-free dataset of docs/performance.md
])
def test_posterior_verdict_has_an_inconclusive_band_on_the_jeffreys_scale(ln_b, expected):
    post = _Posterior(ln_b)
    assert post.p_planet == pytest.approx(1 / (1 + np.exp(-ln_b)))  # prior odds 1
    assert post.verdict.startswith(expected + ":")
    assert not post.planet_preferred
    assert ("no planet position is reported" in post.verdict) is (expected == "inconclusive")
    assert post.inconclusive is (abs(ln_b) < 1)


def test_posterior_outside_the_band_with_p_above_half_prefers_the_planet():
    assert _Posterior(1.01).planet_preferred and not _Posterior(1.01).inconclusive
    assert not _Posterior(1.5, planet_prior=0.1).planet_preferred  # P(planet | data) = 0.29 < 0.5


def test_scan_verdict_names_an_alternative_only_when_it_beats_the_disc():
    from tests.inference.detection.test_verdict import N_DATA, compact_peak, fake_alternatives, fake_scan

    shape = (13, 90)
    weak = fake_scan(compact_peak(shape, 6, 10, 30.0), compact_peak(shape, 6, 80, 5.0))  # spiral Delta BIC -35.6
    lopsided = 30.0  # Delta BIC = 30 - 4 ln N = -11.9 against the disc: itself disfavoured
    verdict = detect(weak, alternatives=fake_alternatives(lopsided=lopsided, geometry=1.0))
    text = verdict.summary()
    assert verdict.alternative_delta_bic == pytest.approx(lopsided - 4 * np.log(N_DATA))
    assert verdict.delta_bic_vs_alternative < 0
    assert "explains the data better" not in text and "no competing asymmetry model explains the data" in text
    assert "rescan_at_fitted_geometry" not in text and not verdict.detected
    strong = detect(weak, alternatives=fake_alternatives(lopsided=200.0))  # Delta BIC 158: the explanation
    assert "the lopsided model explains the data better than any spiral template" in strong.summary()


# --- 5. papercuts ---------------------------------------------------------------------------------
def _bad_config(tmp_path) -> Path:
    cfg = tmp_path / "bad.toml"
    cfg.write_text("[grid]\nn_r_p = 5.5\n")
    return cfg


def test_debug_and_quiet_are_accepted_after_the_command(tmp_path, capsys):
    from spiralbayes.cli import main

    cfg = _bad_config(tmp_path)
    with pytest.raises(ConfigError):  # the traceback, as with --debug first
        main(["scan", str(cfg), "--debug"])
    assert main(["scan", str(cfg), "-q"]) == 2
    assert "(--debug shows the traceback)" in capsys.readouterr().err


@pytest.mark.parametrize("argv,attr,value", [
    (["simulate", "--out", "x.h5", "--dra", "-1.9e-3"], "dra", -1.9e-3),
    (["simulate", "--out", "x.h5", "--ddec", "-2E-3"], "ddec", -2e-3),
    (["simulate", "--out", "x.h5", "--planet-phi", "-30"], "planet_phi", -30.0),
    (["simulate", "--out", "x.h5", "--pa=-12.5"], "pa", -12.5),
])
def test_negative_numbers_are_values_not_options(argv, attr, value):
    from spiralbayes.cli import _join_negative_numbers, build_parser

    assert getattr(build_parser().parse_args(_join_negative_numbers(argv)), attr) == value


def test_presets_are_listed_and_help_shows_defaults(capsys):
    from spiralbayes.cli import main
    from spiralbayes.simulate import PRESETS

    with pytest.raises(SystemExit):
        main(["simulate", "--out", "x.h5", "--preset", "nonsense"])
    err = capsys.readouterr().err
    assert all(name in err for name in PRESETS)
    with pytest.raises(SystemExit):
        main(["forecast", "-h"])
    out = capsys.readouterr().out
    assert "(default: 0.9)" in out and "(default: 140.0)" in out and "taurus" in out


def test_probability_outside_zero_one_is_refused_before_anything_is_printed(capsys):
    from spiralbayes.cli import main

    with pytest.raises(SystemExit) as info:
        main(["forecast", "--probability", "1.5"])
    captured = capsys.readouterr()
    assert info.value.code == 2 and captured.out == ""
    assert "--probability: 1.5 is not a probability in (0, 1)" in captured.err


def test_forecast_text_uses_the_asked_probability_and_never_says_zero_minutes():
    from types import SimpleNamespace

    from spiralbayes.inference.limits.forecasting import Forecast, format_minutes

    times = {0.5: 0.3, 0.9: 95.0}
    stub = SimpleNamespace(r_p=0.357, distance=140.0, expected=np.array([2.0, 4.0]), template={"name": "t"},
                           setup={"name": "fiducial"}, time_on_source=40.0, n_data=100, threshold=lambda: 73.0,
                           probability=lambda: 0.5, time_for_probability=lambda p: times[p])
    assert "50 % needs < 1 min on source" in Forecast.summary(stub, 0.5)
    assert "90 % needs 95 min (1.6 h) on source" in Forecast.summary(stub, 0.9)
    assert format_minutes(float("inf")).startswith("not reachable") and format_minutes(12.4) == "12 min"


def test_posterior_summary_json_gives_phi_p_in_degrees_with_the_unit_in_the_key():
    from spiralbayes.pipeline.sample_command import _summary_with_units

    stats = {"phi_p": {"median": 0.5, "lo": 0.4, "hi": 0.6, "std": 0.05}, "r_p": {"median": 0.3}, "inc": {"median": 30}}
    out = _summary_with_units(stats)
    assert out["phi_p_deg"]["median"] == pytest.approx(0.5 * 180 / np.pi)
    assert out["phi_p_deg"]["std"] == pytest.approx(0.05 * 180 / np.pi)
    assert out["r_p_arcsec"] == {"median": 0.3} and out["inc_deg"] == {"median": 30}


def test_scan_file_datasets_carry_units(setup, tmp_path):
    import h5py

    with h5py.File(setup.result.save(tmp_path / "scan.h5"), "r") as f:
        units = {name: f[name].attrs["units"] for name in f if isinstance(f[name], h5py.Dataset)}
        assert set(f) - set(units) == {"geometry"}  # the one group: the DiscGeometry's fields
    assert units["r_p"] == "arcsec" and units["phi_p"] == "rad" and units["cross"].startswith("dimensionless")
    assert set(units) == {"r_p", "phi_p", "cross", "power", "cross_error", "power_error"}


def test_no_template_matches_shows_the_values_not_every_name():
    from spiralbayes.pipeline import select_templates
    from spiralbayes.templates import TemplateBank, make_template

    bank = TemplateBank([make_template(m, 3.0, 10.0, h, n_x=30, n_phi=48) for m in (0.3, 1.0) for h in "RL"])
    with pytest.raises(InputError) as info:
        select_templates(bank, mass=[99])
    text = str(info.value)
    assert "mass 0.3, 1; tau0 3; beta 10; hand L, R" in text and "wake_" not in text and len(text) < 300


def test_an_unreachable_dask_scheduler_is_reported_before_frank(setup, tmp_path, monkeypatch):
    import socket
    import time

    import spiralbayes.pipeline.inputs as inputs
    import spiralbayes.pipeline.scan_command as scan_command
    from spiralbayes.config import load_config

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    monkeypatch.setattr(inputs, "fit_axisymmetric", lambda *a, **k: pytest.fail("frank must not run"))
    monkeypatch.setattr(scan_command, "load_data", lambda *a, **k: pytest.fail("the data must not be read"))
    cfg = _config(tmp_path / "c.toml", setup, tmp_path / "out", frank="", geometry="inc = 30.0\nPA = 60.0",
                  scan=f'dask = "tcp://127.0.0.1:{port}"')
    t0 = time.monotonic()
    with Unchanged(tmp_path), pytest.raises(InputError, match=f"no Dask scheduler answers at 127.0.0.1:{port}"):
        scan_command.run_scan(load_config(cfg), progress=False)
    assert time.monotonic() - t0 < scan_command.DASK_CONNECT_TIMEOUT_S + 1


def test_compare_on_a_uvtable_without_wavelength_names_the_option_before_the_scan(setup, tmp_path, monkeypatch):
    import spiralbayes._casa as casa
    import spiralbayes.pipeline.compare as compare
    from spiralbayes.config import load_config

    monkeypatch.setattr(casa, "import_casa", lambda: None)  # as if CASA were installed
    monkeypatch.setattr(compare, "run_scan_config", lambda *a, **k: pytest.fail("must fail before the scan"))
    table = tmp_path / "obs.txt"
    vis = setup.vis
    np.savetxt(table, np.column_stack([vis.u, vis.v, vis.V.real, vis.V.imag, vis.weights]), fmt="%.10g")
    cfg = _config(tmp_path / "c.toml", setup, tmp_path / "out", data=f'path = "{table}"')
    with Unchanged(tmp_path), pytest.raises(ConfigError, match=r"set \[data\] wavelength = <metres>"):
        compare.run_compare_config(load_config(cfg), progress=False)


def test_chi2_vs_rp_explains_chi2_sa_and_keeps_the_mirror_visible(setup):
    from spiralbayes.plotting.scan import plot_chi2_vs_rp

    ax = plot_chi2_vs_rp(setup.result).axes[0]
    assert "spiral vs axisymmetric" in ax.get_ylabel()
    styles = {line.get_label(): (line.get_linestyle(), line.get_linewidth()) for line in ax.get_lines()}
    for meta in setup.result.templates:
        ls, lw = styles[meta["name"]]
        assert (ls, lw > 2) == (("--", False) if meta["hand"] == "L" else ("-", True))


AS209 = Path(__file__).parent / "data" / "AS209_DSHARP_subsample_uvtable.txt"


def test_frank_failures_name_our_options_and_print_no_array_or_source_line(capsys):
    """frank prints its whole power spectrum, warns from ``return np.exp(tau)`` and names ``rout``, ``n``."""
    from spiralbayes.axisymmetric import fit_axisymmetric

    vis = load_visibilities(AS209)
    geometry = GEOMETRY.replace(inc=34.97, PA=85.76)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(InputError, match=r"frank's power spectrum became NaN/inf fitting 196 visibilities.*"
                                             r"\[frank\] Rmax = 1.2 arcsec .*p0 = 1e\+10 Jy\^2") as info:
            fit_axisymmetric(vis, geometry, p0=1e10, progress=False)
    assert capsys.readouterr().out == ""  # frank's print(p)
    assert not [w for w in caught if "overflow" in str(w.message)]
    assert "rout" not in str(info.value) and "`n`" not in str(info.value)
    assert "antenna gain errors" in str(info.value)  # miscalibrated data fail this way too


def test_cli_errors_and_warnings_are_single_lines_of_ours(tmp_path):
    """Through the real command: the DataWarning and frank's failure as one line each, nothing on stdout."""
    import os
    import subprocess
    import sys

    # weights 1e12 too large: a DataWarning, then frank fails: its power spectrum overflows, or (with other
    # numpy/BLAS builds) it does not converge; either is one line of ours naming the settings
    table = tmp_path / "heavy.txt"
    vis = load_visibilities(AS209)
    _table(table, vis.with_weights(vis.weights * 1e12, "heavy"))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(__file__).parents[1] / "src"),
                                                        os.environ.get("PYTHONPATH", "")])}
    with Unchanged(tmp_path):
        done = subprocess.run([sys.executable, "-m", "spiralbayes.cli", "-q", "axisym", str(table), "--inc", "35",
                               "--pa", "86", "--out", str(tmp_path / "fit")], capture_output=True, text=True, env=env,
                              timeout=300)
    lines = done.stderr.splitlines()
    assert done.returncode == 2 and done.stdout == ""
    assert [line.split(":")[:2] for line in lines] == [["spiralbayes", " warning"], ["spiralbayes", " error"]]
    assert "DataWarning: " in lines[0] and "estimate_weights = true" in lines[0]
    assert "[frank] Rmax = 1.2 arcsec" in lines[1]
    assert not any(word in done.stderr for word in ("rout", "`n`", "np.exp", "return ", "load_visibilities("))


def test_the_sample_run_reports_its_overall_progress(tmp_path, caplog):
    """Table builds and optimisation took 10 of 12 minutes without a word: every stage now says k/N."""
    import logging

    from tests._support import faults_sampling_job as job

    with caplog.at_level(logging.INFO, logger="spiralbayes.inference.posterior.sampler"):
        job.run(tmp_path)
    stages = [r.getMessage() for r in caplog.records if r.getMessage().startswith("posterior ")]
    assert [s.split(":")[0] for s in stages] == ["posterior 1/3", "posterior 2/3", "posterior 3/3"]
    assert stages[0].startswith("posterior 1/3: no planet") and "min so far" in stages[0]
    assert "wake_" in stages[1] and "tables, optimum, chain" in stages[1]  # the template given a chain
    assert "Laplace evidence" in stages[2]  # its mirror: Laplace only
    assert any(r.getMessage().startswith("posterior: 3 stages done in") for r in caplog.records)


@pytest.mark.slow
def test_the_readme_posterior_on_as209_is_not_called_a_planet(tmp_path):
    """The README's notebook and posterior calls on the AS 209 sample (196 visibilities): before, "planet
    preferred: P(planet | data) = 0.5035, ln B = 0.01". Chains shortened to 16 walkers x 100 steps (the
    evidences come from importance sampling). Measured with these settings: "inconclusive: P(planet | data) =
    0.602, ln B(planet : none) = 0.41", 44 min wall at load average ~12 on 2 cores (8 templates)."""
    import spiralbayes as sb

    vis = sb.load_visibilities(AS209)
    disc = sb.fit_axisymmetric(vis, sb.DiscGeometry(inc=34.97, PA=85.76, dRA=-1.9e-3, dDec=2.5e-3), progress=False)
    templates = sb.default_bank().select(tau0=3, beta=10, h_p=0.07)
    result = sb.scan(vis, disc, templates, r_p=np.linspace(0.02, 0.5, 25), distance=121, progress=False)
    post = sb.sample_posterior(vis, disc, templates, scan=result, chains_dir=tmp_path,
                               priors=sb.Priors.default(disc, widths={"dRA": 0.02, "dDec": 0.02}),
                               n_steps=100, n_walkers=16, convergence="ignore", progress=False)
    assert not post.planet_preferred, post.verdict
    assert post.verdict.startswith(("inconclusive:", "no planet preferred:")), post.verdict
    assert "r_p =" not in post.verdict  # no position quoted
