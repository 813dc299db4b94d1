"""The spiralbayes command: simulate -> scan from a config, and argument/config errors."""

import json

import pytest

from spiralbayes.cli import main


def test_print_config_is_loadable(capsys, tmp_path):
    from spiralbayes.config import default_config, load_config

    assert main(["scan", "--print-config"]) == 0
    path = tmp_path / "c.toml"
    path.write_text(capsys.readouterr().out)
    assert load_config(path) == default_config()


def test_simulate_then_scan_from_config(tmp_path, capsys):
    from spiralbayes.templates import TemplateBank, make_template
    from spiralbayes.visibilities import load_visibilities

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
    assert "Delta BIC" in capsys.readouterr().out


def test_errors_are_reported_not_raised(tmp_path, caplog):
    config = tmp_path / "run.toml"
    config.write_text("[grid]\nbogus = 1\n")
    assert main(["scan", str(config)]) == 2
    assert "unknown option grid.bogus" in caplog.text
    with pytest.raises(SystemExit):
        main(["scan"])


def test_axisym_on_real_as209_sample(tmp_path):
    from pathlib import Path

    from spiralbayes.axisymmetric import AxisymmetricModel

    data = Path(__file__).parent / "data" / "AS209_DSHARP_subsample_uvtable.txt"
    out = tmp_path / "fit"
    code = main(["-q", "axisym", str(data), "--inc", "34.97", "--pa", "85.76", "--dra=-1.9e-3",
                 "--ddec", "2.5e-3", "--distance", "121", "--out", str(out)])
    assert code == 0
    model = AxisymmetricModel.load(next(out.glob("*.h5")))
    assert model.geometry.inc == 34.97 and model.N == 200
    assert 0.1 < model.total_flux < 1.0  # AS 209 at 1.25 mm: about 0.25 Jy
    assert len(list(out.glob("*.png"))) == 2
