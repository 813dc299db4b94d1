"""The configuration schema: defaults, documentation round trip, rejection of bad input."""

import numpy as np
import pytest

from spiralbayes.config import (
    SCHEMA,
    default_config,
    describe_config,
    load_config,
    merge_config,
)
from spiralbayes.exceptions import ConfigError, InputError


def test_described_defaults_read_back_as_defaults(tmp_path):
    path = tmp_path / "default.toml"
    path.write_text(describe_config())
    expected = default_config()
    expected["output"]["dir"] = str(tmp_path / "spiralbayes-output")  # relative to the file, as every path
    assert load_config(path) == expected


def test_paper_defaults():
    cfg = default_config()
    assert (cfg["frank"]["N"], cfg["frank"]["Rmax"], cfg["frank"]["alpha"]) == (0, 1.2, 1.05)  # 0: automatic
    assert (cfg["frank"]["p0"], cfg["frank"]["weights_smooth"]) == (1e-15, 0.1)
    # 0 bounds: the data-driven grid of ScanSettings (25 radii up to 0.6 R_eff), the one sb.scan uses
    grid = cfg["grid"]
    assert (grid["r_p_min"], grid["r_p_max"], grid["n_r_p"], grid["n_phi_p"]) == (0, 0, 25, 90)
    assert all(desc for section in SCHEMA.values() for _, desc in section.values())


def test_relative_data_path_is_relative_to_the_config(tmp_path):
    (tmp_path / "sub").mkdir()
    path = tmp_path / "sub" / "run.toml"
    path.write_text('[data]\npath = "disc.txt"\n[grid]\nn_r_p = 5\n')
    cfg = load_config(path)
    assert cfg["data"]["path"] == str(tmp_path / "sub" / "disc.txt")
    assert cfg["grid"]["n_r_p"] == 5 and cfg["grid"]["n_phi_p"] == 90


@pytest.mark.parametrize("user,match", [
    ({"dat": {}}, r"unknown config section \[dat\]"),
    ({"grid": {"nrp": 3}}, r"unknown option grid.nrp.*n_r_p"),
    ({"grid": {"n_r_p": "many"}}, "grid.n_r_p must be a number"),
    ({"data": {"conjugated": 1}}, "data.conjugated must be true or false"),
])
def test_bad_configuration_is_refused(user, match):
    with pytest.raises(ValueError, match=match):
        merge_config(user)


@pytest.mark.parametrize("user,match", [
    ({"templates": {"bank": "learned"}}, r"bank = 'learned' needs \[templates\] learned_model.*--fit-learned"),
    ({"templates": {"slope": [1.0]}}, r"templates.slope = \[1.0\] is read only with bank = 'learned'"),
    ({"templates": {"bank": "learned", "learned_model": "m.h5", "alpha": [0.0]}}, r"templates.alpha .* element 0.0"),
    ({"templates": {"bank": "learned", "learned_model": "m.h5", "orbits": ["old"]}}, "templates.orbits .*numbers"),
])
def test_learned_bank_options_are_checked(user, match):
    """The learned bank's options: a model file is required, they are refused with another bank, and
    each value is checked (α and ages > 0)."""
    with pytest.raises(ValueError, match=match):
        merge_config(user)


