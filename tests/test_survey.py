"""Survey mode: a 3-disc survey on a 2-worker LocalCluster against the single-disc API, failures, resume, kill -9.

The discs are tiny synthetic Taurus-preset observations (frank N = 60, 2 templates, 6 x 16
planet positions, one alternative model, no plots) so that the whole module runs in about a
minute on 2 cores. The reference is the single-disc API (:func:`run_scan` and
:func:`run_limits_config`) on each disc's merged configuration, in its own folder.
"""

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

SURVEY = """
[survey]
name = "tiny"
output = "out"
scheduler = "serial"
chunk_templates = 1
connect_timeout = 2.0

[bank]
mass = [1.0]
tau0 = [0.3]
beta = [10.0]

[frank]
N = 60
[grid]
n_r_p = 6
n_phi_p = 16
r_p_max = 0.4
[alternatives]
models = ["lopsided"]
n_starts = 1
[limits]
completeness = false
[output]
plots = false

[[disc]]
name = "Disc A"
path = "data/A.h5"
distance = 140.0
inc = 30.0
PA = 60.0
simulate = { preset = "taurus", flux = 0.1, r_eff = 0.4, seed = 1 }

[[disc]]
name = "Disc B"
path = "data/B.h5"
distance = 130.0
inc = 45.0
PA = 10.0
simulate = { preset = "taurus", flux = 0.05, r_eff = 0.3, seed = 2 }
[disc.grid]
r_p_max = 0.35

[[disc]]
name = "Disc C"
path = "data/C.h5"
distance = 160.0
inc = 20.0
PA = 100.0
simulate = { preset = "taurus", flux = 0.08, r_eff = 0.35, seed = 3 }

[[disc]]
name = "Damaged"
path = "data/damaged.h5"
distance = 140.0
inc = 30.0
PA = 60.0
"""

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def survey_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("survey")
    (d / "survey.toml").write_text(SURVEY)
    (d / "data").mkdir()
    (d / "data" / "damaged.h5").write_bytes(b"\x89HDF\r\n\x1a\n" + b"\x00garbage" * 50)  # truncated HDF5
    return d


@pytest.fixture(scope="module")
def cluster_run(survey_dir):
    from spiralbayes.pipeline.survey import run_survey

    return run_survey(survey_dir / "survey.toml", scheduler="", n_workers=2, progress=False)


def _single_disc(job, out: Path):
    """The disc run one by one with the single-disc API, in its own folder."""
    from threadpoolctl import threadpool_limits

    from spiralbayes.pipeline import run_limits_config, run_scan

    config = {s: dict(v) for s, v in job.config.items()}
    config["output"]["dir"] = str(out)
    with threadpool_limits(1):  # Dask workers run one BLAS thread each
        run = run_scan(config, progress=False)
        limits = run_limits_config(config, progress=False)
    return run, limits


