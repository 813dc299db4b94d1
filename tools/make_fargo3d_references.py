#!/usr/bin/env python
"""Make ``tests/data/references/fargo3d_isothermal.h5``: δΣ/Σ reference maps from 2-D FARGO3D
hydrodynamics (Benítez-Llambay & Masset 2016) of a planet in an isothermal disc with
H/r = 0.07 (r/r_p)^0.25 and Σ ∝ r^-1, for M_p = 1 and 0.3 M_th (M_th = h_p³ M_*), plus the
brightness residuals δ for τ0 ∈ {0.3, 3} from the package's own radiative transfer.

Two stages (see tools/README.md)::

    # build FARGO3D (CPU) and run both simulations one after the other (hours), then reduce
    /work/venvs/refs/bin/python tools/make_fargo3d_references.py --run
    # only reduce finished (or running) simulations
    /work/venvs/refs/bin/python tools/make_fargo3d_references.py

Set-up (parameter files in tools/fargo3d/): FARGO3D's standard ``fargo`` setup unchanged
(2-D cylindrical, locally isothermal, FARGO orbital advection, Stockholm damping zones,
constant kinematic viscosity, indirect term), 640 (φ) × 238 (r, log-spaced) cells over
r ∈ [0.27, 2.8] r_p (square cells, 7.1 cells per H at r_p), damping within period ratio 1.15 of
either edge (r < 0.296 and r > 2.551), ν = 1e-6 (α = 2.0e-4 at r_p), planet on a fixed circular
orbit at r = 1 (not feeling the disc), potential softened over 0.6 H(r_p), mass ramped in over
10 orbits (MassTaper), frame corotating with the planet, 100 orbits, a field output every 5.

Reduction: δΣ/Σ = Σ/<Σ>_φ − 1 of the last output, rotated so the planet sits at φ = 0 and
interpolated (linear in ln r and in φ) onto the common reference grid; radii outside the
undamped domain are set to 0 and flagged ``valid = False``. The gas map is read with the
package's own reader (:func:`spiralbayes.templates.read_fargo3d`, fluid ``'gas'``), whose δ is
compared with ours. Steadiness: the map is compared with the outputs 10 and 20 orbits earlier.
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import reference_common as rc

HERE = Path(__file__).resolve().parent
RUNS = {  # name: (mu = M_p/M_th, h_p, reference output or None for the last)
    "spiralref_mu1_h007": (1.0, 0.07, 8),
    "spiralref_mu0.3_h007": (0.3, 0.07, 8),
}
OUTPUT_NOTES = {
    "spiralref_mu1_h007": "output 8 (40 orbits): the wake is steady from ~20 orbits (arm peak changes of "
                          "1-3 % between 20, 30 and 40 orbits); from ~45 orbits a non-steady, vortex-like "
                          "m ~ 3-5 pattern grows at the outer gap edge (x ~ 1.1-1.3) and makes the arm "
                          "amplitude fluctuate by ~10-30 %, so the map at 40 orbits is the reference and "
                          "the last output (60 orbits) is kept as dsigma_last",
    "spiralref_mu0.3_h007": "output 8 (40 orbits): the run (Ntot = 1200, 60 orbits planned) was stopped "
                            "after output 8 when the reference helper stopped, so 40 orbits is its last "
                            "output; the same time as the 1 M_th reference, whose wake is steady from ~20 "
                            "orbits (see its steadiness attribute; this run's is its own)",
}
FARGO3D_URL_DEFAULT = "/work/.mirror/FARGO3D+fargo3d/repo"   # or https://github.com/FARGO3D/fargo3d
FARGO3D_COMMIT = "f359328107f0f3ec6a8e99e623582485276f6bff"
TWO_PI = 2.0 * np.pi


# ------------------------------------------------------------------------------------ running
def build_fargo3d(fargo_dir: Path, source: str):
    if not fargo_dir.exists():
        subprocess.run(["git", "clone", source, str(fargo_dir)], check=True)
        subprocess.run(["git", "-C", str(fargo_dir), "checkout", FARGO3D_COMMIT], check=True)
    make_py = fargo_dir / "scripts/make.py"
    text = make_py.read_text()
    fixed = text.replace("for key in params.keys():", "for key in list(params.keys()):")
    if fixed != text:  # Python 3: a dict cannot change size while it is iterated
        make_py.write_text(fixed)
    subprocess.run(["make", "SETUP=fargo", "PARALLEL=0", "GPU=0"], cwd=fargo_dir, check=True,
                   stdout=subprocess.DEVNULL)
    if not (fargo_dir / "fargo3d").exists():
        raise RuntimeError(f"FARGO3D build failed in {fargo_dir}")


def run_simulation(name: str, fargo_dir: Path, runs_dir: Path):
    logs = runs_dir / "logs"
    logs.mkdir(parents=True, exist_ok=True)
    shutil.copy(HERE / "fargo3d" / f"{name}.cfg", fargo_dir / "planets" / f"{name}.cfg")
    par = (HERE / "fargo3d" / f"{name}.par").read_text()
    par = re.sub(r"(?m)^OutputDir\s+.*$", f"OutputDir\t\t{runs_dir / name}", par)
    par_path = logs / f"{name}.par"
    par_path.write_text(par)
    (logs / f"{name}.start").write_text(f"{int(time.time())}\n")
    with open(logs / f"{name}.log", "w") as log:
        subprocess.run(["nice", "-n", "10", "./fargo3d", "-m", str(par_path)], cwd=fargo_dir,
                       stdout=log, stderr=subprocess.STDOUT, check=True)
    (logs / f"{name}.end").write_text(f"{int(time.time())}\n")


# ------------------------------------------------------------------------------------ reducing
def outputs_available(run: Path) -> list[int]:
    return sorted(int(m.group(1)) for p in run.glob("gasdens*.dat")
                  if (m := re.fullmatch(r"gasdens(\d+)\.dat", p.name)))


def planet_rows(run: Path) -> np.ndarray:
    return np.loadtxt(run / "planet0.dat", ndmin=2)


def remap(field, r_c, phi_c, r_p, phi_p, x, phi):
    """``field(r, φ)`` (FARGO3D cells) at ``r = x r_p``, ``φ = φ_p + phi``: periodic-linear in φ,
    linear in ln r; NaN outside the run's radial cell centres."""
    n = phi_c.size
    dphi = TWO_PI / n
    s = ((phi_p + phi - phi_c[0]) / dphi) % n
    j0 = np.floor(s).astype(np.int64) % n
    w = s - np.floor(s)
    f_phi = (1.0 - w) * field[:, j0] + w * field[:, (j0 + 1) % n]      # (n_r_run, n_phi)
    u = np.log(x * r_p)
    lr = np.log(r_c)
    out = np.full((x.size, phi.size), np.nan)
    inside = (u >= lr[0]) & (u <= lr[-1])
    i = np.clip(np.searchsorted(lr, u[inside], side="right") - 1, 0, lr.size - 2)
    wu = ((u[inside] - lr[i]) / (lr[i + 1] - lr[i]))[:, None]
    out[inside] = (1.0 - wu) * f_phi[i] + wu * f_phi[i + 1]
    return out


