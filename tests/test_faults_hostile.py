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

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from spiralbayes.exceptions import ConfigError, DataWarning, InputError

from .test_faults import GRID, _config, setup  # noqa: F401  (the module's fixture)


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
    from spiralbayes.inference.sampler import sample_posterior

    out = tmp_path / "out"
    setup.result.save(out / "scan.h5")
    with Unchanged(out, *_inputs(setup)), pytest.raises(InputError, match="run_name = '../scan' must be a plain name"):
        sample_posterior(setup.vis, setup.model, setup.templates[:1], run_name="../scan", chains_dir=out / "chains",
                         progress=False)


def test_no_writer_overwrites_a_result_of_another_kind(setup, tmp_path):
    from spiralbayes.inference.chains import ChainStore

    scan_file = setup.result.save(tmp_path / "scan.h5")
    with Unchanged(tmp_path), pytest.raises(InputError, match=r"holds another kind of result \(spiralbayes.ScanResult\), refusing to overwrite it with a spiralbayes.PosteriorRun"):
        ChainStore(scan_file, "t").read()
    with Unchanged(tmp_path), pytest.raises(InputError, match="holds another kind of result"):
        setup.model.save(scan_file)
    assert setup.result.save(scan_file) == scan_file  # the same kind is replaced as before
