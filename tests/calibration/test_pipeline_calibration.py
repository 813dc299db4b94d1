"""``[calibration] solve`` through the command line: simulate with gain errors, scan, and the files it leaves."""

from __future__ import annotations

import json

import numpy as np
import pytest

from spiralbayes.calibration import GainSolution
from spiralbayes.cli import main
from spiralbayes.templates import TemplateBank, make_template


def _config(tmp_path, data: str, calibration: str, out: str = "out") -> str:
    right = make_template(3.0, 0.3, 10.0, "R", n_x=60, n_phi=180)
    TemplateBank([right, right.mirror()]).save(tmp_path / "bank.h5")
    path = tmp_path / "run.toml"
    path.write_text(f"""
[data]
path = "{data}"
[geometry]
inc = 30.0
PA = 60.0
[calibration]
{calibration}
[templates]
bank = "{tmp_path / 'bank.h5'}"
[grid]
r_p_min = 0.2
r_p_max = 0.6
n_r_p = 3
n_phi_p = 12
[alternatives]
fit = false
[limits]
completeness = false
[output]
dir = "{tmp_path / out}"
plots = true
""")
    return str(path)


def test_scan_solves_the_gains_and_says_so(tmp_path, capsys):
    """The Taurus set-up (6.3k visibilities, 43 antennas, 7 integrations) with 15 deg antenna phases."""
    data = tmp_path / "obs.h5"
    assert main(["-q", "simulate", "--preset", "taurus", "--out", str(data), "--seed", "4", "--phase-rms", "15",
                 "--gain-coherence", "600"]) == 0
    config = _config(tmp_path, "obs.h5", 'solve = "phase"\nn_iterations = 1')
    assert main(["-q", "scan", config]) == 0
    out = tmp_path / "out"
    solution = GainSolution.load(out / "gains.h5")
    assert solution.mode == "phase" and solution.n_intervals == 7  # 7 one-minute integrations, 60-s intervals
    # the second solve, against the disc plus the first scan's best spiral, from rows down to S/N 1
    assert solution.min_snr == 1.0
    candidate = solution.provenance["candidate"]
    assert 0.2 <= candidate["r_p_arcsec"] <= 0.6 and "the scan's best spiral, " in solution.note()
    assert solution.phase_rms_deg == pytest.approx(15.0, rel=0.35)
    assert (out / "gains.png").exists()
    text = (out / "verdict.txt").read_text()
    assert f"The data were corrected first: {solution.note()}." in text
    assert "antenna gains solved (phase, 60 s intervals, " in text
    assert json.loads((out / "verdict.json").read_text())["gains_solved"] == solution.note()
    # limits reuse the scan and the saved solution, and say so first
    assert main(["-q", "limits", config]) == 0
    summary = (out / "limits_summary.txt").read_text().splitlines()
    assert summary[0] == f"The data were corrected first: {solution.note()}."
    assert solution.note() in (out / "table3.md").read_text()
    # other [calibration] settings: the saved solution is refused by the commands that reuse it, naming them
    assert main(["-q", "scan", config]) == 0  # a rerun in its own folder resumes (the scan was of corrected data)
    capsys.readouterr()
    other = _config(tmp_path, "obs.h5", 'solve = "phase"\nn_iterations = 1\ninterval_s = 120.0')
    assert main(["-q", "limits", other]) == 2
    err = capsys.readouterr().err
    assert "[calibration] settings (interval_s: 60.0 -> 120.0)" in err and len(err.strip().splitlines()) == 1
    # candidate_min_snr = 0: one solve, against the disc alone, from rows of model S/N >= min_snr
    once = _config(tmp_path, "obs.h5", 'solve = "phase"\nn_iterations = 1\ncandidate_min_snr = 0', "once")
    assert main(["-q", "scan", once]) == 0
    first = GainSolution.load(tmp_path / "once" / "gains.h5")
    assert first.min_snr == 5.0 and "candidate" not in first.provenance and "best spiral" not in first.note()