def reduce_output(run: Path, n: int, x, phi, valid):
    """δΣ/Σ (zero outside ``valid``), <Σ>_φ/Σ_0(r_p), planet state and time for output ``n``."""
    from spiralbayes.templates.fargo3d import read_domain, read_field, read_planet, read_variables

    params = read_variables(run)
    phi_e, r_e = read_domain(run, params)
    phi_c, r_c = 0.5 * (phi_e[1:] + phi_e[:-1]), 0.5 * (r_e[1:] + r_e[:-1])
    sigma = read_field(run, "gas", "dens", n, params)
    sigma0 = read_field(run, "gas", "dens", 0, params)
    planet = read_planet(run, n)
    sig_ref = float(np.interp(planet["r"], r_c, sigma0.mean(axis=1)))
    on_grid = remap(sigma / sig_ref, r_c, phi_c, planet["r"], planet["phi"], x, phi)
    dsigma = np.zeros_like(on_grid)
    mean = np.ones(x.size)
    dsigma[valid], mean[valid] = rc.normalise_to_azimuthal_mean(on_grid[valid])
    rows = planet_rows(run)
    t = float(rows[rows[:, 0].astype(int) == n][-1, 8])
    return dsigma, mean, planet, t, params


def steadiness(a, b, x, valid, x_lo=0.5, x_hi=2.0, exclude=0.15):
    """RMS of (a − b) over RMS of a, over valid radii in [x_lo, x_hi] with |x − 1| > exclude."""
    sel = valid & (x >= x_lo) & (x <= x_hi) & (np.abs(x - 1) > exclude)
    return float(np.sqrt(np.mean((a[sel] - b[sel]) ** 2) / np.mean(a[sel] ** 2)))


