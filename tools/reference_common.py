"""Shared pieces of the reference-map scripts (``make_wakeflow_references.py``,
``make_fargo3d_references.py``): the common polar grid, the brightness residuals through the
package's own radiative transfer, diagnostics, and the HDF5 writer.

Not part of the package; run with a venv where ``spiralbayes`` is installed (``pip install -e .``).

Conventions (docs/conventions.md): ``x = r/r_p``; ``phi`` in ``[-π, π)``, planet at ``φ = 0``;
right-handed (R) = planet orbiting towards increasing φ with trailing arms, so the outer arm lies
at ``φ < 0`` just outside ``r_p`` and the inner arm at ``φ > 0`` just inside.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import subprocess
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]

# Common reference grid: log-spaced radial cell centres in [X_MIN, X_MAX] (edges), uniform azimuths.
X_MIN, X_MAX = 0.2, 3.0
N_X, N_PHI = 200, 450          # 0.8 deg in φ; Δln x = 0.0135 (about 5 cells per H at x = 1, h = 0.07)
TAU0S = (0.3, 3.0)
WAVELENGTH = 0.87e-3           # ALMA Band 7 [m], the package default
MSTAR, R_P_AU, MU_GAS = 0.8, 50.0, 2.34
FLARING, SIGMA_SLOPE = 0.25, 1.0


def reference_grid(n_x: int = N_X, n_phi: int = N_PHI, x_min: float = X_MIN, x_max: float = X_MAX):
    """``(x, phi)``: log-spaced cell centres (edges ``geomspace(x_min, x_max, n_x + 1)``) and
    ``phi_k = -π + 2πk/n_phi`` (``n_phi`` even, so ``φ = 0`` is a grid point)."""
    if n_phi % 2:
        raise ValueError("n_phi must be even so that the planet (φ = 0) is a grid point")
    edges = np.geomspace(x_min, x_max, n_x + 1)
    x = np.sqrt(edges[1:] * edges[:-1])
    phi = -np.pi + 2.0 * np.pi * np.arange(n_phi) / n_phi
    return x, phi


def normalise_to_azimuthal_mean(sigma_over_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(Σ/<Σ>_φ − 1, <Σ>_φ/Σ_ref)`` from ``Σ/Σ_ref`` on an (x, φ) grid (mean along axis 1)."""
    mean = sigma_over_ref.mean(axis=1)
    return sigma_over_ref / mean[:, None] - 1.0, mean


def brightness_residuals(x, phi, dsigma, sigma_axisym, h_p, tau0s=TAU0S, wavelength=WAVELENGTH):
    """``{tau0: δ}`` with ``δ = I/<I>_φ − 1`` from the package's isothermal radiative transfer,
    :func:`spiralbayes.templates.radiative.template_from_perturbation` (``I = B_ν(T)(1 − e^{−τ})``,
    ``τ = τ0 Σ/Σ_0(r_p)``, ``T = T_0(x)``: no temperature perturbation).

    ``dsigma`` must be finite; ``sigma_axisym`` is ``<Σ>_φ/Σ_0(r_p)`` (the gap, if any, enters here).
    """
    from spiralbayes.templates.radiative import template_from_perturbation

    out = {}
    for tau0 in tau0s:
        tmpl = template_from_perturbation(
            x, phi, dsigma, float(tau0), sigma_axisym=np.asarray(sigma_axisym, float), hand="R",
            h_p=h_p, flaring=FLARING, sigma_slope=SIGMA_SLOPE, wavelength=wavelength, mstar=MSTAR,
            r_p_au=R_P_AU, mu=MU_GAS, store_brightness=False,
        )
        out[float(tau0)] = np.asarray(tmpl.delta, dtype=np.float32)
    return out


def linear_wake_phase(x, h_p: float, flaring: float = FLARING) -> np.ndarray:
    """Linear wake ridge (Rafikov 2002 eq. 44), hand R, from the package (``wake_shape``)."""
    from spiralbayes.templates.wake import wake_shape

    return wake_shape(np.asarray(x, float), h_p=h_p, flaring=flaring, hand="R")


def wrap(a):
    """Wrap angles into ``[-π, π)``."""
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi


def diagnostics(x, phi, dsigma, h_p, valid=None, probes=(0.7, 0.8, 1.2, 1.5)) -> dict:
    """Peak δΣ/Σ and the azimuth of the maximum at a few radii, against the linear wake.

    For each probe radius (nearest grid radius): ``peak`` = max over φ of δΣ/Σ, ``phi_peak``
    [deg], ``phi_linear`` [deg] = linear ridge wrapped into [-180, 180), and ``offset`` [deg] =
    wrap(phi_peak − phi_linear) (> 0: the density maximum lies ahead of the linear ridge in the
    direction of rotation).
    """
    out = {}
    lin = linear_wake_phase(x, h_p)
    for xp in probes:
        i = int(np.argmin(np.abs(np.log(x / xp))))
        if valid is not None and not valid[i]:
            continue
        row = dsigma[i]
        j = int(np.argmax(row))
        pitch, pitch_lin = ridge_pitch(x, phi, dsigma, i, j, h_p)
        out[f"x={xp:g}"] = {
            "x": round(float(x[i]), 4),
            "peak": round(float(row[j]), 4),
            "trough": round(float(row.min()), 4),
            "phi_peak_deg": round(float(np.degrees(phi[j])), 2),
            "phi_linear_deg": round(float(np.degrees(wrap(lin[i]))), 2),
            "offset_deg": round(float(np.degrees(wrap(phi[j] - lin[i]))), 2),
            "pitch_deg": round(pitch, 2),
            "pitch_linear_deg": round(pitch_lin, 2),
        }
    return out