@pytest.mark.slow
def test_sample_applies_the_scans_gain_solution(tmp_path):
    """`spiralbayes sample` after `spiralbayes scan` samples the corrected data with the saved solution
    (not a new one) and says so in its summary (~40 s)."""
    data = tmp_path / "obs.h5"
    assert main(["-q", "simulate", "--preset", "taurus", "--out", str(data), "--seed", "4", "--phase-rms", "15",
                 "--gain-coherence", "600"]) == 0
    config = _config(tmp_path, "obs.h5", 'solve = "phase"\nn_iterations = 1')
    with open(config, "a") as f:
        f.write("[sample]\nn_walkers = 14\nn_steps = 20\nevidence_draws = 50\nconvergence = \"ignore\"\n")
    assert main(["-q", "scan", config]) == 0
    gains = tmp_path / "out" / "gains.h5"
    stamp = gains.stat().st_mtime_ns
    assert main(["-q", "sample", config]) == 0
    assert gains.stat().st_mtime_ns == stamp  # reused, not solved again
    summary = json.loads(next((tmp_path / "out").glob("*_summary.json")).read_text())
    assert summary["gains_solved"] == GainSolution.load(gains).note()


def test_data_without_antennas_are_refused_naming_the_option(tmp_path, capsys):
    data = tmp_path / "obs.txt"  # a uvtable keeps no antennas
    assert main(["-q", "simulate", "--preset", "taurus", "--out", str(data), "--seed", "1"]) == 0
    assert main(["-q", "scan", _config(tmp_path, "obs.txt", 'solve = "amplitude+phase"')]) == 2
    err = capsys.readouterr().err
    assert "[calibration] solve = 'amplitude+phase' needs visibilities that record their antennas" in err
    assert not (tmp_path / "out" / "axisymmetric.h5").exists()


def test_a_bad_value_is_refused_when_the_file_is_read(tmp_path, capsys):
    assert main(["-q", "scan", _config(tmp_path, "nothing.h5", 'solve = "gains"')]) == 2
    err = capsys.readouterr().err
    assert "calibration.solve = 'gains' must be one of 'none', 'phase', 'amplitude+phase'" in err
    assert np.all([not p.exists() for p in (tmp_path / "out",)])


def test_the_candidate_spiral_is_the_scans_best_instance():
    """The spiral put in the model of the second solve is the scan's best instance: removing it from the
    residual lowers chi2 by the scan's (free-amplitude) Δχ² there, computed independently by the scan's
    tables, to the scan's accuracy tolerance."""
    import spiralbayes as sb
    from spiralbayes.inference.scan.accuracy import TOLERANCE
    from spiralbayes.pipeline.calibrate import candidate_spiral

    template = make_template(3.0, 0.3, 10.0, "R", n_x=60, n_phi=180)
    vis = sb.simulate_observation("taurus", perturbation=template, r_p=0.36, phi_p=0.5, seed=2)
    disc = sb.fit_axisymmetric(vis, sb.DiscGeometry(np.radians(30.0), np.radians(60.0)), progress=False)
    bank = [template, template.mirror()]
    result = sb.scan(vis, disc, bank, r_p_min=0.2, r_p_max=0.5, n_r_p=4, n_phi_p=24, progress=False)
    for amplitude in ("free", None):
        dv, about = candidate_spiral(result, vis, disc, bank, amplitude)
        peak = result.peak(amplitude=amplitude)
        assert about["template"] == peak.template and about["r_p_arcsec"] == peak.r_p
        s = vis.standardised()
        residual = s.V - disc.visibilities(s.u, s.v)
        exact = float(np.sum(s.weights * (np.abs(residual) ** 2 - np.abs(residual - dv) ** 2)))
        assert peak.delta_chi2 > 100  # a clear planet: the check is not of noise
        assert abs(exact - peak.delta_chi2) < TOLERANCE[0] + TOLERANCE[1] * abs(peak.delta_chi2)
    assert candidate_spiral(result, vis, disc, bank, 0.5)[1]["amplitude"] == 0.5