def reader_check(run: Path, n: int, tau0: float, x, phi, delta_ref, valid):
    """Read the run with the package's reader; return (status, max |δ_reader − δ_ours|)."""
    from spiralbayes.templates import read_fargo3d

    try:
        read_fargo3d(run, n, tau0)  # default fluid 'dust1': expected to fail on a gas-only run
        default_status = "default fluid 'dust1': read (unexpected)"
    except FileNotFoundError as exc:
        default_status = f"default fluid 'dust1': FileNotFoundError ({str(exc)[:90]}...)"
    tmpl = read_fargo3d(run, n, tau0, fluid="gas", x_range=None)
    sel = valid & (x >= tmpl.x[0]) & (x <= tmpl.x[-1])
    d_reader = tmpl.evaluate(x[sel][:, None], phi[None, :], 1.0, 0.0)
    diff = np.abs(d_reader - delta_ref[sel])
    far = np.abs(x[sel] - 1.0) > 0.1
    return {"status": "read OK with fluid='gas'", "default_fluid": default_status,
            "reader_mass_Mth": float(tmpl.mass), "reader_h_p": float(tmpl.h_p),
            "max_abs_delta_difference_vs_reference_grid": float(diff.max()),
            "max_abs_delta_difference_beyond_0.1_rp_of_planet": float(diff[far].max()),
            "rms_delta_difference_over_rms_delta": float(np.sqrt(np.mean(diff**2) / np.mean(delta_ref[sel] ** 2))),
            "note": "differences come from interpolating before (ours) or after (reader) the transfer; "
                    "largest at the arm's shock front",
            "reader_grid": [int(tmpl.x.size), int(tmpl.phi.size)]}


def wall_time(runs_dir: Path, name: str):
    """Wall time (s) and state of a run from the .start/.end epoch stamps in ``runs_dir/logs``.

    A run with no ``.end`` stamp is "running" if its output directory changed in the last 10 min,
    otherwise "stopped" (killed before Ntot), timed to the modification time of its last field.
    """
    logs = runs_dir / "logs"
    try:
        start = int((logs / f"{name}.start").read_text())
    except FileNotFoundError:
        return None, "unknown"
    end_file = logs / f"{name}.end"
    if end_file.exists():
        return int(end_file.read_text()) - start, "finished"
    last = max((p.stat().st_mtime for p in (runs_dir / name).glob("gasdens*.dat")), default=time.time())
    if time.time() - last < 600:
        return int(time.time()) - start, "running"
    return int(last) - start, "stopped before Ntot (timed to its last output)"


