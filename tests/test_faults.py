"""Fault injection: what a hostile user (or a crash) does to spiralbayes, and what it must answer.

Each case of issue 12 is one test here: a scan killed with SIGKILL resumes bit for bit; truncated
and corrupted files fail with one line naming the file; a checkpoint for other inputs is refused
(naming what changed) unless forced; each bad configuration value is refused naming the option;
u, v in metres and non-statistical weights are caught on load; a FARGO3D-like template (unknown
beta) can be detected and the verdict is strict JSON; the command line prints user errors as one
line; outputs follow the umask.

Everything runs on one small synthetic observation: 3000 random baselines at 1.3 mm, a Gaussian
disc of known profile (no frank fit) with a planted spiral, templates on coarse grids.
"""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from spiralbayes import DiscGeometry
from spiralbayes.axisymmetric import AxisymmetricModel
from spiralbayes.exceptions import (
    ConfigError,
    DataFileError,
    DataWarning,
    InputError,
    MissingDependencyError,
    ResumeMismatchError,
)
from spiralbayes.inference.detection.verdict import detect, mirror_index
from spiralbayes.inference.scan.run import ScanResult, scan
from spiralbayes.io import load_visibilities, save_visibilities
from spiralbayes.model import perturbation_visibilities
from spiralbayes.templates import TemplateBank, make_template
from spiralbayes.visibilities import Visibilities

GEOMETRY = DiscGeometry(30.0, 60.0)
WAVELENGTH = 1.3e-3  # m
SIGMA = 5e-4  # Jy, noise of Re and Im
R_P, PHI_P = 0.35, 0.0  # the planted planet [arcsec, rad]
GRID = dict(r_p=np.linspace(0.15, 0.45, 4), n_phi_p=16)


def _profile(r):
    return 1e10 * np.exp(-0.5 * (np.asarray(r) / 0.3) ** 2)  # Jy/sr


def _fargo_like(template):
    """A template as read from a FARGO3D run: the cooling time is unknown (NaN)."""
    return dataclasses.replace(template, beta=float("nan"), name="fargo_m1_R")


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    """Data with a spiral planted by a FARGO3D-like template, the true disc model, four templates,
    and a reference scan with its checkpoint (files in a module-wide folder)."""
    folder = tmp_path_factory.mktemp("faults")
    rng = np.random.default_rng(5)
    n = 3000
    q = 10 ** rng.uniform(np.log10(2e4), np.log10(1.2e6), n)
    theta = rng.uniform(0, 2 * np.pi, n)
    u, v = q * np.cos(theta), q * np.sin(theta)
    model = AxisymmetricModel.from_profile(_profile, GEOMETRY, N=100, Rmax=1.2)
    model = dataclasses.replace(model, hyperparameters={**model.hyperparameters, "alpha": 1.05, "p0": 1e-15})
    fargo = _fargo_like(make_template(1.0, 1.0, 10.0, "R", n_x=60, n_phi=96))
    light = make_template(0.3, 1.0, 10.0, "R", n_x=60, n_phi=96)
    templates = [fargo, fargo.mirror(), light, light.mirror()]
    V = model.visibilities(u, v) + perturbation_visibilities(u, v, GEOMETRY, model.brightness, fargo, R_P, PHI_P)
    V = V + SIGMA * (rng.normal(size=n) + 1j * rng.normal(size=n))
    vis = Visibilities(u, v, V, np.full(n, SIGMA ** -2), wavelength=WAVELENGTH)
    files = SimpleNamespace(data=save_visibilities(vis, folder / "obs.h5"), model=model.save(folder / "axisym.h5"),
                            bank=TemplateBank(templates).save(folder / "bank.h5"))
    checkpoint = folder / "checkpoint.h5"
    result = scan(vis, model, templates, checkpoint=checkpoint, progress=False, **GRID)
    return SimpleNamespace(folder=folder, vis=vis, model=model, templates=templates, files=files,
                           checkpoint=checkpoint, result=result)


