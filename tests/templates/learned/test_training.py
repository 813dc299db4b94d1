"""The learned model's training set: the isothermal gas runs of the reduced reference files."""

from __future__ import annotations

import pytest

from spiralbayes.exceptions import DataFileError, InputError
from spiralbayes.templates.learned import read_training_runs

from .common import run_named


def test_training_set_is_the_isothermal_gas_runs(runs):
    names = {r.name for r in runs}
    # the physics set, the library's gas runs at both ages and the continuum design are in ...
    assert {"physics:h0.07_mu1_slope0.5", "physics:h0.07_mu1_orbits500", "library:h0.07_mu1_orbits200",
            "library:h0.05_mu3", "isothermal:h0.07_mu1"} <= names
    assert sum(n.startswith("continuum:") for n in names) >= 22
    # ... dust, β = 10, numerical checks and the vortex-dominated runs are not
    for left_out in ("library:h0.07_mu1_st0.03", "library:h0.07_mu1_beta10", "library:h0.07_mu1_res14",
                     "library:h0.07_mu1_soft0.35", "library:h0.10_mu3"):
        assert left_out not in names
    run = run_named(runs, "physics:h0.07_mu1_nu1e-04")
    assert run.alpha == pytest.approx(1e-4 / 0.07**2) and run.slope == 1.0 and run.orbits == 20


def test_missing_and_unreadable_files_are_clear_errors(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        read_training_runs([tmp_path / "none.h5"])
    (tmp_path / "bad.h5").write_bytes(b"not hdf5")
    with pytest.raises(DataFileError, match="bad.h5"):
        read_training_runs([tmp_path / "bad.h5"])
