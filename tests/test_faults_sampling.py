"""``spiralbayes sample`` killed with SIGKILL mid-chain and started again equals an uninterrupted run.

A subprocess runs :mod:`tests._support.faults_sampling_job` (the no-planet hypothesis, then a template with a
chain, then its mirror with a Laplace evidence) and is killed once the chain file shows the first
template part-way through its chain. The resumed run must reproduce the uninterrupted one exactly:
the chain (the interrupted template continues from its last flushed batch with its stored random
state), the evidences, and the template run after the resume.
"""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from tests._support import faults_sampling_job as job

ROOT = Path(__file__).resolve().parents[1]


def _iteration(path: Path, group: str) -> int:
    try:
        with h5py.File(path, "r") as f:
            return int(f[group].attrs["iteration"]) if group in f else -1
    except (OSError, KeyError):
        return -1


def test_killed_sample_run_resumes_to_the_uninterrupted_result(tmp_path):
    reference = job.run(tmp_path / "reference")
    name = reference.runs[0].name
    chains = tmp_path / "killed" / "job.h5"
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1",
           "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    proc = subprocess.Popen([sys.executable, "-m", "tests._support.faults_sampling_job", str(chains.parent)],
                            cwd=ROOT, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 900
        while _iteration(chains, name) < 2 * job.FLUSH and time.monotonic() < deadline:
            if proc.poll() is not None:
                pytest.fail("the job ended before it could be killed: " + proc.stderr.read().decode()[-2000:])
            time.sleep(0.05)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    finally:
        if proc.poll() is None:
            proc.kill()
    done = _iteration(chains, name)
    assert 2 * job.FLUSH <= done < job.N_STEPS, done  # killed mid-chain, the last batches flushed
    resumed = job.run(chains.parent)
    a, b = reference.runs[0], resumed.runs[0]
    np.testing.assert_array_equal(a.chain(discard=0, thin=1), b.chain(discard=0, thin=1))
    np.testing.assert_array_equal(a.samples, b.samples)
    assert a.ln_evidence == b.ln_evidence and resumed.null.ln_evidence == reference.null.ln_evidence
    # the template after the resume is the uninterrupted run's
    np.testing.assert_array_equal(reference.runs[1].samples, resumed.runs[1].samples)
    assert reference.runs[1].ln_evidence == resumed.runs[1].ln_evidence
    assert resumed.p_planet == reference.p_planet
    # and a finished run read back again changes nothing
    again = job.run(chains.parent)
    assert again.template_probabilities == resumed.template_probabilities