def test_survey_equals_single_disc_runs(cluster_run, tmp_path):
    from spiralbayes.inference.limits import ExclusionLimits, price_text
    from spiralbayes.inference.scan import ScanResult

    assert cluster_run.engine.startswith("LocalCluster(2 workers")
    rows = {r["disc"]: r for r in cluster_run.rows}
    assert [r["status"] for r in cluster_run.rows] == ["ok", "ok", "ok", "failed"]
    for job in cluster_run.spec.discs[:3]:
        run, limits = _single_disc(job, tmp_path / job.slug)
        survey_scan = ScanResult.load(job.out_dir / "scan.h5")
        assert np.array_equal(survey_scan.delta_chi2(), run.scan.delta_chi2(), equal_nan=True), job.name
        assert np.array_equal(survey_scan.r_p, run.scan.r_p)
        survey_verdict = (job.out_dir / "verdict.json").read_text()
        assert survey_verdict == (tmp_path / job.slug / "verdict.json").read_text(), job.name
        survey_limits = ExclusionLimits.load(job.out_dir / "limits.h5")
        assert np.array_equal(survey_limits.m_lim, limits.limits.m_lim, equal_nan=True)
        assert np.array_equal(survey_limits.upper_limit, limits.limits.upper_limit, equal_nan=True)
        assert (job.out_dir / "table3.md").read_text() == limits.table
        row = rows[job.name]
        assert row["delta_bic"] == run.verdict.delta_bic
        assert row["verdict"] == run.verdict.outcome
        d = job.config["geometry"]["distance"]
        ranges = limits.limits.excluded_ranges(None, 1.0)
        expected = "; ".join(f"{lo * d:.0f}-{hi * d:.0f} au (" for lo, hi in ranges) or "none"
        assert row["excluded_ge1Mth"].startswith(expected.split(" (")[0]), (row["excluded_ge1Mth"], expected)
        assert row["excluded_ge1Mth"].count(" au (") == len(ranges)
        # the survey row and the disc's Table 3 are one writer's: the robust (first) row's ranges
        assert row["excluded_ge1Mth"] in limits.table
        # the survey's [bank] builds every default morphology: the row names them and their price
        assert row["morphologies"] == "compromise, hydro, wakeflow"
        assert row["price_of_robustness"] == price_text(limits.limits)
    assert rows["Disc B"]["R_eff95_arcsec"] == pytest.approx(0.3, abs=0.02)  # the simulated 95 % radius


def test_damaged_disc_is_reported_and_others_finish(cluster_run, survey_dir):
    from astropy.table import Table

    bad = cluster_run.rows[-1]
    assert bad["status"] == "failed" and bad["disc"] == "Damaged"
    assert bad["error"].startswith("load: ") and "damaged.h5" in bad["error"] and "\n" not in bad["error"]
    table = Table.read(survey_dir / "out" / "survey_table.ecsv", format="ascii.ecsv")
    assert list(table["status"]) == ["ok", "ok", "ok", "failed"]
    assert "damaged.h5" in table["error"][3]
    md = (survey_dir / "out" / "survey_table.md").read_text()
    assert md.count("\n") == 2 + 4 and "| Damaged |" in md


def test_rerun_skips_finished_stages_and_gives_the_same_table(cluster_run, survey_dir):
    from spiralbayes.pipeline.survey import run_survey

    before = (survey_dir / "out" / "survey_table.ecsv").read_bytes()
    stamp = {p: p.stat().st_mtime_ns for p in (survey_dir / "out" / "discs").rglob("scan.h5")}
    rerun = run_survey(survey_dir / "survey.toml", scheduler="serial", progress=False)
    assert (survey_dir / "out" / "survey_table.ecsv").read_bytes() == before
    assert {p: p.stat().st_mtime_ns for p in stamp} == stamp  # no scan was redone
    frank = sum(v["stages_s"].get("frank", 0) for v in rerun.timings["discs"].values())
    assert frank < 1.0


def test_kill_client_then_rerun_gives_the_same_table(cluster_run, survey_dir):
    """kill -9 of a serial survey's process after its first disc's scan; the rerun's table equals the cluster run's."""
    out = survey_dir / "killed"
    code = ("import sys; from spiralbayes.pipeline.survey import run_survey; "
            f"run_survey({str(survey_dir / 'survey.toml')!r}, scheduler='serial', output={str(out)!r}, progress=False)")
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", ""),
           "MPLBACKEND": "Agg"}
    proc = subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    marker = out / "discs" / "Disc_B" / "survey_stage_frank.json"
    deadline = time.monotonic() + 120
    while not marker.exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert marker.exists() and not (out / "survey_table.ecsv").exists()
    from spiralbayes.pipeline.survey import run_survey

    run_survey(survey_dir / "survey.toml", scheduler="serial", output=str(out), progress=False)
    got = (out / "survey_table.ecsv").read_bytes()
    assert got == (survey_dir / "out" / "survey_table.ecsv").read_bytes().replace(
        str(survey_dir / "out").encode(), str(out).encode())