def wall_time_to_output(runs_dir: Path, name: str, n: int):
    """Seconds from the run's start stamp to the writing of output ``n`` (its gasdens file)."""
    try:
        start = int((runs_dir / "logs" / f"{name}.start").read_text())
    except FileNotFoundError:
        return None
    return int((runs_dir / name / f"gasdens{n}.dat").stat().st_mtime) - start


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--run", action="store_true", help="build FARGO3D and run the simulations first")
    ap.add_argument("--fargo-dir", type=Path, default=Path("/work/fargo3d"))
    ap.add_argument("--fargo-source", default=FARGO3D_URL_DEFAULT)
    ap.add_argument("--runs-dir", type=Path, default=Path("/work/fargo_runs"))
    ap.add_argument("--runs", nargs="*", default=list(RUNS))
    ap.add_argument("--output", type=int, default=None, help="output number to reduce (default: last)")
    ap.add_argument("--out", type=Path, default=rc.REPO / "tests/data/references/fargo3d_isothermal.h5")
    ap.add_argument("--n-x", type=int, default=rc.N_X)
    ap.add_argument("--n-phi", type=int, default=rc.N_PHI)
    args = ap.parse_args(argv)

    if args.run:
        build_fargo3d(args.fargo_dir, args.fargo_source)
        for name in args.runs:
            run_simulation(name, args.fargo_dir, args.runs_dir)

    x, phi = rc.reference_grid(args.n_x, args.n_phi)
    cases = {}
    for name in args.runs:
        mu, h_p, n_ref = RUNS[name]
        run = args.runs_dir / name
        outs = outputs_available(run)
        n = args.output if args.output is not None else (n_ref if n_ref in outs else outs[-1])
        if n < 1:
            raise SystemExit(f"{run}: no output after the initial condition yet")
        from spiralbayes.templates.fargo3d import read_variables

        params = read_variables(run)
        dz = float(params["DAMPINGZONE"]) ** (2.0 / 3.0)
        y_min, y_max = float(params["YMIN"]), float(params["YMAX"])
        valid = (x >= y_min * dz) & (x <= y_max / dz)
        dsigma, mean, planet, t, _ = reduce_output(run, n, x, phi, valid)
        orbits = t / TWO_PI
        steady = {}
        for back in (2, 4):  # outputs every 5 orbits: 10 and 20 orbits earlier
            if n - back >= 1 and n - back in outs:
                d_old, _, _, t_old, _ = reduce_output(run, n - back, x, phi, valid)
                tag = f"orbit_{t_old / TWO_PI:.0f}"
                steady[f"rms_rel_diff_vs_{tag}"] = round(steadiness(dsigma, d_old, x, valid), 4)
                steady[f"arm_vs_{tag}"] = rc.arm_steadiness(x, phi, dsigma, d_old, h_p, valid)
                steady[f"diagnostics_{tag}"] = rc.diagnostics(x, phi, d_old, h_p, valid)
        last = outs[-1]
        d_last, later = None, {}
        if last != n:  # the run went on: keep its final state too
            d_last, _, _, t_last, _ = reduce_output(run, last, x, phi, valid)
            later = {"output": int(last), "orbits": round(t_last / TWO_PI, 2),
                     "rms_rel_diff_vs_reference_output": round(steadiness(d_last, dsigma, x, valid), 4),
                     "arm_vs_reference_output": rc.arm_steadiness(x, phi, d_last, dsigma, h_p, valid),
                     "diagnostics": rc.diagnostics(x, phi, d_last, h_p, valid)}
        orient = rc.check_orientation(x, phi, dsigma, h_p)
        sig_ax = np.where(valid, mean, x**-rc.SIGMA_SLOPE)
        deltas = {}
        for tau0, d in rc.brightness_residuals(x[valid], phi, dsigma[valid], sig_ax[valid], h_p).items():
            full = np.zeros((x.size, phi.size), np.float32)
            full[valid] = d
            deltas[tau0] = full
        reader = reader_check(run, n, rc.TAU0S[0], x, phi, deltas[rc.TAU0S[0]], valid)
        wall, state = wall_time(args.runs_dir, name)
        diag = rc.diagnostics(x, phi, dsigma, h_p, valid)
        q_planet = float(np.loadtxt(HERE / "fargo3d" / f"{name}.cfg", comments="#", usecols=2, ndmin=1)[0])
        attrs = {
            "run": name, "mu_Mth": mu, "mu_M1": 1.5 * mu, "h_p": h_p,
            "q_planet": q_planet, "q_cs": 0.5 - float(params["FLARINGINDEX"]),
            "p_sigma": float(params["SIGMASLOPE"]), "flaring": float(params["FLARINGINDEX"]),
            "aspect_ratio": float(params["ASPECTRATIO"]), "nu": float(params["NU"]),
            "alpha_at_rp": float(params["NU"]) / h_p**2,
            "nx_phi": int(params["NX"]), "ny_r": int(params["NY"]), "spacing": str(params["SPACING"]),
            "ymin": y_min, "ymax": y_max, "damping_zone_period_ratio": float(params["DAMPINGZONE"]),
            "tau_damp": float(params["TAUDAMP"]), "mass_taper_orbits": float(params["MASSTAPER"]) / TWO_PI,
            "thickness_smoothing_H": float(params["THICKNESSSMOOTHING"]),
            "frame": str(params["FRAME"]), "indirect_term": str(params["INDIRECTTERM"]),
            "eos": "locally isothermal (FARGO3D -DISOTHERMAL)", "setup": "fargo (FARGO3D standard, unchanged)",
            "parameter_file": f"tools/fargo3d/{name}.par", "planet_file": f"tools/fargo3d/{name}.cfg",
            "output": int(n), "orbits": round(orbits, 2), "planet_r": planet["r"], "planet_phi": planet["phi"],
            "run_state": state, "wall_time_s": wall,
            "wall_time_to_reference_output_s": wall_time_to_output(args.runs_dir, name, n),
            "valid_x_min": float(x[valid].min()), "valid_x_max": float(x[valid].max()),
            "outside_valid": "dsigma and delta set to 0 (damping zones / outside the run)",
            "steadiness": steady, "orientation_check": orient, "diagnostics": diag,
            "last_output": later or "the reference output is the run's last",
            "output_choice": OUTPUT_NOTES.get(name, "the run's last output"),
            "package_reader": reader, "tau0": list(deltas),
        }
        datasets = {"dsigma": dsigma, "sigma_axisym": np.where(valid, mean, np.nan).astype(np.float32),
                    "valid": valid}
        for tau0, d in deltas.items():
            datasets[f"delta_tau{tau0:g}"] = d
        if d_last is not None:
            datasets["dsigma_last"] = d_last
        cases[f"h{h_p:.2f}_mu{mu:g}"] = {"datasets": datasets, "attrs": attrs, "dataset_attrs": {
            "dsigma": {"description": "Sigma/<Sigma>_phi - 1 of the gas (zero azimuthal mean per x); 0 where not "
                                      "valid"},
            "dsigma_last": {"description": "Sigma/<Sigma>_phi - 1 at the run's last output (see attribute "
                                           "last_output); 0 where not valid"},
            "sigma_axisym": {"description": "<Sigma>_phi / Sigma_0(r_p) (the gap); NaN where not valid"},
            "valid": {"description": "x inside the undamped domain of the run"},
            **{f"delta_tau{t:g}": {"description": f"I/<I>_phi - 1 for tau0 = {t:g}, isothermal, gap included "
                                   "through tau; spiralbayes.templates.radiative.template_from_perturbation"}
               for t in deltas},
        }}
        print(f"{name}: output {n} ({orbits:.1f} orbits, {state}, wall {wall} s); orientation {orient}")
        print(f"    steadiness {({k: v for k, v in steady.items() if not k.startswith('diag')})}")
        print(f"    reader: {reader}")
        for k, v in diag.items():
            print(f"    {k}: {v}")
    fargo_commit = "unknown"
    if args.fargo_dir.exists():
        fargo_commit = subprocess.run(["git", "-C", str(args.fargo_dir), "rev-parse", "HEAD"],
                                      capture_output=True, text=True).stdout.strip()
    root = {
        "title": "FARGO3D hydrodynamic reference maps (isothermal gas) for spiralbayes issue 9",
        "source": f"FARGO3D commit {fargo_commit} (github.com/FARGO3D/fargo3d), setup 'fargo', "
                  "CPU build (PARALLEL=0 GPU=0); scripts/make.py patched for Python 3 "
                  "(iterate over list(params.keys()))",
        "created_utc": rc.utc_now(), "script": "tools/make_fargo3d_references.py", **rc.git_state(),
        "numpy_version": np.__version__, "python_version": sys.version.split()[0],
        "conventions": "x = r/r_p; phi in [-pi, pi), planet at phi = 0; hand R (FARGO3D's planet and "
                       "gas move towards +phi; trailing arms: outer arm at phi < 0 just outside r_p)",
        "mass_conventions": "mu_Mth = M_p/M_th, M_th = h_p^3 M_* (q_planet = mu h_p^3); "
                            "mu_M1 = M_p/M_1 = 1.5 mu_Mth (M_1 = (2/3) h_p^3 M_*)",
        "radiative_transfer": "spiralbayes.templates.radiative.template_from_perturbation, isothermal, "
                              "tau = tau0 Sigma/Sigma_0(r_p) with the run's own gap, M_* = 0.8 Msun, "
                              f"r_p = 50 au, wavelength {rc.WAVELENGTH} m",
        "grid": f"n_x = {x.size} log-spaced cell centres in [{rc.X_MIN}, {rc.X_MAX}] (edges), "
                f"n_phi = {phi.size}, phi_k = -pi + 2 pi k/n_phi",
        "beta_cooling": "not run: the public FARGO3D has no thermal-relaxation (beta) cooling option",
        "dust": "not run: gas only (dust follows gas for St <~ 0.1)",
        "cases": list(cases),
    }
    path = rc.write_reference_file(args.out, root, x, phi, cases)
    print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB)")


if __name__ == "__main__":
    main()
