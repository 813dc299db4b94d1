"""Sanity of the committed reference maps in tests/data/references/ (issue 9, template fidelity).

The maps come from tools/make_wakeflow_references.py and tools/make_fargo3d_references.py; these
tests only need numpy, h5py and pytest, and check that every file is readable and
self-consistent: shapes, zero azimuthal mean of δΣ/Σ and δ, mass ordering of the wake amplitude,
the hand-R orientation, the optical-depth ordering of δ and the mass bookkeeping.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

h5py = pytest.importorskip("h5py")

REF_DIR = Path(__file__).parent / "data" / "references"
FILES = sorted(REF_DIR.glob("*.h5")) + [p for sub in ("physics", "continuum")
                                       for p in sorted((REF_DIR / sub).glob("*.h5"))]


def _cases(f):
    return {name: f[name] for name in f if isinstance(f[name], h5py.Group)}


def _valid(g, n_x):
    return g["valid"][()].astype(bool) if "valid" in g else np.ones(n_x, bool)


def test_reference_files_exist():
    names = {p.name for p in FILES}
    assert {"wakeflow_isothermal.h5", "fargo3d_isothermal.h5"} <= names, names
    # issue 21: at most 15 MB in all; 17 MB with the library's second dust run set (stored at 2^-14),
    # 21 MB with the physics run set; the continuum file's runs at ~0.35 MB each (2^-14): the design's
    # 40, the aged run and the 13 neighbours of the worst held-out runs add <= 19 MB, the four runs
    # continued to 40 orbits 1.8 MB
    assert sum(p.stat().st_size for p in FILES) < 42e6


@pytest.fixture(params=FILES, ids=[str(p.relative_to(REF_DIR)) for p in FILES])
def ref(request):
    with h5py.File(request.param, "r") as f:
        yield f


def test_grid_and_shapes(ref):
    x, phi = ref["x"][()], ref["phi"][()]
    assert np.all(np.diff(x) > 0) and x[0] > 0
    assert np.allclose(np.diff(np.log(x)), np.log(x[1] / x[0]), rtol=1e-6)  # log-spaced
    n = phi.size
    assert np.allclose(phi, -np.pi + 2 * np.pi * np.arange(n) / n, atol=1e-12)
    assert phi[n // 2] == pytest.approx(0.0, abs=1e-12)
    for attr in ("source", "created_utc", "script", "conventions"):
        assert attr in ref.attrs
    cases = _cases(ref)
    assert cases and set(json.loads(ref.attrs["cases"])) == set(cases)
    for name, g in cases.items():
        maps = [k for k in g if k == "dsigma" or k.startswith("delta_tau")]
        assert {"dsigma", "delta_tau0.3", "delta_tau3"} <= set(maps), name
        for k in maps:
            assert g[k].shape == (x.size, phi.size), (name, k)
            assert g[k].dtype == np.float32
            assert np.all(np.isfinite(g[k][()])), (name, k)
        assert _valid(g, x.size).shape == (x.size,)


def test_zero_azimuthal_mean(ref):
    for name, g in _cases(ref).items():
        for k in ("dsigma", "delta_tau0.3", "delta_tau3"):
            m = g[k][()].astype(np.float64)
            scale = np.maximum(1.0, np.abs(m).max(axis=1))
            assert np.all(np.abs(m.mean(axis=1)) < 1e-5 * scale), (name, k)


def test_peak_grows_with_mass(ref):
    x = ref["x"][()]
    near = (x > 0.75) & (x < 1.3)
    by_h = {}
    for g in _cases(ref).values():
        sel = near & _valid(g, x.size)
        peak = float(np.abs(g["dsigma"][sel, :]).max())
        key = (round(float(g.attrs["h_p"]), 4), str(g.attrs.get("variant", "")))  # like with like
        by_h.setdefault(key, []).append((float(g.attrs["mu_Mth"]), peak))
    for h, rows in by_h.items():
        rows.sort()
        peaks = [p for _, p in rows]
        assert all(b > a for a, b in zip(peaks, peaks[1:])), (h, rows)


def test_arms_trail_for_hand_R(ref):
    """Outer arm just outside r_p at φ < 0, inner arm just inside at φ > 0 (hand R). Where a vortex
    outshines the outer arm the reducer records the check as failed; such a map must not be quasi-steady
    (its δΣ/Σ changes by more than 50 % in its last 5 orbits), and its inner arm is still checked."""
    x, phi = ref["x"][()], ref["phi"][()]
    for name, g in _cases(ref).items():
        h = float(g.attrs["h_p"])
        d = g["dsigma"][()]
        check = json.loads(g.attrs.get("orientation_check", "{}"))
        arms = ((1 + 3 * h, -1), (1 - 3 * h, +1))
        if "failed" in check:
            steady = json.loads(g.attrs["steadiness"])
            assert steady[f"rms_rel_diff_vs_orbit_{float(g.attrs['orbits']) - 5:g}"] > 0.5, name
            arms = arms[1:]
        for xp, sign in arms:
            i = int(np.argmin(np.abs(x - xp)))
            phi_max = phi[int(np.argmax(d[i, :]))]
            assert np.sign(phi_max) == sign and abs(phi_max) < np.pi / 2, (name, x[i], np.degrees(phi_max))
        # the mirror image would fail the same test
        i = int(np.argmin(np.abs(x - arms[0][0])))
        assert np.sign(phi[int(np.argmax(d[i, ::-1]))]) == -arms[0][1]


def test_optically_thick_residual_is_fainter(ref):
    """Isothermal S22 transfer: δ ≈ τ0 e^{-τ0}/(1 − e^{-τ0}) δΣ/Σ, smaller at τ0 = 3 than at 0.3.

    τ0 is the optical depth of the initial profile; where the dust has drifted away (⟨Σ⟩_φ below half
    the initial, e.g. the cavity of the 200-orbit St 0.1 run) the local optical depth is a fraction
    of it and both τ0 are thin there, so those radii are left out."""
    x = ref["x"][()]
    for name, g in _cases(ref).items():
        if float(g.attrs.get("beta", 0.0)) > 0:
            continue  # T varies too: test_library_beta_residual_is_linearised_transfer
        sel = _valid(g, x.size) & (np.abs(x - 1) > 0.2)
        if "sigma_axisym" in g:
            sel &= np.nan_to_num(g["sigma_axisym"][()] / x**-1.0, nan=1.0) > 0.5
        ds = g["dsigma"][sel, :].astype(float)
        d03 = g["delta_tau0.3"][sel, :].astype(float)
        d3 = g["delta_tau3"][sel, :].astype(float)
        rms = lambda a: float(np.sqrt(np.mean(a**2)))  # noqa: E731
        assert rms(d3) < 0.5 * rms(d03) < rms(ds), name
        assert np.corrcoef(ds.ravel(), d03.ravel())[0, 1] > 0.95, name


def test_mass_bookkeeping(ref):
    for g in _cases(ref).values():
        mu, h = float(g.attrs["mu_Mth"]), float(g.attrs["h_p"])
        assert float(g.attrs["mu_M1"]) == pytest.approx(1.5 * mu)
        assert float(g.attrs["q_planet"]) == pytest.approx(mu * h**3, rel=2e-3)


# -- issue 21: the FARGO3D library (tools/make_fargo3d_library.py) ------------------------------------
LIBRARY = REF_DIR / "fargo3d_library.h5"
needs_library = pytest.mark.skipif(not LIBRARY.exists(), reason="fargo3d_library.h5 not generated")


@pytest.fixture(scope="module")
def library():
    with h5py.File(LIBRARY, "r") as f:
        yield f


@needs_library
def test_library_provenance_and_reader(library):
    assert "FARGO3D commit" in library.attrs["source"] and "repo_commit" in library.attrs
    for name, g in _cases(library).items():
        a = g.attrs
        assert {"delta_tau0.1", "delta_tau0.3", "delta_tau1", "delta_tau3"} <= set(g), name
        assert a["run_state"] in ("finished", "running", "stopped before Ntot"), name
        assert a["complete"] == (a["orbits"] >= a["orbits_planned"] - 1e-6), name
        assert int(a["nx_phi"]) * float(a["h_p"]) / (2 * np.pi) > 6.9, name  # ≥ 7 cells per H
        reader = json.loads(a["package_reader"])
        assert reader["reader_mass_Mth"] == pytest.approx(float(a["mu_Mth"]), rel=1e-3), name
        assert reader["rms_delta_difference_over_rms_delta"] < 0.05, (name, reader)


@needs_library
def test_library_beta_cooling_relaxes_at_omega_over_beta(library):
    """The unperturbed β = 10 disc: the temperature excess decays at Ω/β (analytic rate)."""
    res = json.loads(library.attrs["beta_cooling_test"])
    rows = [v for k, v in res.items() if k.startswith("r=")]
    assert len(rows) == 3
    for row in rows:
        assert row["omega_over_beta"] == pytest.approx(row["r"] ** -1.5 / 10.0, rel=1e-3)
        assert row["ratio"] == pytest.approx(1.0, abs=0.05), row
        assert row["excess_end"] == pytest.approx(row["excess_t0"] * np.exp(-row["omega_over_beta"] * 4 * np.pi),
                                                  rel=0.1), row


def _dlnb_dlnt(temperature, wavelength=0.87e-3):
    xq = 6.62607015e-34 * 2.99792458e8 / (wavelength * 1.380649e-23 * temperature)
    return xq * np.exp(xq) / np.expm1(xq)


@needs_library
def test_library_beta_residual_is_linearised_transfer(library):
    """β = 10: δ = I/<I>_φ − 1 against the linearised S22 transfer
    δ ≈ f(τ) δΣ/Σ + (d ln B/d ln T) δT/T, f = τ e^{-τ}/(1 − e^{-τ}), T_0 = 19.7 K x^{-1/2}."""
    x = library["x"][()]
    beta_cases = {n: g for n, g in _cases(library).items() if float(g.attrs["beta"]) > 0}
    if not beta_cases:
        pytest.skip("no beta = 10 case reduced yet")
    for name, g in beta_cases.items():
        sel = _valid(g, x.size) & (np.abs(x - 1) > 0.2) & (x > 0.5) & (x < 2.0)
        ds, dt = g["dsigma"][sel].astype(float), g["dtemp"][sel].astype(float)
        assert np.sqrt(np.mean(dt**2)) > 0.1 * np.sqrt(np.mean(ds**2)), name  # the run has δT
        tau = 3.0 * g["sigma_axisym"][sel][:, None]
        lin = tau * np.exp(-tau) / -np.expm1(-tau) * ds + _dlnb_dlnt(19.7 * x[sel, None] ** -0.5) * dt
        d3 = g["delta_tau3"][sel].astype(float)
        assert np.corrcoef(lin.ravel(), d3.ravel())[0, 1] > 0.9, name
        assert np.sqrt(np.mean(d3**2) / np.mean(lin**2)) == pytest.approx(1.0, abs=0.25), name


@needs_library
def test_library_dust_follows_gas(library):
    """Dust at St 0.01–0.1: its arms lie on the gas's (Sturm et al. 2020; Speedie et al. 2022). Where
    the dust has no structure of its own — more than 0.15 r_p from the orbit and its ⟨Σ⟩_φ within
    30 % of the initial profile (outside its rings and gaps) — dust and gas δΣ/Σ correlate; at
    0.7, 0.8, 1.2 and 1.5 r_p the arm's azimuth is the gas's within 5°."""
    x, phi = library["x"][()], library["phi"][()]
    dust = {n: g for n, g in _cases(library).items() if float(g.attrs["stokes"]) > 0}
    if not dust:
        pytest.skip("no dust case reduced yet")
    for name, g in dust.items():
        d_all, gas_all = g["dsigma"][()].astype(float), g["dsigma_gas"][()].astype(float)
        sel = _valid(g, x.size) & (np.abs(x - 1) > 0.15) & (x > 0.5) & (x < 2.0)
        ratio = np.sqrt(np.mean(d_all[sel] ** 2) / np.mean(gas_all[sel] ** 2))
        assert ratio == pytest.approx(float(g.attrs["dust_over_gas_arm_rms"]), rel=0.05), name
        own = np.abs(np.log(np.nan_to_num(g["sigma_axisym"][()] / x**-1.0, nan=1.0))) > np.log(1.3)
        calm = sel & ~own
        # the 200-orbit St 0.1 run has a cavity and rings over most radii: 25 calm ones (x 450 azimuths)
        assert calm.sum() > 20, name
        assert np.corrcoef(d_all[calm].ravel(), gas_all[calm].ravel())[0, 1] > 0.85, name
        for xp in (0.7, 0.8, 1.2, 1.5):
            i = int(np.argmin(np.abs(x - xp)))
            off = np.angle(np.exp(1j * (phi[np.argmax(d_all[i])] - phi[np.argmax(gas_all[i])])))
            assert abs(np.degrees(off)) < 5.0, (name, xp, np.degrees(off))


@needs_library
def test_library_dust_departs_from_gas_more_for_larger_grains(library):
    """Radial drift, and so the dust's trapping at the gap edges and its co-orbital pile-up, grows
    with the Stokes number for St ≪ 1 (Weidenschilling 1977; Pinilla et al. 2012): among the dust
    runs of one planet and one run length, the co-orbital RMS of δΣ/Σ (|x − 1| < 0.1, more than 2 H
    from the planet) over the gas's in the same run, and the outer gap-edge ring's ⟨Σ⟩_φ over the
    initial profile (1.1–1.5 r_p), grow with St."""
    x, phi = library["x"][()], library["phi"][()]
    runs: dict[tuple, list] = {}
    for g in _cases(library).values():
        a = g.attrs
        if float(a["stokes"]) > 0:
            runs.setdefault((float(a["mu_Mth"]), float(a["h_p"]), float(a["orbits"])), []).append(g)
    compared = 0
    for key, gs in runs.items():
        if len(gs) < 2:
            continue
        band, ring = np.abs(x - 1.0) < 0.1, (x > 1.1) & (x < 1.5)
        rows = []
        for g in sorted(gs, key=lambda g: float(g.attrs["stokes"])):
            far = np.abs(phi) > 2.0 * float(g.attrs["h_p"])
            co = [np.sqrt(np.mean(g[k][()][band][:, far].astype(float) ** 2)) for k in ("dsigma", "dsigma_gas")]
            rows.append((co[0] / co[1], float(np.nanmax(g["sigma_axisym"][()][ring] / x[ring] ** -1.0))))
        for (co_a, ring_a), (co_b, ring_b) in zip(rows, rows[1:]):
            assert co_b > co_a and ring_b > ring_a, (key, rows)
        compared += 1
    if not compared:
        pytest.skip("no planet with dust runs at two Stokes numbers")