def test_unreachable_scheduler_fails_in_one_line_naming_it(survey_dir):
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", "")}
    address = "tcp://127.0.0.1:9"
    t0 = time.monotonic()
    done = subprocess.run([sys.executable, "-m", "spiralbayes.cli", "survey", str(survey_dir / "survey.toml"),
                           "--scheduler", address], env=env, capture_output=True, text=True, timeout=120)
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert done.returncode == 2
    assert len(lines) == 1 and address in lines[0] and lines[0].startswith("spiralbayes: error: cannot reach"), lines
    assert time.monotonic() - t0 < 60
    assert not (survey_dir / "unreached").exists()


def test_survey_file_errors_name_the_option(tmp_path):
    from spiralbayes.exceptions import ConfigError
    from spiralbayes.pipeline.survey.config import load_survey

    path = tmp_path / "s.toml"
    for text, words in (('[survey]\nposterior = "some"\n[[disc]]\nname="a"\npath="x.h5"\n', "survey.posterior"),
                        ('[[disc]]\nname="a"\npath="x.h5"\ncolour=1\n', "colour"),
                        ('[[disc]]\nname="a"\npath="x.h5"\n[disc.limits]\ncl=2.0\n', "limits.cl"),
                        ('[grid]\nn_r_p=5\n', "no disc")):
        path.write_text(text)
        with pytest.raises(ConfigError, match=words):
            load_survey(path)


def test_example_survey_is_the_demo_and_parses():
    from spiralbayes.pipeline.survey.config import load_survey
    from spiralbayes.pipeline.survey.demo import TAURUS_DISCS, taurus_survey_toml

    example = ROOT / "examples" / "taurus_survey.toml"
    assert example.read_text() == taurus_survey_toml()
    spec = load_survey(example)
    assert [j.name for j in spec.discs] == list(TAURUS_DISCS)
    uz = spec.discs[-1].config
    assert (uz["geometry"]["inc"], uz["geometry"]["PA"], uz["geometry"]["distance"]) == (56.1, 90.4, 131.0)
    assert uz["grid"]["r_p_max"] == 1.0 and spec.discs[0].config["grid"]["r_p_max"] == 0.5


def test_jobqueue_cluster_from_configuration():
    pytest.importorskip("dask_jobqueue")
    from spiralbayes._compat import tomllib

    from spiralbayes.cluster import jobqueue_cluster

    options = tomllib.loads('jobs = 4\ncores = 2\nmemory = "8GB"\nwalltime = "02:00:00"\n'
                            'job_extra_directives = ["--account=disc-survey"]\n')
    cluster = jobqueue_cluster("slurm", options)
    try:
        script = cluster.job_script()
    finally:
        cluster.close()
    assert "#SBATCH -t 02:00:00" in script and "--account=disc-survey" in script
    assert "--nthreads 1" in script and "--nworkers 2" in script  # one thread per worker process
    cluster = jobqueue_cluster("pbs", {"cores": 1, "walltime": "01:00:00"})
    try:
        assert "#PBS -l walltime=01:00:00" in cluster.job_script()
    finally:
        cluster.close()


def test_posterior_policy():
    from spiralbayes.pipeline.survey.stages import wants_posterior

    quiet, candidate, detected = {"detected": False, "candidate": None}, \
        {"detected": False, "candidate": {"template": "t"}}, {"detected": True, "candidate": None}
    assert [wants_posterior("candidates", v) for v in (quiet, candidate, detected)] == [False, True, True]
    assert [wants_posterior("all", v) for v in (quiet, candidate, detected)] == [True, True, True]
    assert not any(wants_posterior("none", v) for v in (quiet, candidate, detected))


