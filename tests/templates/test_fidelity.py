"""The built-in generator against every committed reference map (issue 9; docs/templates.md).

Default run: δ-map level (seconds) — for every reference case and τ0, the generator's template at
the same (M_p, H/r, τ0) must correlate with the reference after smoothing with the fiducial beam,
have a comparable amplitude, and beat the version-1 generator. ``slow``: the issue's scan-level
criteria on the fiducial synthetic observation (recovery ≥ 0.85, r_p within one grid step,
φ_p within 4°, best bank mass = true mass) for the cases that meet them, and the measured floor
for those that do not (they are listed in the closing note of issue 9).
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

pytest.importorskip("h5py")

from tests.templates import fidelity as F

CASES = [c for c in F.reference_cases() if c.source != "fargo3dlib"]  # the issue-9 calibration set
LIBRARY = [c for c in F.reference_cases() if c.source == "fargo3dlib"]  # issue 21: reported, see below
IDS = [c.label for c in CASES]


def test_every_reference_case_is_present():
    labels = set(IDS)
    for h in ("0.05", "0.07", "0.10"):
        for mu in ("0.1", "0.3", "1"):
            assert f"wakeflow:h{h}_mu{mu}" in labels
    assert {"fargo3d:h0.07_mu0.3", "fargo3d:h0.07_mu1"} <= labels


@pytest.fixture(scope="module")
def map_rows():
    return {(r["case"], r["tau0"]): r for r in F.map_table(CASES)}


@pytest.fixture(scope="module")
def version1_rows():
    return {(r["case"], r["tau0"]): r for r in F.map_table(CASES, **F.VERSION1)}


@pytest.mark.parametrize("case", CASES, ids=IDS)
@pytest.mark.parametrize("tau0", F.TAUS)
def test_delta_map_matches_reference(case, tau0, map_rows, version1_rows):
    row, old = map_rows[(case.label, tau0)], version1_rows[(case.label, tau0)]
    # shape: the beam-smoothed maps correlate (now 0.63-0.97; version 1: 0.43-0.79)
    assert row["beam_ncc"] >= 0.60, row
    # amplitude within a factor 2 either way after smoothing (version 1: up to 2.4x too bright)
    assert 0.5 <= row["beam_rms_ratio"] <= 2.0, row
    # and the generator recovers at least a third of the reference's smoothed Δχ², better than before
    assert row["beam_recovery"] >= 0.35, row
    assert row["beam_recovery"] > old["beam_recovery"], (row, old)


def test_mean_beam_recovery_per_source(map_rows):
    """The calibration's objective (measured 0.81 for wakeflow, 0.61 for FARGO3D; version 1:
    0.21 and -0.41)."""
    wf = [r["beam_recovery"] for (label, _), r in map_rows.items() if label.startswith("wakeflow")]
    hydro = [r["beam_recovery"] for (label, _), r in map_rows.items() if label.startswith("fargo3d")]
    assert len(wf) == 18 and len(hydro) == 4
    assert np.mean(wf) >= 0.78
    assert np.mean(hydro) >= 0.55


LIBRARY_MAIN = [c for c in LIBRARY if c.group.count("_") == 1 or c.group.endswith("_beta10")]  # no checks
KNOWN_SHORT = {  # the generator (the compromise variant) where it misses the library's map-level bounds
    "fargo3dlib:h0.07_mu3": "3 M_th: generator 1.4-1.5x too bright, beam NCC 0.51-0.57",
    "fargo3dlib:h0.05_mu3": "3 M_th at H/r 0.05 (second run set): generator 1.6-1.7x too bright, beam NCC 0.41-0.56",
    "fargo3dlib:h0.10_mu3": "3 M_th at H/r 0.10 (second run set): vortex-dominated, beam NCC 0.27-0.29, recovery "
                            "-0.6/-0.4 (not a reference, fidelity.MAX_CHANGE)",
    "fargo3dlib:h0.05_mu1": "H/r 0.05, 1 M_th at tau0 3: beam NCC 0.57, recovery -0.11 (tau0 0.3: NCC 0.78, "
                            "recovery 0.47; version 1 -0.78 and -4.3); the hydro variant covers it (A_up 1.9-3.0)",
}
LIBRARY_PARAMS = [pytest.param(c, id=c.label, marks=[pytest.mark.xfail(strict=True, reason=KNOWN_SHORT[c.label])]
                               if c.label in KNOWN_SHORT else []) for c in LIBRARY_MAIN]


@pytest.mark.parametrize("case", LIBRARY_PARAMS)
def test_generator_holds_on_the_issue21_hydro_library(case):
    """Issue 21's FARGO3D runs (other masses, H/r and β than the calibration's; 20 orbits, r 0.4–2.5):
    the calibrated generator meets the same map-level bounds as on the calibration set and beats
    version 1 (measured at 0.3–1 M_th, H/r 0.07–0.10, β 0 and 10: beam NCC 0.80–0.90, recovery
    0.54–0.79; H/r 0.05, 0.3 M_th: NCC 0.66–0.85, recovery 0.37–0.71); at 3 M_th (every H/r), and at
    H/r 0.05 for 1 M_th, it does not (strict xfails, :data:`KNOWN_SHORT`). A run reduced before its end
    (attribute ``complete`` False) is not held to them."""
    import h5py

    with h5py.File(F.REF_DIR / case.file, "r") as f:
        if not bool(f[case.group].attrs["complete"]):
            pytest.skip(f"{case.label}: reduced at {f[case.group].attrs['orbits']} orbits, before the run's end")
    for tau0 in F.TAUS:
        ref = F.reference_template(case, tau0)
        row = F.beam_metrics(ref, F.generator_template(case.mu, tau0, case.h_p, case.beta))
        old = F.beam_metrics(ref, F.generator_template(case.mu, tau0, case.h_p, case.beta, **F.VERSION1))
        assert row["beam_ncc"] >= 0.60 and 0.5 <= row["beam_rms_ratio"] <= 2.0, (case.label, tau0, row)
        assert row["beam_recovery"] >= 0.35 and row["beam_recovery"] > old["beam_recovery"], (case.label, tau0, row)


def test_map_metrics_against_brute_force():
    """The weighted cross-correlation of two templates against an explicit double loop."""
    case = CASES[0]
    ref = F.reference_template(case, 0.3)
    gen = F.generator_template(case.mu, 0.3, case.h_p, n_x=40, n_phi=90, n_eta=256)
    m = F.map_metrics(ref, gen)
    w = F._weights(ref.x, 0.3)
    saa = sab = sbb = 0.0
    for i in range(ref.x.size):  # one radius at a time, the template evaluated on that circle
        a = ref.delta[i].astype(float)
        b = gen.evaluate(np.full(ref.phi.size, ref.x[i]), ref.phi, r_p=1.0)
        saa, sab, sbb = saa + w[i] * a @ a, sab + w[i] * a @ b, sbb + w[i] * b @ b
    assert m["ncc"] == pytest.approx(sab / np.sqrt(saa * sbb), rel=1e-9)
    assert m["rms_ratio"] == pytest.approx(np.sqrt(sbb / saa), rel=1e-9)
    assert F.map_metrics(ref, ref)["ncc"] == pytest.approx(1.0)
    assert F.beam_metrics(ref, ref)["beam_recovery"] == pytest.approx(1.0)


# --------------------------------------------------------------------------- scan level (slow)
SETUP_IDS = ["face-on", "inclined"]
MEETS_ISSUE = {
    # (case, tau0, setup) whose recovery, position and mass meet the issue's thresholds
    # (measured with tests/templates/fidelity.py; the table is in the closing note of issue 9)
    (label, tau0, setup)
    for label, tau0 in [("wakeflow:h0.07_mu0.3", 3.0), ("wakeflow:h0.10_mu0.1", 3.0),
                        ("wakeflow:h0.10_mu0.3", 3.0), ("wakeflow:h0.10_mu1", 0.3)]
    for setup in SETUP_IDS
}
WRONG_MASS = {("fargo3d:h0.07_mu1", 0.3)}
"""The bank's 0.3 M_th template fits FARGO3D's 1 M_th τ0 = 0.3 spiral better than the 1 M_th one."""


@cache
def _scan_row(label: str, tau0: float, setup: str) -> dict:
    case = next(c for c in CASES if c.label == label)
    inc, phi_p = F.SETUPS[SETUP_IDS.index(setup)]
    return F.evaluate_case(case, tau0, inc, phi_p)


SCAN_PARAMS = [(c.label, t, s) for c in CASES for t in F.TAUS for s in SETUP_IDS]


@pytest.mark.slow
@pytest.mark.parametrize("label,tau0,setup", sorted(MEETS_ISSUE))
def test_scan_meets_issue_thresholds(label, tau0, setup):
    row = _scan_row(label, tau0, setup)
    assert F.passes(row), row


@pytest.mark.slow
@pytest.mark.parametrize("label,tau0,setup", SCAN_PARAMS)
def test_scan_position_mass_and_recovery_floor(label, tau0, setup):
    """Every reference case: the true-mass template's best fit is within one r_p step and 4° of
    the truth, the best bank mass is the true one (but for WRONG_MASS), and the recovery has not
    fallen below what the calibration reached (wakeflow ≥ 0.42, FARGO3D 0.3 M_th ≥ 0.7,
    FARGO3D 1 M_th τ0 = 3 ≥ 0.4; FARGO3D 1 M_th τ0 = 0.3, -0.14 inclined and -0.16 face-on, has
    no floor)."""
    row = _scan_row(label, tau0, setup)
    assert row["dr_steps"] <= 1.0 + 1e-9 and row["dphi_deg"] <= 4.0 + 1e-9, row
    if (label, tau0) not in WRONG_MASS:
        assert row["best_mass"] == pytest.approx(row["mu"]), row
    floor = {"fargo3d:h0.07_mu0.3": 0.7, "fargo3d:h0.07_mu1": 0.4 if tau0 == 3.0 else -np.inf}
    assert row["recovery"] >= floor.get(label, 0.42), row
