"""The learned model's training set: the isothermal gas runs of the reduced reference files."""

from __future__ import annotations

import pytest

from spiralbayes.exceptions import DataFileError, InputError
from spiralbayes.templates.learned import read_training_runs

from .common import FILES, run_named


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


def _write_run(f, name, *, mu, orbits, change, variant):
    import json

    import numpy as np

    g = f.create_group(name)
    g["dsigma"] = np.zeros((f["x"].size, f["phi"].size))
    g["sigma_axisym"] = np.ones(f["x"].size)
    g.attrs.update({"h_p": 0.1, "mu_Mth": mu, "p_sigma": 1.0, "nu": 1e-3 * 0.1**2, "orbits": orbits,
                    "fluid": "gas", "variant": variant, "run_state": "finished",
                    "steadiness": json.dumps({f"rms_rel_diff_vs_orbit_{orbits - 5:g}": change})})


def test_a_map_whose_later_age_grows_vortices_is_a_transient(tmp_path):
    import h5py
    import numpy as np

    path = tmp_path / "runs.h5"
    with h5py.File(path, "w") as f:
        f["x"], f["phi"] = np.linspace(0.5, 2.0, 4), np.linspace(-np.pi, np.pi, 6, endpoint=False)
        # a planet steady at 20 orbits whose continuation to 40 orbits grows vortices ...
        _write_run(f, "a", mu=1.4, orbits=20.0, change=0.38, variant="slope1")
        _write_run(f, "a_orbits40", mu=1.4, orbits=40.0, change=1.44, variant="slope1_orbits40")
        # ... and a lighter one in the same disc that stays steady
        _write_run(f, "b", mu=1.0, orbits=20.0, change=0.2, variant="slope1")
        _write_run(f, "b_orbits40", mu=1.0, orbits=40.0, change=0.1, variant="slope1_orbits40")
    names = [r.name.split(":")[-1] for r in read_training_runs([path], drop_transients=True)]
    assert names == ["b", "b_orbits40"]
    # by default the transient is trained on; its unsteady continuation never is
    assert [r.name.split(":")[-1] for r in read_training_runs([path])] == ["a", "b", "b_orbits40"]


def test_the_repository_transients_are_the_four_runs_continued_to_40_orbits(runs):
    # planets at H/r 0.11 whose maps still changed by > 25 % at 20 orbits and are unsteady at 40
    names = {r.name for r in runs}
    kept = {r.name for r in read_training_runs(FILES, drop_transients=True)}
    transients = ("mu1.4_slope1.4_alpha1.3e-04", "mu1.5_slope1.2_alpha2.0e-04", "mu3_slope1_alpha5.0e-03",
                  "mu1.3_slope1.3_alpha1.2e-04")
    assert names - kept == {f"continuum:h0.11_{run}" for run in transients}
    assert kept < names and not any(n.endswith("_orbits40") for n in names)