@pytest.mark.slow
def test_posterior_all_runs_the_sample_stage(survey_dir, tmp_path):
    """posterior = "all" on one disc: the sample stage's files appear and P(planet) is in the table."""
    from spiralbayes.pipeline.survey import run_survey

    text = SURVEY.split("[[disc]]")[0] + "[[disc]]" + SURVEY.split("[[disc]]")[1]
    text = text.replace("[survey]\n", '[survey]\nposterior = "all"\nposterior_steps = 60\n', 1)
    text += "[sample]\nn_walkers = 16\nevidence_draws = 200\nconvergence = \"ignore\"\n"
    path = survey_dir / "posterior.toml"
    path.write_text(text)
    run = run_survey(path, output=str(tmp_path / "post"), progress=False)
    row = run.rows[0]
    assert row["status"] == "ok", row
    assert 0.0 <= row["p_planet"] <= 1.0
    assert (tmp_path / "post" / "discs" / "Disc_A" / "posterior_summary.json").exists()


def _tree_hashes(folder: Path) -> dict:
    import hashlib

    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()} if folder.exists() else {}


@pytest.mark.parametrize("name", [".", "..", "_", "./..", "/"])
def test_disc_name_that_names_no_folder_of_its_own_is_refused(tmp_path, name):
    from spiralbayes.exceptions import ConfigError
    from spiralbayes.pipeline.survey import load_survey, run_survey

    path = tmp_path / "s.toml"
    path.write_text(f'[survey]\noutput = "out"\nscheduler = "serial"\n[[disc]]\nname = {name!r}\npath = "x.h5"\n'
                    'distance = 140.0\ninc = 30.0\nPA = 10.0\n'.replace("'", '"'))
    before = _tree_hashes(tmp_path)
    with pytest.raises(ConfigError, match=r"disc\.name = .* no letter or digit.*give the disc a name"):
        load_survey(path)
    with pytest.raises(ConfigError, match="disc.name"):
        run_survey(path, progress=False)
    assert _tree_hashes(tmp_path) == before and not (tmp_path / "out").exists()


@pytest.mark.parametrize("distance", [1e9, 0.5, 20000.0])
def test_implausible_distance_is_refused_with_the_range(tmp_path, distance):
    from spiralbayes.exceptions import ConfigError
    from spiralbayes.pipeline.survey import load_survey

    path = tmp_path / "s.toml"
    value = repr(distance)
    path.write_text(f'[[disc]]\nname = "far"\npath = "x.h5"\ndistance = {value}\ninc = 30.0\nPA = 10.0\n')
    with pytest.raises(ConfigError, match=r"disc 'far': geometry.distance = .* must be a distance in pc between 1 "
                                          r"and 10000"):
        load_survey(path)
    path.write_text(path.read_text().replace(f"distance = {value}", "distance = 9999.0"))
    assert load_survey(path).discs[0].config["geometry"]["distance"] == 9999.0
    shared = f'[geometry]\ndistance = {value}\n[[disc]]\nname = "far"\npath = "x.h5"\ninc = 30.0\nPA = 10.0\n'
    path.write_text(shared)  # the distance shared by every disc is checked as well
    with pytest.raises(ConfigError, match=r"geometry.distance = .* must be a distance in pc between 1 and 10000"):
        load_survey(path)


def test_survey_file_reading_errors(tmp_path):
    from spiralbayes.exceptions import ConfigError, MissingFileError
    from spiralbayes.pipeline.survey import load_survey

    binary = tmp_path / "s.toml"
    binary.write_bytes(b"\xff\xfe\x00\x81 not text")
    with pytest.raises(ConfigError, match="is not a text"):
        load_survey(binary)
    with pytest.raises(MissingFileError, match="survey file .* not found"):
        load_survey(tmp_path / "none.toml")
    binary.write_text('[survey]\nscheduler = "locl"\n[[disc]]\nname="a"\npath="x.h5"\n')
    with pytest.raises(ConfigError, match="survey.scheduler = 'locl' is not a Dask engine"):
        load_survey(binary)


