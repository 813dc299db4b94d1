"""The spiralbayes command: simulate -> scan from a config, and argument/config errors."""

from __future__ import annotations

from dataclasses import replace
import json
import warnings

import pytest

from spiralbayes.cli import main
from spiralbayes.templates import make_template
from tests._support.helpers import DATA


def test_print_config_is_loadable(capsys, tmp_path):
    from spiralbayes.config import default_config, load_config

    assert main(["scan", "--print-config"]) == 0
    path = tmp_path / "c.toml"
    path.write_text(capsys.readouterr().out)
    expected = default_config()
    expected["output"]["dir"] = str(tmp_path / "spiralbayes-output")
    assert load_config(path) == expected


def test_simulate_then_scan_from_config(tmp_path, capsys):
    from spiralbayes.io import load_visibilities
    from spiralbayes.templates import TemplateBank

    data = tmp_path / "obs.txt"
    assert main(["-q", "simulate", "--preset", "taurus", "--out", str(data), "--planet-mass", "3",
                 "--tau0", "0.3", "--beta", "10", "--planet-au", "60", "--planet-phi", "90", "--seed", "4"]) == 0
    vis = load_visibilities(data)
    assert vis.n > 5000 and vis.wavelength == pytest.approx(1.33e-3)
    right = make_template(3.0, 0.3, 10.0, "R", n_x=120, n_phi=360)
    TemplateBank([right, right.mirror()]).save(tmp_path / "bank.h5")
    config = tmp_path / "run.toml"
    config.write_text(f"""
[data]
path = "obs.txt"
[geometry]
inc = 30.0
PA = 60.0
[templates]
bank = "{tmp_path / 'bank.h5'}"
[grid]
r_p_min = 0.1
r_p_max = 0.7
n_r_p = 7
n_phi_p = 30
[output]
dir = "{tmp_path / 'out'}"
""")
    assert main(["-q", "scan", str(config)]) == 0
    out = tmp_path / "out"
    verdict = json.loads((out / "verdict.json").read_text())
    assert verdict["template"].endswith("_R") and verdict["test1_passed"]
    assert abs(verdict["r_p"] - 60 / 140) <= 0.1 + 1e-9
    assert (out / "scan.h5").exists() and (out / "config_used.toml").exists()
    assert list(out.glob("heatmap_*.png"))
    # test 3: the competing asymmetry models are fitted, scored and drawn beside the spiral
    assert verdict["test3_passed"] in (True, False) and verdict["best_alternative"] in verdict["alternatives"]
    assert (out / "alternatives.h5").exists() and (out / "residual_comparison.png").exists()
    assert "Test 3" in capsys.readouterr().out


def test_errors_are_reported_not_raised(tmp_path, capsys):
    config = tmp_path / "run.toml"
    config.write_text("[grid]\nbogus = 1\n")
    assert main(["scan", str(config)]) == 2
    assert "unknown option grid.bogus" in capsys.readouterr().err
    assert main(["scan"]) == 2
    assert "scan needs a CONFIG file" in capsys.readouterr().err


def test_axisym_on_real_as209_sample(tmp_path):

    from spiralbayes.axisymmetric import AxisymmetricModel

    data = DATA / "AS209_DSHARP_subsample_uvtable.txt"
    out = tmp_path / "fit"
    code = main(["-q", "axisym", str(data), "--inc", "34.97", "--pa", "85.76", "--dra=-1.9e-3",
                 "--ddec", "2.5e-3", "--distance", "121", "--out", str(out)])
    assert code == 0
    model = AxisymmetricModel.load(next(out.glob("*.h5")))
    assert model.geometry.inc == 34.97 and 50 < model.N < 200  # sparse data: N follows the longest baseline
    assert 0.1 < model.total_flux < 1.0  # AS 209 at 1.25 mm: about 0.25 Jy
    assert len(list(out.glob("*.png"))) == 2


