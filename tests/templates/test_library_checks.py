"""The FARGO3D library's checks of one setting (issue 21), computed from the committed maps.

Resolution: the library runs at 7.1 cells per H; the 14.3-cell run of the same set-up must agree
with it once smoothed with the fiducial beam, at equal time. Reference: issue 21's own 16-vs-7
test (11 orbits, another domain), which agreed to 1 % in RMS with NCC 0.999 after the beam.
Longer evolution: the 200-orbit runs continue the 20-orbit library set-up; their gaps must be
deeper than at 20 orbits (the map's own ⟨Σ⟩_φ), which is what makes them a check of evolution.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from .fidelity import REF_DIR, beam_metrics, reference_cases, reference_template

h5py = pytest.importorskip("h5py")
LIBRARY = REF_DIR / "fargo3d_library.h5"


def _library_cases() -> dict:
    if not LIBRARY.exists():
        return {}
    return {c.group: c for c in reference_cases() if c.file == LIBRARY.name}


def _orbits(group: str) -> float:
    with h5py.File(LIBRARY, "r") as f:
        return float(f[group].attrs["orbits"])


@pytest.mark.parametrize("tau0", [0.3, 3.0])
def test_the_library_resolution_is_what_the_beam_sees(tau0):
    cases = _library_cases()
    if "h0.07_mu1_res14" not in cases or "h0.07_mu1" not in cases:
        pytest.skip("the resolution check or its library case is not in fargo3d_library.h5")
    if _orbits("h0.07_mu1_res14") != _orbits("h0.07_mu1"):
        pytest.skip(f"the 14-cell run is at {_orbits('h0.07_mu1_res14'):g} orbits, the library at "
                    f"{_orbits('h0.07_mu1'):g}: not at equal time (see its equal_time_check attribute)")
    fine = reference_template(cases["h0.07_mu1_res14"], tau0)
    library = reference_template(cases["h0.07_mu1"], tau0)
    m = beam_metrics(library, fine)
    assert m["beam_ncc"] >= 0.99, m
    assert m["beam_rms_ratio"] == pytest.approx(1.0, abs=0.02), m


def test_the_stored_equal_time_check_is_the_maps_own():
    """The reduction's equal-time attribute (7-cell map at the 14-cell run's output) against the
    committed 20-orbit maps, when the two are at the same time."""
    cases = _library_cases()
    if "h0.07_mu1_res14" not in cases or _orbits("h0.07_mu1_res14") != _orbits("h0.07_mu1"):
        pytest.skip("no equal-time pair in fargo3d_library.h5")
    with h5py.File(LIBRARY, "r") as f:
        stored = json.loads(f["h0.07_mu1_res14"].attrs["equal_time_check"])
    m = beam_metrics(reference_template(cases["h0.07_mu1"], 0.3), reference_template(cases["h0.07_mu1_res14"], 0.3))
    # another 7-cell run of the same set-up (a restart on another machine): equal to round-off and restarts
    assert m["beam_ncc"] == pytest.approx(stored["beam_ncc"], abs=0.005)
    assert m["beam_rms_ratio"] == pytest.approx(stored["beam_rms_ratio"], abs=0.01)


@pytest.mark.parametrize("mu", ["1", "3"])
def test_the_200_orbit_gap_is_deeper_than_at_20(mu):
    cases = _library_cases()
    long, short = f"h0.07_mu{mu}_orbits200", f"h0.07_mu{mu}"
    if long not in cases or short not in cases:
        pytest.skip(f"{long} or {short} not in fargo3d_library.h5")
    with h5py.File(LIBRARY, "r") as f:
        x = f["x"][()]
        near = np.abs(x - 1.0) < 0.05
        depth = {g: float(np.mean(f[g]["sigma_axisym"][()][near])) for g in (long, short)}
    assert _orbits(long) > _orbits(short)
    assert depth[long] < depth[short], depth