def test_failed_discs_give_a_nonzero_exit_after_the_table(cluster_run, survey_dir):
    from spiralbayes.pipeline.survey import SurveyFailedError

    assert cluster_run.failed == ["Damaged"] and cluster_run.exit_code == 1
    assert (survey_dir / "out" / "survey_table.ecsv").exists()
    with pytest.raises(SurveyFailedError,
                       match=r"^1 of 4 discs failed \(Damaged\): their errors are in .*survey_table"):
        cluster_run.check()


def _pair_survey(survey_dir: Path, inc_c: float = 20.0) -> str:
    """Discs A and C of SURVEY with the bank and data at absolute paths, so that only [output] moves with a copy."""
    discs = SURVEY.split("[[disc]]")
    text = discs[0].replace("[bank]\nmass = [1.0]\ntau0 = [0.3]\nbeta = [10.0]\n",
                         f"[templates]\nbank = {str(survey_dir / 'out' / 'bank.h5')!r}\n")
    for disc in (discs[1], discs[3]):
        text += "[[disc]]" + disc.replace('path = "data/', f'path = "{survey_dir}/data/')
    return text.replace("inc = 20.0", f"inc = {inc_c}").replace("'", '"')


@pytest.fixture(scope="module")
def pair_run(cluster_run, survey_dir, tmp_path_factory):
    from spiralbayes.pipeline.survey import run_survey

    folder = tmp_path_factory.mktemp("pair")
    (folder / "pair.toml").write_text(_pair_survey(survey_dir))
    run = run_survey(folder / "pair.toml", scheduler="serial", progress=False)
    assert [r["status"] for r in run.rows] == ["ok", "ok"]
    return folder


def test_changed_disc_reruns_exactly_its_changed_stages(pair_run, survey_dir, tmp_path):
    """One disc's inclination changed: its frank, scan and limits run again; the other disc's scan is untouched."""
    import json

    from spiralbayes.pipeline.survey import run_survey

    out = tmp_path / "out"
    shutil.copytree(pair_run / "out", out)
    path = tmp_path / "changed.toml"
    path.write_text(_pair_survey(survey_dir, inc_c=25.0))
    others = {d: _tree_hashes(out / "discs" / d) for d in ("Disc_A",)}
    scans = {d: (out / "discs" / d / "scan.h5").stat().st_mtime_ns for d in ("Disc_A", "Disc_C")}
    rerun = run_survey(path, scheduler="serial", output=str(out), progress=False)
    assert [r["status"] for r in rerun.rows] == ["ok", "ok"]
    for d in ("Disc_A",):
        assert (out / "discs" / d / "scan.h5").stat().st_mtime_ns == scans[d]
        now = _tree_hashes(out / "discs" / d)
        # only the limits stage reran there ([output] dir is in its key and the folder moved)
        assert {k for k in now if now[k] != others[d].get(k)} <= {"survey_stage_limits.json", "limits.h5",
                                                                   "config_used_limits.toml"} | {
            k for k in now if k.startswith(("mass_radius", "excluded_fraction", "table3", "limits_summary"))}
        assert "scan.h5" in now and now["scan.h5"] == others[d]["scan.h5"]
    disc_c = out / "discs" / "Disc_C"
    assert (disc_c / "scan.h5").stat().st_mtime_ns != scans["Disc_C"]
    from spiralbayes.inference.scan import ScanResult

    assert ScanResult.load(disc_c / "scan.h5").geometry.inc == 25.0
    scan_marker = json.loads((disc_c / "survey_stage_scan.json").read_text())
    assert scan_marker["status"] == "done" and "scan.h5" in scan_marker["files"]
    frank_marker = json.loads((disc_c / "survey_stage_frank.json").read_text())
    assert frank_marker["info"]["replaced"] == ["axisymmetric.h5"]