def test_cli_sample_from_toml_config(setup, tmp_path):
    """`spiralbayes sample CONFIG` writes chains under OUT/chains/<run_name>.h5 and a summary."""
    import json

    from spiralbayes.cli import main
    from spiralbayes.io import save_visibilities
    from spiralbayes.templates import TemplateBank

    from spiralbayes.axisymmetric import AxisymmetricModel
    from tests._support.posterior_setup import profile

    save_visibilities(setup["vis"], tmp_path / "obs.h5")
    AxisymmetricModel.from_profile(profile, setup["model"].geometry, N=80).save(tmp_path / "axisym.h5")
    template = setup["template"]
    TemplateBank([template, template.mirror()]).save(tmp_path / "bank.h5")
    (tmp_path / "run.toml").write_text(
        '[data]\npath = "obs.h5"\n[frank]\nmodel = "axisym.h5"\n[templates]\nbank = "bank.h5"\n'
        '[sample]\nrun_name = "cli"\nn_walkers = 16\nn_steps = 40\nconvergence = "ignore"\nevidence_draws = 200\n'
        f'mcmc_templates = ["{template.name}"]\n'
        "[priors]\nr_p_min = 0.3\nr_p_max = 0.4\ninc_sigma = 3.0\nPA_sigma = 3.0\n"
        "dRA_sigma = 0.03\ndDec_sigma = 0.03\n"
        f'[output]\ndir = "{tmp_path / "out"}"\n')
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["-q", "sample", str(tmp_path / "run.toml")]) == 0
    assert (tmp_path / "out" / "chains" / "cli.h5").exists()
    summary = json.loads((tmp_path / "out" / "cli_summary.json").read_text())
    assert "summary" in summary and summary["verdict"].startswith("planet preferred")
    assert 0.99 < summary["p_planet"] <= 1.0 and summary["null"]["ln_evidence"] < summary["runs"][0]["ln_evidence"]
    assert (tmp_path / "out" / "cli_corner.png").exists() and (tmp_path / "out" / "cli_hypotheses.png").exists()
    (tmp_path / "bad.toml").write_text('[data]\npath = "obs.h5"\n[sample]\nbogus = 1\n')
    assert main(["sample", str(tmp_path / "bad.toml")]) == 2


def test_limits_from_config_reuses_the_scan_and_writes_table3(tmp_path, capsys, limits_case):
    """`spiralbayes limits CONFIG` after `scan`: limits.h5, completeness, Table 3 (md, csv) and plots."""
    from spiralbayes.inference.limits.exclusion import ExclusionLimits
    from spiralbayes.io import save_visibilities
    from spiralbayes.templates import TemplateBank
    from tests._support import limits_setup

    vis, model, templates, result = limits_case
    save_visibilities(vis, tmp_path / "obs.h5")
    model.save(tmp_path / "axisym.h5")
    TemplateBank(templates).save(tmp_path / "bank.h5")
    out = tmp_path / "out"
    out.mkdir()
    result.save(out / "scan.h5")
    model.save(out / "axisymmetric.h5")
    r = limits_setup.R_P
    (tmp_path / "run.toml").write_text(
        '[data]\npath = "obs.h5"\n[frank]\nmodel = "axisym.h5"\n[templates]\nbank = "bank.h5"\n'
        f"[grid]\nr_p_min = {r[0]}\nr_p_max = {r[-1]}\nn_r_p = {r.size}\nn_phi_p = {limits_setup.N_PHI}\n"
        '[limits]\nn_azimuths = 2\nname = "test disc"\nresolution = 0.2\n'
        f'[output]\ndir = "{out}"\n')
    assert main(["-q", "limits", str(tmp_path / "run.toml")]) == 0
    printed = capsys.readouterr().out
    assert "test disc" in printed and "tau0=0.3, beta=10, h_p=0.07" in printed
    for name in ("limits.h5", "table3.md", "table3.ecsv", "limits_summary.txt", "config_used_limits.toml"):
        assert (out / name).exists(), name
    assert len(list(out.glob("completeness_*.h5"))) == 1 and len(list(out.glob("mass_radius_*.png"))) == 1
    limits = ExclusionLimits.load(out / "limits.h5")
    assert limits.flags[0] == "unresolved" and limits.cl == 0.95
    assert "near_planet" not in limits.flags.tolist()
    # the scan's verdict.json beside scan.h5: radii near its planet and its significant asymmetry
    # models are flagged, not excluded; an older verdict.json belongs to another scan and is ignored
    import os

    for verdict, flag in (({"test1_passed": True, "r_p": float(r[-1])}, "near_planet"),
                          ({"test1_passed": False, "r_p": float(r[-1]), "alternatives": {"arc": {
                              "delta_bic": 30.0, "params": {"r_c": float(r[2]), "sigma_r": 0.01}}}}, "near_asymmetry")):
        (out / "verdict.json").write_text(json.dumps(verdict))
        assert main(["-q", "limits", str(tmp_path / "run.toml")]) == 0
        flags = ExclusionLimits.load(out / "limits.h5").flags.tolist()
        assert flags == ["unresolved"] + [flag] * 3, flags  # every resolved radius lies within the 0.2" beam
    stale = (out / "scan.h5").stat().st_mtime - 60
    os.utime(out / "verdict.json", (stale, stale))
    assert main(["-q", "limits", str(tmp_path / "run.toml")]) == 0
    assert "near_planet" not in ExclusionLimits.load(out / "limits.h5").flags.tolist()
    (tmp_path / "bad.toml").write_text('[data]\npath = "obs.h5"\n[limits]\ncl = 1.5\n'
                                       f'[templates]\nbank = "bank.h5"\n[output]\ndir = "{out}"\n'
                                       f"[grid]\nr_p_min = {r[0]}\nr_p_max = {r[-1]}\nn_r_p = {r.size}\n"
                                       f"n_phi_p = {limits_setup.N_PHI}\n")
    capsys.readouterr()
    assert main(["limits", str(tmp_path / "bad.toml")]) == 2
    assert "limits.cl = 1.5 must be a confidence level" in capsys.readouterr().err


