#!/usr/bin/env python
"""Make ``tests/data/references/wakeflow_isothermal.h5``: independent δΣ/Σ reference maps from
wakeflow (Bollati et al. 2021; Hilder et al. 2023; https://github.com/TomHilder/wakeflow) for
H/r(r_p) ∈ {0.05, 0.07, 0.10} × M_p ∈ {0.1, 0.3, 1} M_th (M_th = h_p³ M_*, the paper's
convention), plus the brightness residuals δ for τ0 ∈ {0.3, 3} from the package's own radiative
transfer.

Run in a separate venv holding wakeflow 1.4.0 and the package (see tools/README.md)::

    /work/venvs/wakeflow/bin/python tools/make_wakeflow_references.py [--workdir /work/wf_runs]

About 30 s per model (9 models); wakeflow unpacks 1.3 GB of linear-solution tables into its
install folder on first use.

Physics set-up and conversions
------------------------------
* Disc: M_* = 0.8 M_sun, r_p = 50 au (the map is scale-free in x = r/r_p), c_s ∝ r^-q with
  q = 0.25 (H/r ∝ r^0.25), Σ ∝ r^-1. wakeflow's ``p`` is the slope of the *volume* density
  (ρ ∝ r^-p; its Σ slope is p + q − 3/2), so Σ ∝ r^-1 needs wakeflow ``p = 2.25``.
* Mass: wakeflow's thermal mass is M_1 = (2/3) h_p³ M_* (Goodman & Rafikov 2001), so
  M_p/M_1 = 1.5 M_p/M_th; the planet mass is passed in Jupiter masses, m = μ h_p³ M_* with
  astropy's M_sun/M_jup (the constants wakeflow itself uses). For μ = 1, M_p = 1.5 M_1 > M_1 and
  wakeflow prints "M_planet > M_thermal. This may break the solution."
* Isothermal: wakeflow hard-codes an adiabatic index of 5/3 in its Burgers step (C ∝ γ+1,
  δΣ/Σ = 2χ/((γ+1)g)); we override it with γ = 1 (``model_params["adiabatic_index"]``), the
  isothermal value the package's generator uses for β = 0. γ = 1 makes wakeflow's velocity
  formula divide by γ − 1, so ``use_old_vel=True`` is set (velocities are not used here).
* Orientation: ``cw_rotation=False`` (anticlockwise: the gas and planet move towards +φ),
  planet at φ = 0: the package's hand R. Checked on every map: the δΣ/Σ maximum at x = 1 + 3h_p
  lies at φ < 0 and at x = 1 − 3h_p at φ > 0, and the background v_φ > 0 (rotation towards +φ).
* What wakeflow includes: the linear wake of Bollati et al. 2021 (tabulated shearing-sheet
  solution, scaled linearly with M_p/M_1) in a box |r − r_p| < 2l, |y| < 2l around the planet
  (l = (2/3) H_p), including the planet's own local density enhancement; the outer and inner
  primary arms evolved with the inviscid Burgers equation (numerical solution, then the N-wave
  asymptote). It does NOT include the gap (δΣ/Σ is relative to the unperturbed power law),
  secondary/tertiary arms, vortices, the planet's accretion, or viscosity.
* Output: Σ/<Σ>_φ − 1 with <Σ>_φ the azimuthal mean of wakeflow's total density (so each row has
  zero mean); the unperturbed-relative mean offset is kept in ``mean_offset``. Nothing is
  zeroed or NaN-filled: wakeflow returns finite values on the whole grid. ``regime`` (per x)
  says which part of wakeflow made the value, and ``valid`` is False only where the N-wave has
  grown wider than 2π in azimuth (wakeflow's single-wake N-wave then fills the whole circle as a
  sawtooth, beyond the model's assumptions).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
import time
from pathlib import Path

import numpy as np

if not hasattr(np, "trapz"):  # NumPy >= 2.4 removed np.trapz, which wakeflow 1.4.0 calls
    np.trapz = np.trapezoid

sys.path.insert(0, str(Path(__file__).resolve().parent))
import reference_common as rc

H_PS = (0.05, 0.07, 0.10)
MUS = (0.1, 0.3, 1.0)
GAMMA_ISO = 1.0
REGIMES = {0: "linear box (|x-1| < 4h/3; wakeflow's linear solution, zero outside its azimuthal box)",
           1: "Burgers numerical solution", 2: "N-wave asymptote",
           3: "N-wave wider than 2 pi (sawtooth; beyond the single-wake model) - valid = False"}


def case_name(h_p, mu):
    h = f"{h_p:.2f}" if np.isclose(round(h_p, 2), h_p) else f"{h_p:g}"
    return f"h{h}_mu{mu:g}"


_RECORD = {"tf": [], "nonlinear": [], "patched": False}


def _capture_burgers():
    """Record wakeflow's Burgers end times and its non-linear solver objects (patched once), so
    the regime of each radius can be stated."""
    if _RECORD["patched"]:
        return _RECORD["tf"], _RECORD["nonlinear"]
    import wakeflow.non_linear_perts as nlp
    import wakeflow.wakeflow as wfw

    original = nlp._solve_burgers

    def wrapper(*args, **kwargs):
        res = original(*args, **kwargs)
        _RECORD["tf"].append(float(res[0][-1]))  # last time of the numerical solution
        return res

    class Recording(nlp._NonLinearPerts):
        def __init__(self, *a, **k):
            super().__init__(*a, **k)
            _RECORD["nonlinear"].append(self)

    nlp._solve_burgers = wrapper
    wfw._NonLinearPerts = Recording
    _RECORD["patched"] = True
    return _RECORD["tf"], _RECORD["nonlinear"]


def run_case(h_p, mu, x, phi, workdir: Path, log):
    import wakeflow
    from astropy import constants as const
    from wakeflow import WakeflowModel
    from wakeflow.transformations import _t_vector

    q = 0.5 - rc.FLARING
    p_rho = rc.SIGMA_SLOPE + 1.5 - q  # wakeflow's p: ρ ∝ r^-p, Σ ∝ r^-(p + q - 3/2)
    msun_mjup = float((const.M_sun / const.M_jup).decompose().value)
    m_th_mjup = h_p**3 * rc.MSTAR * msun_mjup
    m_planet = mu * m_th_mjup
    name = case_name(h_p, mu)
    tf_calls, instances = _capture_burgers()
    model = WakeflowModel()
    n_phi = phi.size
    model.configure(
        name=name, system=str(workdir), m_star=rc.MSTAR, m_planet=m_planet,
        r_inner=x[0] * rc.R_P_AU, r_outer=x[-1] * rc.R_P_AU, r_planet=rc.R_P_AU, r_ref=rc.R_P_AU,
        phi_planet=0.0, q=q, p=p_rho, hr=h_p, cw_rotation=False, grid_type="cylindrical",
        n_r=x.size, n_phi=n_phi + 1, n_z=1, r_log=True, make_midplane_plots=False,
        show_midplane_plots=False, dimensionless=True, save_perturbations=True, save_total=True,
    )
    model.model_params["adiabatic_index"] = GAMMA_ISO
    model.model_params["use_old_vel"] = True
    t0 = time.perf_counter()
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        model.run(overwrite=True)
    wall = time.perf_counter() - t0
    log.write(f"===== {name}\n{buf.getvalue()}\n")
    out = workdir / name / f"{m_planet}Mj"
    R = np.load(out / "R.npy")[0, 0, :]
    P = np.load(out / "PHI.npy")[:, 0, 0]
    drho = np.load(out / "delta_rho.npy")[:, 0, :]
    total = np.load(out / "total_rho.npy")[:, 0, :]
    vphi_total = np.load(out / "total_v_phi.npy")[:, 0, :]
    if not np.allclose(R, x, rtol=1e-10):
        raise RuntimeError(f"wakeflow radii differ from the reference grid (max {np.abs(R / x - 1).max():.2e})")
    if not (np.allclose(P[:-1], phi, atol=1e-12) and np.isclose(P[-1], np.pi)):
        raise RuntimeError("wakeflow azimuths differ from the reference grid")
    if not np.allclose(total[-1], total[0], rtol=1e-6, atol=1e-12):
        raise RuntimeError("wakeflow map is not periodic (φ = -π and π rows differ)")
    background = (total - drho)[:-1].T          # (n_x, n_phi), ρ0(r) at z = 0 (dimensionless)
    rel = drho[:-1].T / background              # δΣ/Σ relative to the unperturbed power law
    if not np.allclose(background[:, 0], x**-p_rho, rtol=1e-10):
        raise RuntimeError("unexpected wakeflow background density (check p)")
    if not np.all(np.isfinite(rel)):
        raise RuntimeError("wakeflow returned non-finite densities")
    rotation_positive = bool(np.all(vphi_total > 0))

    nl = instances[-1]
    tf_outer, tf_inner = tf_calls[-2], tf_calls[-1]
    t = _t_vector(x, 1.0, h_p, q, nl.p.p)
    regime = np.full(x.size, 2, dtype=np.int8)
    l_over_rp = (2.0 / 3.0) * h_p
    outer = x > 1
    t0 = np.where(outer, nl.t0_outer, nl.t0_inner)
    tf = np.where(outer, tf_outer, tf_inner)
    C = np.where(outer, nl.C_outer, nl.C_inner)
    regime[t < t0 + tf] = 1
    width = 2.0 * np.sqrt(2.0 * C * np.clip(t - t0, 0, None))
    regime[(regime == 2) & (width >= 3.0 * np.pi / h_p)] = 3
    regime[np.abs(x - 1) < 2 * l_over_rp] = 0
    params = {
        "wakeflow_version": getattr(wakeflow, "__version__", None) or _dist_version("wakeflow"),
        "h_p": h_p, "q_cs": q, "p_sigma": rc.SIGMA_SLOPE, "wakeflow_p_rho": p_rho,
        "flaring": rc.FLARING, "mu_Mth": mu, "mu_M1": 1.5 * mu,
        "M_th_Mjup": m_th_mjup, "M_1_Mjup_wakeflow": float(nl.p.m_thermal),
        "m_planet_Mjup": m_planet, "q_planet": mu * h_p**3, "mstar_Msun": rc.MSTAR,
        "r_p_au": rc.R_P_AU, "adiabatic_index_burgers": GAMMA_ISO, "use_old_vel": True,
        "cw_rotation": False, "C_outer": float(nl.C_outer), "C_inner": float(nl.C_inner),
        "t0_outer": float(nl.t0_outer), "t0_inner": float(nl.t0_inner),
        "tf_outer": float(tf_outer), "tf_inner": float(tf_inner),
        "eta_tilde_outer": float(nl.eta_tilde_outer), "eta_tilde_inner": float(nl.eta_tilde_inner),
        "linear_box_half_width_x": 2 * l_over_rp, "wall_time_s": round(wall, 1),
        "background_rotation_towards_plus_phi": rotation_positive,
        "warning": "M_p > wakeflow thermal mass M_1 (wakeflow: 'may break the solution')" if 1.5 * mu > 1 else "",
    }
    return rel, regime, params


def _dist_version(name):
    import importlib.metadata as md

    return md.version(name)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=rc.REPO / "tests/data/references/wakeflow_isothermal.h5")
    ap.add_argument("--workdir", type=Path, default=Path("/work/wf_runs"),
                    help="scratch folder for wakeflow's own outputs (kept out of git)")
    ap.add_argument("--n-x", type=int, default=rc.N_X)
    ap.add_argument("--n-phi", type=int, default=rc.N_PHI)
    ap.add_argument("--h-ps", type=float, nargs="+", default=list(H_PS), help="aspect ratios H/r at r_p")
    ap.add_argument("--mus", type=float, nargs="+", default=list(MUS), help="planet masses [M_th]")
    args = ap.parse_args(argv)

    x, phi = rc.reference_grid(args.n_x, args.n_phi)
    args.workdir.mkdir(parents=True, exist_ok=True)
    cases, summary = {}, {}
    t_start = time.perf_counter()
    with open(args.workdir / "wakeflow_runs.log", "w") as log:
        for h_p in args.h_ps:
            for mu in args.mus:
                name = case_name(h_p, mu)
                rel, regime, params = run_case(h_p, mu, x, phi, args.workdir, log)
                dsigma, mean = rc.normalise_to_azimuthal_mean(1.0 + rel)
                orient = rc.check_orientation(x, phi, dsigma, h_p)
                if not params["background_rotation_towards_plus_phi"]:
                    raise RuntimeError(f"{name}: wakeflow background v_phi is not > 0")
                sig_ax = x**-rc.SIGMA_SLOPE * mean  # <Σ>_φ / Σ_0(r_p): no gap in wakeflow
                deltas = rc.brightness_residuals(x, phi, dsigma, sig_ax, h_p)
                valid = regime != 3
                diag = rc.diagnostics(x, phi, dsigma, h_p, valid)
                datasets = {"dsigma": dsigma, "mean_offset": (mean - 1.0).astype(np.float32),
                            "regime": regime, "valid": valid}
                for tau0, d in deltas.items():
                    datasets[f"delta_tau{tau0:g}"] = d
                attrs = dict(params)
                attrs.update({
                    "orientation_check": orient, "diagnostics": diag,
                    "valid_x_min": float(x[valid].min()), "valid_x_max": float(x[valid].max()),
                    "tau0": list(deltas),
                })
                cases[name] = {"datasets": datasets, "attrs": attrs, "dataset_attrs": {
                    "dsigma": {"description": "Sigma/<Sigma>_phi - 1 (zero azimuthal mean per x)"},
                    "mean_offset": {"description": "<Sigma>_phi/Sigma_unperturbed - 1 (wakeflow has no gap)"},
                    "regime": {"description": "; ".join(f"{k}: {v}" for k, v in REGIMES.items())},
                    "valid": {"description": "x where wakeflow's single-wake model applies (regime != 3); "
                                             "values elsewhere are kept, not masked"},
                    **{f"delta_tau{t:g}": {"description": f"I/<I>_phi - 1 for tau0 = {t:g}, isothermal, "
                                           "spiralbayes.templates.radiative.template_from_perturbation"}
                       for t in deltas},
                }}
                summary[name] = {k: v for k, v in diag.items()}
                print(f"{name}: wall {params['wall_time_s']} s; orientation {orient}; "
                      f"valid x {attrs['valid_x_min']:.3f}-{attrs['valid_x_max']:.3f}", flush=True)
                for k, v in diag.items():
                    print(f"    {k}: {v}", flush=True)
    root = {
        "title": "wakeflow reference maps (isothermal) for spiralbayes issue 9 (template fidelity)",
        "source": f"wakeflow {_dist_version('wakeflow')} (PyPI; Bollati et al. 2021, Hilder et al. 2023)",
        "created_utc": rc.utc_now(), "script": "tools/make_wakeflow_references.py",
        **rc.git_state(),
        "numpy_version": np.__version__, "python_version": sys.version.split()[0],
        "conventions": "x = r/r_p; phi in [-pi, pi), planet at phi = 0; hand R (planet and gas move "
                       "towards +phi, trailing arms: outer arm at phi < 0 just outside r_p)",
        "mass_conventions": "mu_Mth = M_p/M_th with M_th = h_p^3 M_* (Stevenson et al. 2024; S22); "
                            "mu_M1 = M_p/M_1 = 1.5 mu_Mth with M_1 = (2/3) h_p^3 M_* (wakeflow)",
        "disc": "M_* = 0.8 Msun, r_p = 50 au, c_s ∝ r^-0.25 (H/r ∝ r^0.25), Sigma ∝ r^-1",
        "radiative_transfer": "spiralbayes.templates.radiative.template_from_perturbation, isothermal (no "
                              "temperature perturbation), tau = tau0 Sigma/Sigma_0(r_p), "
                              f"wavelength {rc.WAVELENGTH} m, mu_gas {rc.MU_GAS}",
        "grid": f"n_x = {x.size} log-spaced cell centres in [{rc.X_MIN}, {rc.X_MAX}] (edges), "
                f"n_phi = {phi.size}, phi_k = -pi + 2 pi k/n_phi",
        "wall_time_total_s": round(time.perf_counter() - t_start, 1),
        "cases": list(cases),
    }
    path = rc.write_reference_file(args.out, root, x, phi, cases)
    print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB)")


if __name__ == "__main__":
    main()