def track_arms(x, phi, dsigma, h_p, valid=None, start: float = 3.0, window_deg: float = 12.0):
    """Follow the primary outer and inner arms outwards/inwards from ``x = 1 ± start·h_p``.

    At each radius the ridge is predicted from the previous one with the linear-wake slope
    ``dφ/dx = −|x^{-3/2} − 1| x^q / h_p`` and corrected to the δΣ/Σ maximum within
    ±``window_deg``. Returns ``(index, peak, phi)`` arrays sorted by x (both arms together).
    """
    n_phi = phi.size
    dphi = 2.0 * np.pi / n_phi
    win = max(1, int(round(np.radians(window_deg) / dphi)))
    q = 0.5 - FLARING
    ok = np.ones(x.size, bool) if valid is None else np.asarray(valid, bool)
    idx, peaks, phis = [], [], []
    for sign in (+1, -1):
        i = int(np.argmin(np.abs(x - (1.0 + sign * start * h_p))))
        # seed: the maximum within ±90° of the linear ridge
        lin = linear_wake_phase(x[i:i + 1], h_p)[0]
        j0 = int(round((wrap(lin) + np.pi) / dphi)) % n_phi
        cand = (j0 + np.arange(-n_phi // 4, n_phi // 4 + 1)) % n_phi
        j = int(cand[np.argmax(dsigma[i, cand])])
        phi_cur = phi[0] + j * dphi
        while 0 <= i < x.size and ok[i]:
            idx.append(i)
            peaks.append(float(dsigma[i, j]))
            phis.append(float(wrap(phi_cur)))
            k = i + sign
            if not (0 <= k < x.size):
                break
            slope = -abs(x[i] ** -1.5 - 1.0) * x[i] ** q / h_p
            pred = phi_cur + slope * (x[k] - x[i])
            jp = int(np.round((pred - phi[0]) / dphi))
            cand = (jp + np.arange(-win, win + 1)) % n_phi
            j = int(cand[np.argmax(dsigma[k, cand])])
            phi_cur = pred + wrap(phi[j] - pred)
            i = k
    order = np.argsort(x[idx])
    return np.asarray(idx)[order], np.asarray(peaks)[order], np.asarray(phis)[order]


def arm_steadiness(x, phi, d_new, d_old, h_p, valid, x_lo=0.5, x_hi=2.0) -> dict:
    """Compare the primary arms of two maps: median relative change of the ridge peak δΣ/Σ and
    median |change| of the ridge azimuth [deg] over ``x_lo <= x <= x_hi``."""
    i1, p1, f1 = track_arms(x, phi, d_new, h_p, valid)
    i0, p0, f0 = track_arms(x, phi, d_old, h_p, valid)
    common = np.intersect1d(i1, i0)
    common = common[(x[common] >= x_lo) & (x[common] <= x_hi)]
    a = {i: (p, f) for i, p, f in zip(i1, p1, f1)}
    b = {i: (p, f) for i, p, f in zip(i0, p0, f0)}
    dp = np.array([abs(a[i][0] - b[i][0]) / abs(a[i][0]) for i in common])
    df = np.array([abs(np.degrees(wrap(a[i][1] - b[i][1]))) for i in common])
    return {"arm_peak_median_rel_change": round(float(np.median(dp)), 4),
            "arm_peak_p90_rel_change": round(float(np.percentile(dp, 90)), 4),
            "arm_phase_median_abs_change_deg": round(float(np.median(df)), 2),
            "arm_phase_p90_abs_change_deg": round(float(np.percentile(df, 90)), 2),
            "n_radii": int(common.size)}


def ridge_pitch(x, phi, dsigma, i, j, h_p, half_width: float = 0.04, window_deg: float = 20.0):
    """Pitch angle [deg] of the density ridge through grid cell ``(i, j)``, and that of the linear
    wake there: the ridge is followed by the local maximum (within ±``window_deg`` of the previous
    radius's) over ``|ln x − ln x_i| < half_width``; ``tan(pitch) = 1/(x |dφ/dx|)`` from a
    straight-line fit of the unwrapped ridge azimuth against x."""
    n_phi = phi.size
    win = max(1, int(round(np.radians(window_deg) / (2 * np.pi / n_phi))))
    sel = np.nonzero(np.abs(np.log(x / x[i])) < half_width)[0]
    ridge = {i: float(phi[j])}
    for step in (1, -1):
        jj = j
        k = i + step
        while k in sel:
            idx = (jj + np.arange(-win, win + 1)) % n_phi
            jj = int(idx[np.argmax(dsigma[k, idx])])
            ridge[k] = float(phi[jj])
            k += step
    ks = np.array(sorted(ridge))
    ph = np.unwrap(np.array([ridge[k] for k in ks]))
    slope = np.polyfit(x[ks], ph, 1)[0] if ks.size >= 3 else np.nan
    q = 0.5 - FLARING
    slope_lin = -abs(x[i] ** -1.5 - 1.0) * x[i] ** q / h_p
    pitch = float(np.degrees(np.arctan(1.0 / (x[i] * abs(slope))))) if np.isfinite(slope) and slope else float("nan")
    return pitch, float(np.degrees(np.arctan(1.0 / (x[i] * abs(slope_lin)))))


def check_orientation(x, phi, dsigma, h_p) -> dict:
    """Hand-R check: the δΣ/Σ maximum just outside the planet (x ≈ 1 + 3h_p) lies at φ < 0 and
    just inside (x ≈ 1 − 3h_p) at φ > 0. Returns the azimuths [deg]; raises if the sense is wrong."""
    res = {}
    for name, xp, sign in (("outer", 1.0 + 3.0 * h_p, -1.0), ("inner", 1.0 - 3.0 * h_p, 1.0)):
        i = int(np.argmin(np.abs(x - xp)))
        phi_max = float(phi[int(np.argmax(dsigma[i]))])
        res[name] = {"x": float(x[i]), "phi_max_deg": float(np.degrees(phi_max))}
        if np.sign(phi_max) != sign or abs(phi_max) > np.pi / 2:
            raise RuntimeError(
                f"orientation check failed: {name} arm at x = {x[i]:.3f} peaks at φ = "
                f"{np.degrees(phi_max):.1f} deg, expected sign {sign:+.0f} (hand R, trailing)"
            )
    return res


def git_state() -> dict:
    def _git(*args):
        try:
            return subprocess.run(["git", "-C", str(REPO), *args], capture_output=True, text=True,
                                  check=True).stdout.strip()
        except Exception:  # pragma: no cover - outside a checkout
            return "unknown"

    # dirty: the scripts themselves differ from the commit (docs do not count)
    return {"repo_commit": _git("rev-parse", "HEAD"),
            "repo_dirty": bool(_git("status", "--porcelain", "--", "tools/*.py", "tools/fargo3d"))}


def utc_now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat()


def _attr(v):
    if isinstance(v, (dict, list, tuple)) and not (isinstance(v, (list, tuple)) and v and all(
            isinstance(e, (int, float)) and not isinstance(e, bool) for e in v)):
        return json.dumps(v)
    if v is None:
        return "none"
    return v


def write_reference_file(path, root_attrs: dict, x, phi, cases: dict, x_attrs: dict | None = None):
    """Write one reference HDF5 file atomically (temporary file, then rename).

    ``cases``: ``{name: {"datasets": {name: array}, "attrs": {...}}}``; 2-D float arrays are stored
    as gzip-9 + shuffle float32, 1-D ones as given.
    """
    import h5py

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    with h5py.File(tmp, "w") as f:
        for k, v in root_attrs.items():
            f.attrs[k] = _attr(v)
        dx = f.create_dataset("x", data=np.asarray(x, np.float64))
        dx.attrs["description"] = "r/r_p, radial cell centres (log-spaced)"
        for k, v in (x_attrs or {}).items():
            dx.attrs[k] = _attr(v)
        dp = f.create_dataset("phi", data=np.asarray(phi, np.float64))
        dp.attrs["description"] = ("azimuth [rad], -pi + 2 pi k/n_phi, planet at phi = 0, hand R "
                                   "(planet moves towards +phi, trailing arms)")
        for name, case in cases.items():
            g = f.create_group(name)
            for k, v in case["attrs"].items():
                g.attrs[k] = _attr(v)
            for dname, arr in case["datasets"].items():
                arr = np.asarray(arr)
                if arr.ndim == 2:
                    ds = g.create_dataset(dname, data=arr.astype(np.float32), compression="gzip",
                                          compression_opts=9, shuffle=True)
                else:
                    ds = g.create_dataset(dname, data=arr)
                for k, v in case.get("dataset_attrs", {}).get(dname, {}).items():
                    ds.attrs[k] = _attr(v)
    os.replace(tmp, path)
    return path