def test_a_file_the_survey_did_not_write_is_never_replaced(pair_run, survey_dir, tmp_path):
    from spiralbayes.pipeline.survey import run_survey

    out = tmp_path / "out"
    shutil.copytree(pair_run / "out", out)
    foreign = out / "discs" / "Disc_C" / "scan_checkpoint.h5"
    foreign.write_bytes(b"a checkpoint of another scan")
    path = tmp_path / "changed.toml"
    path.write_text(_pair_survey(survey_dir, inc_c=26.0))
    before = _tree_hashes(out / "discs" / "Disc_C")
    run = run_survey(path, scheduler="serial", output=str(out), progress=False)
    row = run.rows[1]
    assert row["status"] == "failed" and "scan_checkpoint.h5 was not written by this survey" in row["error"]
    assert "move it away or delete it" in row["error"] and "\n" not in row["error"]
    after = _tree_hashes(out / "discs" / "Disc_C")
    assert after["scan_checkpoint.h5"] == before["scan_checkpoint.h5"]
    assert after["scan.h5"] == before["scan.h5"] and after["verdict.json"] == before["verdict.json"]
    fresh = tmp_path / "fresh"
    (fresh / "discs" / "Disc_A").mkdir(parents=True)
    (fresh / "discs" / "Disc_A" / "notes.txt").write_text("mine")
    run = run_survey(survey_dir / "survey.toml", scheduler="serial", output=str(fresh), progress=False)
    assert run.rows[0]["status"] == "failed" and "already holds files the survey did not write (notes.txt)" in \
        run.rows[0]["error"]
    assert (fresh / "discs" / "Disc_A" / "notes.txt").read_text() == "mine"
    assert sorted(p.name for p in (fresh / "discs" / "Disc_A").iterdir()) == ["notes.txt"]


def test_stage_markers_own_exactly_what_their_stage_wrote(tmp_path):
    from spiralbayes.pipeline.survey.files import (ForeignFileError, begin, claim, clear, done, mark, superseded,
                                                   write_text)

    out = tmp_path / "disc"
    out.mkdir()
    (out / "notes.txt").write_text("the user's")
    since = begin(out, "frank", "k1")
    assert done(out, "frank", "k1") is None  # running is not done
    write_text(out / "axisymmetric.h5", "model 1")
    assert claim(out, ["axisymmetric.h5"]) == ["axisymmetric.h5"]  # an interrupted stage's file is the survey's
    with pytest.raises(ForeignFileError, match=r"notes.txt was not written by this survey .* move it away or delete"):
        claim(out, ["notes.txt"])  # there before the stage began: never the survey's
    assert begin(out, "frank", "k1")["before"] == since["before"]  # a retry keeps the first attempt's snapshot
    mark(out, "frank", "k1", {"n": 1}, since=since)
    assert done(out, "frank", "k1", "axisymmetric.h5") == {"n": 1} and done(out, "frank", "k2") is None
    assert superseded(out, "frank", "k2") and not superseded(out, "frank", "k1")
    (out / "axisymmetric.h5").write_text("edited by hand")
    with pytest.raises(ForeignFileError, match="axisymmetric.h5 was not written by this survey \\(or was changed"):
        claim(out, ["axisymmetric.h5", "absent.h5"])
    # chains the survey wrote are cleared for a new posterior; a foreign one stops it and nothing is deleted
    since = begin(out, "posterior", "p1")
    write_text(out / "chains" / "run.h5", "chain")
    mark(out, "posterior", "p1", since=since)
    assert clear(out, "chains") == ["chains/run.h5"] and not (out / "chains" / "run.h5").exists()
    write_text(out / "chains" / "run.h5", "someone else's chain")
    with pytest.raises(ForeignFileError, match="chains/run.h5"):
        clear(out, "chains")
    assert (out / "chains" / "run.h5").read_text() == "someone else's chain"
    assert (out / "notes.txt").read_text() == "the user's"