def test_forecast_command(capsys):
    assert main(["-q", "forecast", "--preset", "taurus", "--mass", "1", "--tau0", "0.3", "--beta", "10",
                 "--r-au", "50", "--probability", "0.5"]) == 0
    out = capsys.readouterr().out
    assert "P(ΔBIC > 10)" in out and "50 % needs" in out and "90 %" not in out and " 0 min" not in out
    with pytest.raises(SystemExit) as info:  # argparse lists the presets
        main(["forecast", "--preset", "nowhere"])
    assert info.value.code == 2 and "taurus" in capsys.readouterr().err


# --- conventions: --version, exit status 2, help everywhere, options checked in the user's units ---
def _parsers():
    """(name, parser) of the top-level parser and of every sub-command."""
    import argparse

    from spiralbayes.cli import build_parser

    top = build_parser()
    out = [("spiralbayes", top)]
    for action in top._actions:
        if isinstance(action, argparse._SubParsersAction):
            out += sorted(action.choices.items())
    return out


def test_every_positional_and_option_has_help_and_options_show_their_default():
    import argparse

    parsers = _parsers()
    assert {name for name, _ in parsers} >= {"demo", "simulate", "axisym", "scan", "sample", "compare", "limits",
                                            "survey", "forecast", "templates"}
    for name, parser in parsers:
        for action in parser._actions:
            if action.help is argparse.SUPPRESS or isinstance(action, argparse._SubParsersAction):
                continue
            label = f"{name} {action.option_strings or action.dest}"
            assert action.help and action.help.strip(), f"{label} has no help"
            shown = action.default not in (None, False, "", argparse.SUPPRESS) and action.option_strings
            assert not shown or "%(default)" in action.help, f"{label} does not show its default"


def test_version_prints_the_package_version(capsys):
    from spiralbayes._version import __version__

    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0 and capsys.readouterr().out.strip() == f"spiralbayes {__version__}"


@pytest.mark.parametrize("argv", [["scan"], ["sample"], ["compare"], ["limits"], ["survey"],
                                  ["scan", "missing.toml"], ["limits", "missing.toml"], ["survey", "missing.toml"],
                                  ["axisym", "missing.txt", "--inc", "30", "--pa", "60"]])