def test_missing_and_invalid_files(tmp_path):
    with pytest.raises(FileNotFoundError, match="--print-config"):
        load_config(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[grid\n")
    with pytest.raises(ValueError, match="not valid TOML"):
        load_config(bad)


def test_every_default_passes_its_value_check():
    from spiralbayes.config import CHECKS

    for section, checks in CHECKS.items():
        for key, check in checks.items():
            if key in SCHEMA.get(section, {}):
                assert check(SCHEMA[section][key][0]) is None, f"default of {section}.{key} fails its check"


@pytest.mark.parametrize("user,match", [
    ({"alternatives": {"models": ["vortex"]}}, r"alternatives.models .* 'arc'"),
    ({"alternatives": {"n_starts": 0}}, "alternatives.n_starts = 0 must be an integer >= 1"),
])
def test_bad_alternatives_options_are_refused(user, match):
    with pytest.raises(ValueError, match=match):
        merge_config(user)
    merged = merge_config({"alternatives": {"models": ["geometry", "arc"], "n_starts": 3}})
    assert merged["alternatives"]["n_starts"] == 3


def test_without_tomllib_the_config_is_read_with_tomli(tmp_path):
    """Python 3.10 has no tomllib: the reader falls back to tomli (stood in for here by tomllib itself)."""
    import subprocess
    import sys

    config = tmp_path / "run.toml"
    config.write_text("[grid]\nn_phi_p = 46\n")
    code = ("import sys, tomllib, types\n"
            "tomli = types.ModuleType('tomli'); tomli.loads = tomllib.loads; tomli.TOMLDecodeError = "
            "tomllib.TOMLDecodeError\n"
            "sys.modules['tomli'] = tomli; sys.modules['tomllib'] = None\n"
            "from spiralbayes.config import load_config, tomllib as used\n"
            f"assert used is tomli, used\nprint(load_config({str(config)!r})['grid']['n_phi_p'])\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split()[-1] == "46"


@pytest.mark.parametrize("name, robust", [("default", True), ("variants", True), ("compromise", False)])
def test_built_in_banks_are_names_not_paths(tmp_path, monkeypatch, name, robust):
    """``[templates] bank = "default"`` (and its alias ``"variants"``) loads the morphology-robust
    bank, ``"compromise"`` the single-morphology one; each stays a name (not resolved against the
    file) and is selected like any bank."""
    from spiralbayes.config import load_config
    from spiralbayes.pipeline import inputs
    from spiralbayes.templates import TemplateBank
    from spiralbayes.templates.variants import variant_template

    path = tmp_path / "c.toml"
    path.write_text(f'[data]\npath = "d.txt"\n[geometry]\ninc = 30\nPA = 60\n[templates]\nbank = "{name}"\n'
                    'mass = [1.0]\n')
    config = load_config(path)
    assert config["templates"]["bank"] == name
    small = {v: TemplateBank([variant_template(m, 0.3, 0.0, "R", v, h_p=0.07, n_x=60, n_phi=90)
                              for m in (0.3, 1.0)]) for v in ("compromise", "hydro")}
    robust_bank = TemplateBank([*small["compromise"], *small["hydro"]])
    monkeypatch.setitem(inputs.BANKS, "default", lambda: robust_bank)
    monkeypatch.setitem(inputs.BANKS, "variants", lambda: robust_bank)
    monkeypatch.setitem(inputs.BANKS, "compromise", lambda: small["compromise"])
    chosen = sorted(t.name for t in inputs.load_templates(config["templates"]))
    expected = ["hydro_m1_tau0.3_b0_h0.07_R", "wake_m1_tau0.3_b0_h0.07_R"] if robust else ["wake_m1_tau0.3_b0_h0.07_R"]
    assert chosen == expected


def test_aspect_ratios_the_built_in_bank_lacks_make_it_at_them(tmp_path, monkeypatch):
    """``[templates] h_p`` values outside the built-in bank's 0.05, 0.07, 0.10 make that bank at
    exactly those aspect ratios (the generator's templates at H/r 0.0625 and 0.075, the variants'
    constants as in the cached bank); values it holds select from it; a bank file is only selected."""
    from spiralbayes.config import load_config
    from spiralbayes.pipeline import inputs
    from spiralbayes.templates import TemplateBank
    from spiralbayes.templates.variants import default_bank, variant_template

    path = tmp_path / "c.toml"
    path.write_text('[data]\npath = "d.txt"\n[geometry]\ninc = 30\nPA = 60\n[templates]\nmass = [1.0]\n'
                    'tau0 = [3.0]\nbeta = [10.0]\nhand = ["R"]\nh_p = [0.0625, 0.075]\n')
    config = load_config(path)
    cache = tmp_path / "cache"
    monkeypatch.setitem(inputs.BANKS, "default", lambda **kw: default_bank(cache_dir=cache, **kw))
    chosen = inputs.load_templates(config["templates"])
    assert sorted(t.name for t in chosen) == sorted(f"{v}_m1_tau3_b10_h{h:g}_R" for v in ("wake", "hydro", "wakeflow")
                                                    for h in (0.0625, 0.075))
    exact = variant_template(1.0, 3.0, 10.0, "R", "hydro", h_p=0.075)
    made = next(t for t in chosen if t.name.startswith("hydro") and t.h_p == 0.075)
    np.testing.assert_allclose(made.delta, exact.delta, rtol=1e-6, atol=1e-6)
    # a bank file holding other aspect ratios is only selected from
    small = TemplateBank([variant_template(1.0, 3.0, 10.0, "R", "compromise", h_p=0.07, n_x=60, n_phi=90)])
    small.save(tmp_path / "bank.h5")
    section = dict(config["templates"], bank=str(tmp_path / "bank.h5"))
    with pytest.raises(InputError, match="h_p=\\[0.0625, 0.075\\]"):
        inputs.load_templates(section)


def test_maps_files_are_scanned_beside_the_bank(tmp_path, monkeypatch):
    """``[templates] maps``: TemplateBank files of simulated maps, resolved against the configuration's
    folder, selected by mass, τ0, β and hand (not H/r: a simulation has its own), appended to the bank;
    a name already in the scan is refused with the file and the fix."""
    import dataclasses

    from spiralbayes.config import load_config
    from spiralbayes.pipeline import inputs
    from spiralbayes.templates import TemplateBank, make_template

    def sim(mass, tau0, h_p, name):  # a stand-in for read_fargo3d's maps: no generator in the provenance
        t = make_template(mass, tau0, 0.0, "R", h_p=h_p, n_x=60, n_phi=90)
        return dataclasses.replace(t, name=name, provenance={"reader": "test"})

    TemplateBank([sim(1.0, 0.3, 0.06, "runA_R"), sim(1.0, 3.0, 0.06, "runA_tau3_R"),
                  sim(3.0, 0.3, 0.06, "runB_R")]).save(tmp_path / "maps" / "runs.h5")
    path = tmp_path / "c.toml"
    path.write_text('[data]\npath = "d.txt"\n[geometry]\ninc = 30\nPA = 60\n[templates]\nmass = [1.0]\n'
                    'tau0 = [0.3]\nh_p = [0.07]\nmaps = ["maps/runs.h5"]\n')
    config = load_config(path)
    assert config["templates"]["maps"] == [str(tmp_path / "maps" / "runs.h5")]
    bank = TemplateBank([make_template(m, 0.3, 0.0, h, h_p=0.07, n_x=60, n_phi=90) for m in (1.0, 3.0) for h in "RL"])
    monkeypatch.setitem(inputs.BANKS, "default", lambda: bank)
    chosen = [t.name for t in inputs.load_templates(config["templates"])]
    assert chosen == ["wake_m1_tau0.3_b0_h0.07_R", "wake_m1_tau0.3_b0_h0.07_L", "runA_R"]
    TemplateBank([sim(1.0, 0.3, 0.06, "wake_m1_tau0.3_b0_h0.07_R")]).save(tmp_path / "clash.h5")
    section = dict(config["templates"], maps=[str(tmp_path / "clash.h5")])
    with pytest.raises(InputError, match="clash.h5.*already in the scan.*rename"):
        inputs.load_templates(section)
    # a second run of the same mass, tau0, beta and H/r (another viscosity, say): one place in one family
    TemplateBank([sim(1.0, 0.3, 0.06, "runC_R")]).save(tmp_path / "twin.h5")
    section = dict(config["templates"], maps=[str(tmp_path / "maps" / "runs.h5"), str(tmp_path / "twin.h5")])
    with pytest.raises(InputError, match=r"\[templates\] maps: templates 'runA_R' and 'runC_R'.*variant"):
        inputs.load_templates(section)
    with pytest.raises(ConfigError, match="maps"):
        path.write_text('[data]\npath = "d.txt"\n[geometry]\ninc = 30\nPA = 60\n[templates]\nmaps = [3]\n')
        load_config(path)


def test_templates_without_options_use_the_robust_default_bank():
    """A configuration that says nothing about templates gets the morphology-robust bank."""
    from spiralbayes.config import BUILT_IN_BANKS, default_config
    from spiralbayes.pipeline import inputs
    from spiralbayes.templates import compromise_bank, default_bank

    section = default_config()["templates"]
    # every built-in name is a bank of its own but "learned", which a saved model makes (learned_templates)
    assert section["bank"] == "default" and set(BUILT_IN_BANKS) == set(inputs.BANKS) | {"learned"}
    assert inputs.BANKS[section["bank"]] is default_bank and inputs.BANKS["compromise"] is compromise_bank


# --- [grid] and [scan]: the fields of ScanSettings ------------------------------------------------
def test_grid_and_scan_sections_are_the_fields_of_scan_settings():
    import dataclasses

    from spiralbayes import ScanSettings
    from spiralbayes.pipeline.scan_command import scan_settings

    fields = {f.name: f for f in dataclasses.fields(ScanSettings)}
    assert set(SCHEMA["grid"]) | set(SCHEMA["scan"]) == set(fields) | {"scheduler"}
    for section in ("grid", "scan"):
        for key, (default, doc) in SCHEMA[section].items():
            if key != "scheduler":
                assert doc == fields[key].metadata["doc"]
                assert default == (0 if fields[key].default is None else fields[key].default), key
    assert scan_settings(default_config()) == ScanSettings()  # TOML's 0 bounds read back as automatic (None)
    given = merge_config({"grid": {"r_p_min": 0.02, "r_p_max": 0.5, "n_phi_p": 46},
                          "scan": {"quadrature": "midpoint", "nthreads": 2, "building_blocks": False}})
    assert scan_settings(given) == ScanSettings(r_p_min=0.02, r_p_max=0.5, n_phi_p=46, quadrature="midpoint",
                                                nthreads=2, building_blocks=False)


@pytest.mark.parametrize("user,match", [
    ({"grid": {"n_phi_p": 45}}, r"grid.n_phi_p = 45 must be a positive, even integer"),
    ({"grid": {"r_p_max": -0.5}}, r"grid.r_p_max = -0.5 must be a positive, finite number"),
    ({"grid": {"r_p_min": 0.4, "r_p_max": 0.3}}, r"grid.r_p_min = 0.4 must be smaller than grid.r_p_max = 0.3"),
    ({"scan": {"quadrature": "simpson"}}, r"scan.quadrature = 'simpson' must be one of 'product', 'midpoint'"),
    ({"scan": {"power_path": "fast"}}, r"scan.power_path = 'fast' must be one of 'auto', 'polar', 'direct'"),
    ({"scan": {"nthreads": 0}}, r"scan.nthreads = 0 must be an integer >= 1"),
    ({"scan": {"dask": "local", "scheduler": "local"}}, r"scan.dask is the old name of scan.scheduler"),
])
def test_bad_grid_and_scan_values_name_the_option(user, match):
    with pytest.raises(ValueError, match=match):
        merge_config(user)


@pytest.mark.parametrize("user,match", [
    ({"sample": {"n_walkers": 5}}, r"sample.n_walkers = 5: emcee needs at least 2 x 6 = 12 walkers"),
    ({"sample": {"max_steps": 0}}, r"sample.max_steps = 0 must be an integer >= 1"),
    ({"sample": {"run_name": "../x"}}, r"sample.run_name = '../x' must be a plain name"),
    ({"frank": {"N": 1}}, r"frank.N = 1 must be None \(0 in a configuration file: automatic\) or an integer >= 2"),
    ({"frank": {"alpha": 0.5}}, r"frank.alpha = 0.5: .* alpha >= 1"),
    ({"priors": {"r_p_min": 0.5, "r_p_max": 0.3}}, r"priors.r_p_min = 0.5 must be smaller than r_p_max = 0.3"),
    ({"priors": {"inc_sigma": -1.0}}, r"priors.inc_sigma = -1.0 must be a positive width \[deg\]"),
    ({"priors": {"amplitude_max": -2.0}}, r"priors.amplitude_max = -2.0"),
    ({"limits": {"cl": 1.5}}, r"limits.cl = 1.5 must be a confidence level in \(0.5, 1\)"),
    ({"limits": {"thresholds": [3, -1]}}, r"limits.thresholds = \(3, -1\) must be a list of positive planet masses"),
    ({"limits": {"inject_hand": ["X"]}}, r"limits.inject_hand = \('X',\) must be a non-empty list of 'R' and/or 'L'"),
    ({"alternatives": {"threshold": float("nan")}}, r"alternatives.threshold = nan must be a finite number"),
])
def test_settings_sections_are_checked_by_their_dataclass(user, match):
    with pytest.raises(ValueError, match=match):
        merge_config(user)


def test_only_one_bound_may_be_automatic():
    cfg = merge_config({"grid": {"r_p_min": 0.3}})  # r_p_max automatic: checked against the data's R_eff later
    assert (cfg["grid"]["r_p_min"], cfg["grid"]["r_p_max"]) == (0.3, 0.0)
    assert merge_config({"grid": {"r_p_max": 0.1}})["grid"]["r_p_max"] == 0.1


def test_old_dask_key_is_read_as_scheduler_with_a_future_warning():
    with pytest.warns(FutureWarning, match=r"scan.dask is renamed scan.scheduler"):
        cfg = merge_config({"scan": {"dask": "local"}})
    assert cfg["scan"]["scheduler"] == "local" and "dask" not in cfg["scan"]


def test_a_distance_beyond_the_galaxy_is_refused():
    """1e9 pc (a unit slip) would put planets at 1e8 au; the limit is MAX_DISTANCE_PC."""
    with pytest.raises(ValueError, match=r"geometry.distance = 1000000000.0 must be a distance in pc between 1 "
                                         r"and 10000 \(e.g. 140 for Taurus\)"):
        merge_config({"geometry": {"distance": 1e9}})
    assert merge_config({"geometry": {"distance": 400}})["geometry"]["distance"] == 400.0


def test_defaults_and_sentinels_of_settings_sections_pass():
    config = merge_config({"priors": {"r_p_min": 0.0, "amplitude_max": 0.0}, "frank": {"N": 0},
                           "sample": {"n_steps": 0, "n_walkers": 12}})
    assert (config["priors"]["r_p_min"], config["frank"]["N"], config["sample"]["n_walkers"]) == (0.0, 0, 12)


def test_sample_config_is_refused_before_the_data_are_read(tmp_path, monkeypatch, capsys):
    """``[sample] n_walkers = 5`` stops ``spiralbayes sample`` when the file is read: no data file is opened."""
    from spiralbayes import io
    from spiralbayes.cli import main
    from spiralbayes.pipeline import inputs

    def no_reading(*args, **kwargs):
        raise AssertionError("the data were read before the configuration was checked")

    monkeypatch.setattr(inputs, "load_visibilities", no_reading)
    monkeypatch.setattr(io, "load_visibilities", no_reading)
    data = tmp_path / "disc.txt"
    data.write_text("# u v Re Im w\n1 2 3 4 5\n")
    config = tmp_path / "run.toml"
    config.write_text('[data]\npath = "disc.txt"\n[geometry]\ninc = 30\nPA = 60\n[sample]\nn_walkers = 5\n')
    assert main(["-q", "sample", str(config)]) == 2
    err = capsys.readouterr().err
    assert "sample.n_walkers = 5" in err and "12 walkers" in err
    assert not (tmp_path / "spiralbayes-output").exists()