def _config(path: Path, setup, out: Path, **sections) -> Path:
    """A scan configuration for the module's files (``sections`` adds/overrides TOML lines)."""
    base = {
        "data": f'path = "{setup.files.data}"',
        "frank": f'model = "{setup.files.model}"',
        "templates": f'bank = "{setup.files.bank}"',
        "grid": "r_p_min = 0.15\nr_p_max = 0.45\nn_r_p = 4\nn_phi_p = 16",
        "output": f'dir = "{out}"\nplots = false',
    }
    base.update(sections)
    path.write_text("\n".join(f"[{name}]\n{body}" for name, body in base.items()) + "\n")
    return path


# --- kill -9 and resume ---------------------------------------------------------------------------
DRIVER = """
import sys, time
import spiralbayes.inference.scan.run as scan_module
real = scan_module.scan_template

def slow(context, template):  # leaves time to kill the process between two checkpoints
    time.sleep(float(sys.argv[2]))
    return real(context, template)

scan_module.scan_template = slow
from spiralbayes.cli import main
sys.exit(main(["-q", "scan", sys.argv[1]]))
"""


def test_scan_killed_with_sigkill_resumes_bitwise(setup, tmp_path, monkeypatch):
    import spiralbayes.inference.scan.run as scan_module
    from spiralbayes.cli import main

    killed_cfg = _config(tmp_path / "killed.toml", setup, tmp_path / "killed")
    (tmp_path / "driver.py").write_text(DRIVER)
    proc = subprocess.Popen([sys.executable, str(tmp_path / "driver.py"), str(killed_cfg), "1.5"], cwd=tmp_path,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    checkpoint = tmp_path / "killed" / "scan_checkpoint.h5"
    done, deadline = 0, time.monotonic() + 90
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            if checkpoint.exists():
                done = int(ScanResult.load(checkpoint).completed.sum())
                if done >= 1:
                    os.kill(proc.pid, signal.SIGKILL)
                    break
            time.sleep(0.05)
    finally:
        if proc.poll() is None and done == 0:
            proc.kill()
        proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL, proc.stderr.read().decode()[-2000:]
    done = int(ScanResult.load(checkpoint).completed.sum())  # what the kill left
    assert 1 <= done < len(setup.templates)

    real, calls = scan_module.scan_template, []
    monkeypatch.setattr(scan_module, "scan_template", lambda c, t: calls.append(t.name) or real(c, t))
    assert main(["-q", "scan", str(killed_cfg)]) == 0
    assert len(calls) == len(setup.templates) - done  # only the missing templates were computed
    resumed = ScanResult.load(tmp_path / "killed" / "scan.h5")

    assert main(["-q", "scan", str(_config(tmp_path / "ref.toml", setup, tmp_path / "ref"))]) == 0
    reference = ScanResult.load(tmp_path / "ref" / "scan.h5")
    assert resumed.completed.all()
    np.testing.assert_array_equal(resumed.cross, reference.cross)  # bit for bit
    np.testing.assert_array_equal(resumed.power, reference.power)


# --- truncated and corrupt files ------------------------------------------------------------------
def _readers(setup):
    """(file, dataset holding bulk data, loader) for each kind of HDF5 file spiralbayes reads."""
    return {
        "visibilities": (setup.files.data, "V", load_visibilities),
        "checkpoint": (setup.checkpoint, "cross", ScanResult.load),
        "axisymmetric": (setup.files.model, "I", AxisymmetricModel.load),
        "bank": (setup.files.bank, "templates/fargo_m1_R/delta", TemplateBank.load),
    }


def _damage(src: Path, dst: Path, how: str, dataset: str) -> None:
    import h5py

    data = bytearray(src.read_bytes())
    if how == "truncated":
        data = data[: len(data) * 2 // 3]
    elif how == "garbage":
        data = bytearray(np.random.default_rng(0).integers(0, 256, 4096, dtype=np.uint8).tobytes())
    else:  # flip bytes inside the dataset's raw data: only its checksum can tell
        with h5py.File(src, "r") as f:
            chunk = f[dataset].id.get_chunk_info(0)
        start = chunk.byte_offset + chunk.size // 2
        data[start:start + 8] = bytes(255 - b for b in data[start:start + 8])
    dst.write_bytes(bytes(data))


@pytest.mark.parametrize("kind", ["visibilities", "checkpoint", "axisymmetric", "bank"])
@pytest.mark.parametrize("how", ["truncated", "corrupted", "garbage"])
def test_damaged_files_raise_one_line_naming_the_file(setup, tmp_path, kind, how):
    src, dataset, load = _readers(setup)[kind]
    damaged = tmp_path / f"damaged{src.suffix}"
    _damage(src, damaged, how, dataset)
    with pytest.raises(DataFileError) as info:
        load(damaged)
    message = str(info.value)
    assert str(damaged) in message and "\n" not in message
    assert "re-create" in message or "delete" in message


def test_corrupt_checkpoint_fails_before_the_slow_steps(setup, tmp_path):
    from spiralbayes.config import load_config
    from spiralbayes.pipeline import run_scan_config

    out = tmp_path / "out"
    out.mkdir()
    _damage(setup.checkpoint, out / "scan_checkpoint.h5", "truncated", "")
    cfg = _config(tmp_path / "c.toml", setup, out, data='path = "missing.h5"')  # would fail later
    with pytest.raises(DataFileError, match="scan_checkpoint.h5 is not a readable HDF5 scan result"):
        run_scan_config(load_config(cfg), progress=False)


# --- changed settings on resume -------------------------------------------------------------------
def _scaled(template, factor):
    return dataclasses.replace(template, delta=template.delta * factor)


@pytest.mark.parametrize("change,expected", [
    ("frank_N", r"the axisymmetric model's profile; frank settings \(N: 100 -> 80\)"),
    ("frank_alpha", r"frank settings \(alpha: 1.05 -> 1.3\)"),
    ("rule", r"quadrature settings \(cell_factor: None -> 20.0, rule: 'product' -> 'midpoint'\)"),
    ("templates", r"templates \(changed: fargo_m1_R\)"),
    ("geometry", r"geometry \(inc: 30.0 -> 31.0\)"),
    ("data", r"the data \(u, v, V or weights\)"),
])
def test_changed_settings_on_resume_are_refused(setup, tmp_path, change, expected):
    checkpoint = tmp_path / "checkpoint.h5"
    checkpoint.write_bytes(setup.checkpoint.read_bytes())
    vis, model, templates, kwargs = setup.vis, setup.model, list(setup.templates), dict(GRID)
    if change == "frank_N":
        model = AxisymmetricModel.from_profile(_profile, GEOMETRY, N=80, Rmax=1.2)
        model = dataclasses.replace(model, hyperparameters={**model.hyperparameters, "alpha": 1.05, "p0": 1e-15})
    elif change == "frank_alpha":
        model = dataclasses.replace(model, hyperparameters={**model.hyperparameters, "alpha": 1.3})
    elif change == "rule":
        kwargs["rule"] = "midpoint"
    elif change == "templates":
        templates[0] = _scaled(templates[0], 1.01)
    elif change == "geometry":
        kwargs["geometry"] = GEOMETRY.replace(inc=31.0)
    else:
        vis = vis.with_weights(vis.weights * 1.01, "changed")
    with pytest.raises(ResumeMismatchError, match=expected) as info:
        scan(vis, model, templates, checkpoint=checkpoint, progress=False, **kwargs)
    assert "--force-resume" in str(info.value) and "\n" not in str(info.value)


def test_force_resume_keeps_the_completed_templates(setup, tmp_path, monkeypatch):
    import spiralbayes.inference.scan.run as scan_module

    checkpoint = tmp_path / "checkpoint.h5"
    checkpoint.write_bytes(setup.checkpoint.read_bytes())
    model = dataclasses.replace(setup.model, hyperparameters={**setup.model.hyperparameters, "alpha": 1.3})
    monkeypatch.setattr(scan_module, "scan_template", lambda *a: pytest.fail("nothing should be recomputed"))
    forced = scan(setup.vis, model, setup.templates, checkpoint=checkpoint, progress=False, force_resume=True,
                  **GRID)
    np.testing.assert_array_equal(forced.cross, setup.result.cross)
    assert "alpha" in forced.provenance["forced_resume"]["differences"][0]
    with pytest.raises(ResumeMismatchError, match="cannot be force-resumed: its planet grid differs"):
        scan(setup.vis, model, setup.templates, checkpoint=checkpoint, progress=False, force_resume=True,
             r_p=[0.2, 0.3], n_phi_p=16)


def test_cli_refuses_a_stale_checkpoint_and_force_resume_overrides(setup, tmp_path, capsys, monkeypatch):
    """Issue 12, item 1: new frank settings used to resume the old model's terms silently."""
    import spiralbayes.inference.scan.run as scan_module
    from spiralbayes.cli import main

    out = tmp_path / "out"
    out.mkdir()
    (out / "scan_checkpoint.h5").write_bytes(setup.checkpoint.read_bytes())  # complete, for alpha = 1.05
    refit = dataclasses.replace(setup.model, hyperparameters={**setup.model.hyperparameters, "alpha": 1.3})
    cfg = _config(tmp_path / "c.toml", setup, out, frank=f'model = "{refit.save(tmp_path / "refit.h5")}"')
    assert main(["-q", "scan", str(cfg)]) == 2
    err = capsys.readouterr().err
    assert "frank settings (alpha: 1.05 -> 1.3)" in err and "--force-resume" in err
    assert not (out / "config_used.toml").exists()  # nothing claims the new settings were used
    monkeypatch.setattr(scan_module, "scan_template", lambda *a: pytest.fail("nothing should be recomputed"))
    assert main(["-q", "scan", "--force-resume", str(cfg)]) == 0
    assert ScanResult.load(out / "scan.h5").provenance["forced_resume"]["differences"]


# --- configuration values -------------------------------------------------------------------------
@pytest.mark.parametrize("section,line,field", [
    ("scan", 'amplitude = "maybe"', "scan.amplitude = 'maybe' must be one of 'fixed', 'free'"),
    ("grid", "n_r_p = 5.5", "grid.n_r_p must be an integer"),
    ("grid", "n_r_p = 0", "grid.n_r_p = 0 must be an integer >= 1"),
    ("grid", "n_phi_p = 0", "grid.n_phi_p = 0 must be a positive, even integer"),
    ("grid", "n_phi_p = 45", "grid.n_phi_p = 45 must be a positive, even integer"),
    ("grid", "r_p_min = nan", "grid.r_p_min = nan must be a positive, finite number"),
    ("grid", "r_p_max = -0.5", "grid.r_p_max = -0.5 must be a positive"),
    ("grid", "r_p_min = 0.6\nr_p_max = 0.5", "grid.r_p_min = 0.6 must be smaller than grid.r_p_max"),
    ("frank", "alpha = 0.5", "frank.alpha = 0.5: frank's power-spectrum prior needs alpha >= 1"),
    ("frank", "N = 1", "frank.N = 1 must be None \\(0 in a configuration file: automatic\\) or an integer >= 2"),
    ("geometry", "inc = 95.0", r"geometry.inc = 95.0 must be an inclination in degrees in \[0, 90\)"),
    ("geometry", "distance = 0", "geometry.distance = 0.0 must be a distance in pc between 1 and 10000"),
    ("templates", 'hand = ["R", "X"]', "templates.hand = \\['R', 'X'\\] has element 'X'"),
    ("templates", "mass = [1, -3]", "templates.mass = \\[1, -3\\] has element -3"),
    ("data", 'uv_units = "furlongs"', "data.uv_units = 'furlongs' must be one of"),
    ("scan", "cell_factor = 0", "scan.cell_factor = 0.0 must be a positive"),
    ("scan", "nthreads = 0", "scan.nthreads = 0 must be an integer >= 1"),
    ("sample", 'convergence = "sometimes"', "sample.convergence = 'sometimes' must be one of"),
    ("priors", "inc_sigma = -1", "priors.inc_sigma = -1.0 must be a positive"),
])
def test_each_bad_config_value_is_refused_naming_the_field(tmp_path, section, line, field):
    from spiralbayes.config import load_config

    path = tmp_path / "bad.toml"
    path.write_text(f"[{section}]\n{line}\n")
    with pytest.raises(ConfigError, match=field) as info:
        load_config(path)
    assert str(info.value).startswith(str(path))


def test_every_config_path_resolves_against_the_config_file(tmp_path, monkeypatch):
    from spiralbayes.config import PATH_KEYS, load_config

    (tmp_path / "project").mkdir()
    cfg = tmp_path / "project" / "run.toml"
    cfg.write_text('[data]\npath = "obs.txt"\n[frank]\nmodel = "fit/axisym.h5"\n[templates]\nbank = "../bank.h5"\n'
                   '[sample]\nscan = "out/scan.h5"\n[output]\ndir = "out"\n')
    monkeypatch.chdir(tmp_path)  # elsewhere than the file
    config = load_config(Path("project") / "run.toml")
    expected = {("data", "path"): tmp_path / "project" / "obs.txt",
                ("frank", "model"): tmp_path / "project" / "fit" / "axisym.h5",
                ("templates", "bank"): tmp_path / "bank.h5",
                ("sample", "scan"): tmp_path / "project" / "out" / "scan.h5",
                ("output", "dir"): tmp_path / "project" / "out"}
    # the learned bank's model file is read only with bank = "learned", so it is checked in a file of its own
    assert set(expected) | {("templates", "learned_model")} == set(PATH_KEYS)
    for (section, key), path in expected.items():
        assert config[section][key] == str(path), (section, key)
    learned = tmp_path / "project" / "learned.toml"
    learned.write_text('[templates]\nbank = "learned"\nlearned_model = "models/lm.h5"\n')
    config = load_config(Path("project") / "learned.toml")
    assert config["templates"]["bank"] == "learned"
    assert config["templates"]["learned_model"] == str(tmp_path / "project" / "models" / "lm.h5")
    cfg.write_text('[templates]\nbank = "default"\n[output]\ndir = "~/sb-out"\n')
    config = load_config(cfg)
    assert config["templates"]["bank"] == "default"
    assert config["output"]["dir"] == str(Path("~/sb-out").expanduser())


# --- grids at the API -----------------------------------------------------------------------------
def test_bad_grids_are_refused_and_radii_beyond_rmax_warn(setup):
    vis, model, templates = setup.vis, setup.model, setup.templates[:1]
    with pytest.raises(InputError, match="r_p must be positive, finite radii"):
        scan(vis, model, templates, r_p=[0.2, np.nan], n_phi_p=16, progress=False)
    with pytest.raises(InputError, match="strictly increasing"):
        scan(vis, model, templates, r_p=[0.3, 0.2], n_phi_p=16, progress=False)
    for bad in (0, 15, 5.5, True):
        with pytest.raises(InputError, match="positive, even integer"):
            scan(vis, model, templates, r_p=[0.2], n_phi_p=bad, progress=False)
    with pytest.raises(InputError, match="cell_factor"):
        scan(vis, model, templates, r_p=[0.2], n_phi_p=16, cell_factor=float("nan"), progress=False)
    with pytest.warns(DataWarning, match="beyond frank's Rmax = 1.2 arcsec"):
        scan(vis, model, templates, r_p=[0.2, 1.3], n_phi_p=4, progress=False)


# --- units of u, v --------------------------------------------------------------------------------
def _uvtable(path: Path, u, v, header=""):
    n = len(u)
    rows = np.column_stack([u, v, np.ones(n), np.zeros(n), np.full(n, 1e4)])
    np.savetxt(path, rows, header=header)
    return path


def _alma_metres(n=2000, b_min=15.0, b_max=16e3, seed=1):
    """Baseline vectors [m] of a long-baseline configuration."""
    rng = np.random.default_rng(seed)
    b = 10 ** rng.uniform(np.log10(b_min), np.log10(b_max), n)
    angle = rng.uniform(0, 2 * np.pi, n)
    return b * np.cos(angle), b * np.sin(angle)


def test_metres_read_as_wavelengths_are_refused_when_clear_and_warned_when_ambiguous(tmp_path):
    from spiralbayes.io import read_uvtable

    um, vm = _alma_metres()
    stated = _uvtable(tmp_path / "stated.txt", um, vm, "wavelength[m] = 1.3e-3")  # metres, wavelength known
    with pytest.raises(InputError, match=r"u, v look like metres.*uv_units='m'"):
        read_uvtable(stated)
    assert read_uvtable(stated, uv_units="m").u.max() == pytest.approx(um.max() / 1.3e-3)
    short = _uvtable(tmp_path / "short.txt", *_alma_metres(b_max=300))  # ACA-like metres, no wavelength
    with pytest.raises(InputError, match="even at a wavelength of 0.01 m"):
        read_uvtable(short)
    long_m = _uvtable(tmp_path / "long.txt", *_alma_metres(b_min=400))  # no wavelength, could be either
    with pytest.warns(DataWarning, match="could also be metres"):
        read_uvtable(long_m)
    with warnings.catch_warnings():  # the user said so: no warning
        warnings.simplefilter("error", DataWarning)
        read_uvtable(long_m, uv_units="lambda")
        read_uvtable(_uvtable(tmp_path / "ok.txt", um / 1.3e-3, vm / 1.3e-3, "wavelength[m] = 1.3e-3"))
        read_uvtable(_uvtable(tmp_path / "ok2.txt", um / 1.3e-3, vm / 1.3e-3))  # longest 1.2e7: wavelengths


# --- weights --------------------------------------------------------------------------------------
def test_non_statistical_weights_warn_with_the_fix_and_the_config_option_repairs_them(setup, tmp_path):
    from spiralbayes.config import load_config
    from spiralbayes.pipeline import load_data

    simobserve = setup.vis.with_weights(np.full(setup.vis.n, 2.0), "WEIGHT = SIGMA = 1 per hand")
    path = save_visibilities(simobserve, tmp_path / "simobserve.h5")
    with pytest.warns(DataWarning, match=r"weights look .* times too small.*exactly 2.*estimate_weights") as record:
        load_visibilities(path)
    factor = float(str(record[0].message).split("weights look ")[1].split(" times")[0])
    assert factor == pytest.approx(SIGMA ** -2 / 2, rel=0.15)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataWarning)
        load_visibilities(setup.files.data)  # statistical weights: silent
        cfg = _config(tmp_path / "c.toml", setup, tmp_path / "out",
                      data=f'path = "{path}"\nestimate_weights = true', geometry="inc = 30.0\nPA = 60.0")
        config = load_config(cfg)
        repaired = load_data(config["data"], GEOMETRY)
    assert np.median(repaired.weights) == pytest.approx(SIGMA ** -2, rel=0.05)
    with pytest.warns(DataWarning, match="weights look about .* times too small"):  # and the scan says it too
        scan(simobserve, setup.model, setup.templates[:1], r_p=[0.3], n_phi_p=4, progress=False)


# --- unknown template metadata; strict JSON -------------------------------------------------------
def test_fargo3d_like_template_with_nan_beta_is_detected_and_verdict_is_strict_json(setup, tmp_path):
    from spiralbayes.pipeline import write_scan_outputs

    result = setup.result
    assert result.templates[0]["beta"] is None  # unknown, stored as null
    assert mirror_index(result, 0) == 1 and mirror_index(result, 1) == 0
    verdict = detect(result)
    assert verdict.template == "fargo_m1_R" and verdict.detected
    assert np.isfinite(verdict.handedness_ratio) and verdict.handedness_ratio < 0.5
    assert abs(verdict.r_p - R_P) < 1e-9
    files = write_scan_outputs(result, verdict, tmp_path, plots=True)
    assert any(f.name == "heatmap_fargo_m1_R.png" for f in files)

    def refuse(constant):
        raise ValueError(f"non-standard JSON constant {constant}")

    assert json.loads((tmp_path / "verdict.json").read_text(), parse_constant=refuse)["detected"] is True
    loaded = ScanResult.load(tmp_path / "scan.h5")
    assert loaded.templates == result.templates  # equal after a round trip (NaN would not be)
    lonely = dataclasses.replace(result, templates=result.templates[:1], cross=result.cross[:1],
                                 power=result.power[:1], cross_error=result.cross_error[:1],
                                 power_error=result.power_error[:1])  # no mirror scanned: the ratio is unknown
    alone = json.loads(json.dumps(detect(lonely).to_dict(), allow_nan=False))
    assert alone["handedness_ratio"] is None and alone["test2_passed"] is False


# --- command line ---------------------------------------------------------------------------------
def test_cli_prints_user_errors_as_one_line_and_debug_shows_the_traceback(tmp_path, capsys):
    from spiralbayes.cli import main

    cfg = tmp_path / "bad.toml"
    cfg.write_text("[grid]\nn_r_p = 5.5\n")
    assert main(["scan", str(cfg)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("spiralbayes: error: ") and "grid.n_r_p must be an integer" in err
    assert "Traceback" not in err and err.count("\n") == 1
    with pytest.raises(ConfigError):
        main(["--debug", "scan", str(cfg)])
    assert main(["axisym", str(tmp_path / "nothing.txt")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_cli_help_is_plain_text_and_documents_config(capsys):
    from spiralbayes.cli import main

    for argv in (["--help"], ["scan", "-h"]):
        with pytest.raises(SystemExit):
            main(argv)
        text = capsys.readouterr().out
        assert "``" not in text and ":func:" not in text
    assert "TOML configuration file" in text and "--force-resume" in text


def test_measurement_set_errors_are_one_line(tmp_path, monkeypatch):
    import builtins

    from spiralbayes.io import read_ms

    ms = tmp_path / "obs.ms"
    ms.mkdir()
    (ms / "table.dat").write_bytes(b"")
    with pytest.raises(InputError, match=r"option wavelength= does not apply.*CHAN_FREQ.*options of read_ms: column"):
        load_visibilities(ms, wavelength=1.3e-3)
    real_import = builtins.__import__

    def no_casacore(name, *args, **kwargs):
        if name.startswith("casacore"):
            raise ImportError("No module named 'casacore'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_casacore)
    with pytest.raises(MissingDependencyError, match=r'pip install "spiralbayes\[ms\]"') as info:
        read_ms(ms)
    assert info.value.__cause__ is None and info.value.__suppress_context__


# --- files ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("umask", [0o022, 0o077, 0o002])
def test_outputs_are_written_with_the_users_umask(setup, tmp_path, umask):
    from spiralbayes.pipeline import save_figure
    from spiralbayes.plotting.scan import plot_chi2_vs_rp

    old = os.umask(umask)
    try:
        written = [setup.result.save(tmp_path / "scan.h5"), save_visibilities(setup.vis, tmp_path / "v.txt"),
                   save_figure(plot_chi2_vs_rp(setup.result), tmp_path / "p.png")]
    finally:
        os.umask(old)
    for path in written:
        assert path.stat().st_mode & 0o777 == 0o666 & ~umask, path
    assert not list(tmp_path.glob(".*.tmp"))  # no temporary file left behind


def test_reprs_are_a_line_not_an_array_dump(setup):
    for obj in (setup.result, setup.model):
        text = repr(obj)
        assert "\n" not in text and len(text) < 400 and "array(" not in text
    assert "fargo_m1_R" in repr(setup.result) and "face-on flux" in repr(setup.model)