def test_every_user_error_exits_2_with_one_line(argv, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("spiralbayes: error: ") and err.count("\n") == 1, err


@pytest.mark.parametrize("argv,expected", [
    (["forecast", "--inc=-5"], "argument --inc: -5 is outside [0, 90) deg"),
    (["forecast", "--inc", "90"], "argument --inc: 90 is outside [0, 90) deg"),
    (["forecast", "--r-au", "-50"], "argument --r-au: -50 must be > 0"),
    (["forecast", "--distance", "0"], "argument --distance: 0 must be > 0"),
    (["forecast", "--mass", "nan"], "argument --mass: nan is not a finite number"),
    (["simulate", "--out", "x.txt", "--planet-au", "abc"], "argument --planet-au: 'abc' is not a number"),
    (["simulate", "--out", "x.txt", "--seed", "-1"], "argument --seed: -1 must be >= 0"),
    (["axisym", "d.txt", "--inc=-5", "--pa", "60"], "argument --inc: -5 is outside [0, 90) deg"),
    (["survey", "--demo", "--workers", "0"], "argument --workers: 0 must be >= 1"),
])
def test_bad_options_are_named_as_typed_in_the_users_units(argv, expected, capsys):
    with pytest.raises(SystemExit) as info:
        main(argv)
    captured = capsys.readouterr()
    assert info.value.code == 2 and captured.out == ""
    assert expected in captured.err and captured.err.count("\n") == 1, captured.err
    assert "DiscGeometry" not in captured.err and "arcsec" not in captured.err


def test_distance_defaults_come_from_the_settings():
    from spiralbayes.cli import build_parser
    from spiralbayes.settings import DEFAULT_DISTANCE_PC

    parser = build_parser()
    assert parser.parse_args(["forecast"]).distance == DEFAULT_DISTANCE_PC
    assert parser.parse_args(["simulate", "--out", "x.txt"]).distance == DEFAULT_DISTANCE_PC


def test_dask_is_a_hidden_alias_of_scheduler(monkeypatch, capsys):
    import argparse

    import spiralbayes.cli as cli

    parser = cli.build_parser()
    assert parser.parse_args(["demo", "--scheduler", "local"]).scheduler == "local"
    args = parser.parse_args(["demo", "--dask", "tcp://h:1"])
    with pytest.warns(FutureWarning, match="--dask is renamed --scheduler"):
        assert cli._scheduler(args) == "tcp://h:1"
    assert cli._scheduler(argparse.Namespace(scheduler="serial", dask_alias=None)) == "serial"
    with pytest.raises(SystemExit):
        main(["demo", "-h"])
    assert "--dask" not in capsys.readouterr().out


def test_verbose_raises_only_spiralbayes_log_level(monkeypatch):
    import logging

    import spiralbayes.cli as cli

    seen = {}

    def probe(args):
        seen["ours"] = logging.getLogger("spiralbayes.inference").getEffectiveLevel()
        seen["matplotlib"] = logging.getLogger("matplotlib.font_manager").getEffectiveLevel()
        return 0

    before = logging.getLogger("spiralbayes").level
    parser = cli.build_parser
    monkeypatch.setattr(cli, "build_parser", lambda: _with_func(parser(), "forecast", probe))
    assert cli.main(["-v", "forecast"]) == 0
    assert seen["ours"] == logging.DEBUG and seen["matplotlib"] > logging.DEBUG
    assert logging.getLogger("spiralbayes").level == before  # restored for the next caller in this process


def _with_func(parser, command, func):
    import argparse

    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            action.choices[command].set_defaults(func=func)
    return parser


@pytest.mark.parametrize("argv,expected", [(["--scheduler", "serial"], "serial"), ([], None),
                                           (["--scheduler", "local"], "local"), (["--dask", "local"], "local")])
def test_demo_hands_its_scheduler_to_the_scan(argv, expected, monkeypatch, tmp_path):
    import spiralbayes.pipeline as pipeline
    from spiralbayes.exceptions import InputError

    seen = {}

    def fake_demo(out, **kwargs):
        seen.update(kwargs)
        raise InputError("stopped before the demo")

    monkeypatch.setattr(pipeline, "run_demo", fake_demo)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert main(["-q", "demo", "--out", str(tmp_path / "demo"), *argv]) == 2
    assert seen["scheduler"] == expected
    assert any(issubclass(w.category, FutureWarning) for w in caught) is ("--dask" in argv)


@pytest.mark.parametrize("failed,status", [([], 0), (["Damaged"], 1)])
def test_survey_with_failed_discs_exits_non_zero_after_writing_its_table(failed, status, monkeypatch, tmp_path,
                                                                        capsys):
    import spiralbayes.pipeline.survey as survey
    from spiralbayes.pipeline.survey.run import SurveyRun

    table = tmp_path / "survey_table.md"
    table.write_text("| disc | status |\n|---|---|\n| A | ok |\n")
    rows = [{"disc": "A", "status": "ok"}] + [{"disc": name, "status": "failed"} for name in failed]
    run = SurveyRun(None, rows, [tmp_path / "survey_table.ecsv", table], "serial")
    monkeypatch.setattr(survey, "run_survey", lambda *args, **kwargs: run)
    config = tmp_path / "s.toml"
    config.write_text("")
    assert main(["-q", "survey", str(config)]) == status
    out, err = capsys.readouterr()
    assert "| A | ok |" in out and str(table) in out  # the table is printed and listed either way
    assert ("Damaged" in err) == bool(failed)


def test_the_tests_line_names_test_3_as_the_verdict_decided_it():
    from spiralbayes.cli import tests_line
    from tests.inference.detection.test_mass_range import scan_of

    from spiralbayes.inference.detection import detect

    plain = detect(scan_of())
    assert tests_line(plain).endswith("test 3 (competing asymmetry models): not run; outcome: detected")
    assert "test 1 (Delta BIC > 10): pass; test 2 (handedness and compactness): pass" in tests_line(plain)
    nested = replace(plain, test3_method="nested", nested_delta_bic=12.34, nested_threshold=30.0, test3_passed=False,
                     detected=False)
    assert tests_line(nested).endswith("(a spiral in addition to the best competing asymmetry models, nested "
                                       "Delta BIC 12.3 > 30): fail; outcome: not detected")
    assert tests_line(replace(nested, compact_source={"r": 0.36})).endswith("outcome: candidate")
    single = replace(plain, test3_method="best model", test3_passed=True, alternative_threshold=10.0)
    assert tests_line(single).endswith("(the spiral beats the best competing asymmetry model by > 10): pass; "
                                       "outcome: detected")
