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
FILES = sorted(REF_DIR.glob("*.h5"))


def _cases(f):
    return {name: f[name] for name in f if isinstance(f[name], h5py.Group)}


def _valid(g, n_x):
    return g["valid"][()].astype(bool) if "valid" in g else np.ones(n_x, bool)


def test_reference_files_exist():
    names = {p.name for p in FILES}
    assert {"wakeflow_isothermal.h5", "fargo3d_isothermal.h5"} <= names, names
    assert sum(p.stat().st_size for p in FILES) < 6e6


@pytest.fixture(params=FILES, ids=[p.name for p in FILES])
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
    for name, g in _cases(ref).items():
        sel = near & _valid(g, x.size)
        peak = float(np.abs(g["dsigma"][sel, :]).max())
        by_h.setdefault(round(float(g.attrs["h_p"]), 4), []).append((float(g.attrs["mu_Mth"]), peak))
    for h, rows in by_h.items():
        rows.sort()
        peaks = [p for _, p in rows]
        assert all(b > a for a, b in zip(peaks, peaks[1:])), (h, rows)


def test_arms_trail_for_hand_R(ref):
    """Outer arm just outside r_p at φ < 0, inner arm just inside at φ > 0 (hand R)."""
    x, phi = ref["x"][()], ref["phi"][()]
    for name, g in _cases(ref).items():
        h = float(g.attrs["h_p"])
        d = g["dsigma"][()]
        for xp, sign in ((1 + 3 * h, -1), (1 - 3 * h, +1)):
            i = int(np.argmin(np.abs(x - xp)))
            phi_max = phi[int(np.argmax(d[i, :]))]
            assert np.sign(phi_max) == sign and abs(phi_max) < np.pi / 2, (name, x[i], np.degrees(phi_max))
        # the mirror image would fail the same test
        i = int(np.argmin(np.abs(x - (1 + 3 * h))))
        assert phi[int(np.argmax(d[i, ::-1]))] > 0


def test_optically_thick_residual_is_fainter(ref):
    """Isothermal S22 transfer: δ ≈ τ0 e^{-τ0}/(1 − e^{-τ0}) δΣ/Σ, smaller at τ0 = 3 than at 0.3."""
    x = ref["x"][()]
    for name, g in _cases(ref).items():
        sel = _valid(g, x.size) & (np.abs(x - 1) > 0.2)
        ds = g["dsigma"][sel, :].astype(float)
        d03 = g["delta_tau0.3"][sel, :].astype(float)
        d3 = g["delta_tau3"][sel, :].astype(float)
        rms = lambda a: float(np.sqrt(np.mean(a**2)))  # noqa: E731
        assert rms(d3) < 0.5 * rms(d03) < rms(ds), name
        assert np.corrcoef(ds.ravel(), d03.ravel())[0, 1] > 0.95, name


def test_mass_bookkeeping(ref):
    for name, g in _cases(ref).items():
        mu, h = float(g.attrs["mu_Mth"]), float(g.attrs["h_p"])
        assert float(g.attrs["mu_M1"]) == pytest.approx(1.5 * mu)
        assert float(g.attrs["q_planet"]) == pytest.approx(mu * h**3, rel=2e-3)
