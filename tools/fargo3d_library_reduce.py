#!/usr/bin/env python
"""Reduce the FARGO3D library runs (tools/fargo3d_library_cases.py) into
``tests/data/references/fargo3d_library.h5``, in the layout of ``fargo3d_isothermal.h5``
(tools/README.md).

Per case: δΣ/Σ of the fluid the continuum sees (gas; dust1 for the dust case, whose gas map is
kept as ``dsigma_gas``) at the run's last output, rotated so the planet sits at φ = 0 and
interpolated onto the common reference grid; ``delta_tau{0.1,0.3,1,3}`` from the package's
radiative transfer, with the temperature perturbation T/T_0(r) from the run's own energy field for
β = 10 (``dtemp`` = T/T_0 − 1, T ∝ e/Σ, T_0 the initial profile); steadiness against the outputs
5 and 10 orbits earlier; arm RMS, near-planet peak, the package reader's check; wall time and
whether the run had finished (a running run is reduced at its latest output and marked
``run_state = running``). Root attribute ``beta_cooling_test``: the unperturbed-disc relaxation
test (decay rate of the temperature excess against Ω/β).

    python tools/fargo3d_library_reduce.py [--runs-dir /work/fargo_runs] [--min-output 2] [--cases NAME ...]
"""

from __future__ import annotations

import argparse
import json
import logging
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(1, str(Path(__file__).resolve().parents[1]))  # tests.templates.fidelity (beam smoothing)
import fargo3d_library_cases as lib
import make_fargo3d_references as ref3
import reference_common as rc
from spiralbayes.templates.learned.training import MAX_CHANGE  # the training set's quasi-steady rule

TAU0S = (0.1, 0.3, 1.0, 3.0)
QUANTUM = 2.0**-17   # maps are rounded to multiples of this (7.6e-6) before gzip: 3x smaller files
# run sets stored coarser, to keep the repository's reference files small: 2^-14 (6.1e-5, rounding
# noise 1.8e-5 RMS, < 0.1 % of any arm RMS) makes a dust case 0.45 MB instead of 0.57 MB
QUANTUM_BY_BATCH = {"dust2": 2.0**-14, "continuum": 2.0**-14}
log = logging.getLogger("fargo3d_library")


def _quantise(a: np.ndarray, quantum: float = QUANTUM) -> np.ndarray:
    """``a`` rounded to multiples of ``quantum``; a map's rows keep their sums to within half a quantum
    (the zero azimuthal mean: where a row is nearly constant, e.g. optically thick, plain rounding
    errs the same way in every cell), by moving the cells rounded furthest by one quantum."""
    a = np.asarray(a, np.float64) / quantum
    n = np.round(a)
    if a.ndim == 2:
        resid = a - n
        deficit = np.round(resid.sum(axis=1)).astype(int)
        order = np.argsort(-resid, axis=1)  # the most under-rounded cells first
        for i, k in enumerate(deficit):
            if k > 0:
                n[i, order[i, :k]] += 1
            elif k < 0:
                n[i, order[i, k:]] -= 1
    return (n * quantum).astype(np.float32)


def _params_and_grid(run: Path):
    from spiralbayes.templates.fargo3d import read_domain, read_variables

    params = read_variables(run)
    phi_e, r_e = read_domain(run, params)
    return params, 0.5 * (phi_e[1:] + phi_e[:-1]), 0.5 * (r_e[1:] + r_e[:-1])


def reduce_output(run: Path, n: int, x, phi, valid, fluid: str = "gas", temperature: bool = False) -> dict:
    """δΣ/Σ of ``fluid`` (0 outside ``valid``), <Σ>_φ/Σ_0(r_p), optionally T/T_0, planet, time."""
    from spiralbayes.templates.fargo3d import read_field, read_planet

    params, phi_c, r_c = _params_and_grid(run)
    sigma = read_field(run, fluid, "dens", n, params)
    sigma0 = read_field(run, fluid, "dens", 0, params)
    planet = read_planet(run, n)
    sig_ref = float(np.interp(planet["r"], r_c, sigma0.mean(axis=1)))
    on_grid = ref3.remap(sigma / sig_ref, r_c, phi_c, planet["r"], planet["phi"], x, phi)
    dsigma, mean = np.zeros_like(on_grid), np.ones(x.size)
    dsigma[valid], mean[valid] = rc.normalise_to_azimuthal_mean(on_grid[valid])
    out = {"dsigma": dsigma, "mean": mean, "planet": planet, "params": params,
           "near_planet_peak": near_planet_peak(sigma, phi_c, r_c, planet, float(params["ASPECTRATIO"]))}
    if temperature:
        gas = sigma if fluid == "gas" else read_field(run, "gas", "dens", n, params)
        energy = read_field(run, "gas", "energy", n, params)
        h = float(params["ASPECTRATIO"]) * r_c ** float(params["FLARINGINDEX"])
        cs0_sq = (h * r_c**-0.5) ** 2           # (h Ω r)^2 with Ω = r^-3/2 (G = M_* = 1)
        tfac = energy / gas * (float(params["GAMMA"]) - 1.0) / cs0_sq[:, None]
        t_grid = ref3.remap(tfac, r_c, phi_c, planet["r"], planet["phi"], x, phi)
        out["tfac"] = np.where(valid[:, None], t_grid, 1.0)
    rows = np.loadtxt(run / "planet0.dat", ndmin=2)
    out["t"] = float(rows[rows[:, 0].astype(int) == n][-1, 8])
    return out


def near_planet_peak(sigma, phi_c, r_c, planet, h_p: float, radius_h: float = 1.0) -> float:
    """max(Σ/<Σ>_φ − 1) on the native grid within ``radius_h`` H(r_p) of the planet."""
    rel = sigma / sigma.mean(axis=1, keepdims=True) - 1.0
    dphi = rc.wrap(phi_c[None, :] - planet["phi"])
    dist = np.hypot(r_c[:, None] * np.sin(dphi), r_c[:, None] * np.cos(dphi) - planet["r"])
    return float(rel[dist <= radius_h * h_p * planet["r"]].max())


def arm_rms(dsigma, x, valid) -> float:
    """RMS δΣ/Σ over valid 0.5 ≤ x ≤ 2 with |x − 1| > 0.15 (the arms, not the planet's vicinity)."""
    sel = valid & (x >= 0.5) & (x <= 2.0) & (np.abs(x - 1) > 0.15)
    return float(np.sqrt(np.mean(dsigma[sel] ** 2)))


def run_timing(runs_dir: Path, case: lib.Case) -> dict:
    """Wall time and state from the driver's ``.start``/``.end`` stamps and the output mtimes."""
    logs, out = runs_dir / "logs", runs_dir / case.name
    starts = [int(line.split()[0]) for line in (logs / f"{case.name}.start").read_text().split("\n") if line.strip()]
    last = max(p.stat().st_mtime for p in out.glob("gasdens*.dat"))
    if (logs / f"{case.name}.end").exists():
        end, state = int((logs / f"{case.name}.end").read_text()), "finished"
    else:
        end = int(last)
        state = "running" if time.time() - last < 900 else "stopped before Ntot"
    out_ = {"wall_time_s": int(end - starts[0]), "run_state": state, "restarts": len(starts) - 1}
    cpu = logs / f"{case.name}.cpu"  # CPU seconds per (re)start, when the driver recorded them
    if cpu.exists():
        rows = [line.split() for line in cpu.read_text().split("\n") if line.strip()]
        out_["cpu_time_s"] = round(sum(float(r[0]) for r in rows))
        out_["cpu_from_orbit"] = int(rows[0][1]) * lib.ORBITS_PER_OUTPUT  # a continued run's cost starts there
    return out_


def relaxation_test(runs_dir: Path) -> dict | str:
    """Decay rate of the mean temperature excess of the unperturbed β = 10 disc against Ω/β."""
    from spiralbayes.templates.fargo3d import read_field

    case = next(c for c in lib.CASES if c.role == "relaxtest")
    run = runs_dir / case.name
    if not (run / f"gasdens{lib.n_outputs(case)}.dat").exists():
        return "not run"
    params, _, r_c = _params_and_grid(run)
    gamma, beta = float(params["GAMMA"]), float(params["BETACOOL"])
    cs0_sq = (float(params["ASPECTRATIO"]) * r_c ** float(params["FLARINGINDEX"]) * r_c**-0.5) ** 2
    ns = np.arange(lib.n_outputs(case) + 1)
    t = ns * float(params["DT"]) * float(params["NINTERM"])
    excess = np.array([(read_field(run, "gas", "energy", n, params) / read_field(run, "gas", "dens", n, params)
                        * (gamma - 1.0) / cs0_sq[:, None]).mean(axis=1) - 1.0 for n in ns])
    res = {"setup": "spiral_beta, no planet (zero mass), e = 1.1 e_eq at t = 0, BetaCool 10, "
                    f"{case.orbits:g} orbits, {case.grid[0]} x {case.grid[1]}"}
    for r0 in (0.6, 1.0, 1.6):
        j = int(np.argmin(np.abs(r_c - r0)))
        rate = -np.polyfit(t, np.log(excess[:, j]), 1)[0]
        expect = r_c[j] ** -1.5 / beta
        res[f"r={r0:g}"] = {"r": round(float(r_c[j]), 4), "excess_t0": round(float(excess[0, j]), 5),
                            "excess_end": round(float(excess[-1, j]), 5), "fitted_rate": round(float(rate), 5),
                            "omega_over_beta": round(float(expect), 5), "ratio": round(float(rate / expect), 4)}
    return res


def equal_time_check(case: lib.Case, runs_dir: Path, n: int, x, phi, valid, dsigma) -> dict | None:
    """A numerical check run against the library set-up it repeats, at the same output (orbit).

    For the resolution check (``res14``) the 7-cells-per-H run of the same planet may be a library
    case or the longer run that starts identically (``orbits200``); whichever holds output ``n``
    is reduced at ``n`` onto the same grid, and the raw and beam-smoothed δ maps (τ0 = 0.3) are
    compared: RMS ratio (this case / the library set-up) and normalised cross-correlation.
    """
    from spiralbayes.templates import SpiralTemplate
    from tests.templates.fidelity import smoothed_image

    same = [c for c in lib.CASES if c is not case and c.role in ("library", "orbits200") and
            (c.mu, c.h_p, c.beta, c.stokes, c.softening) == (case.mu, case.h_p, case.beta, case.stokes, case.softening)]
    base = next((c for c in same if (runs_dir / c.name / f"gasdens{n}.dat").exists()), None)
    if base is None:
        return None
    ref = reduce_output(runs_dir / base.name, n, x, phi, valid)["dsigma"]
    sig = x**-rc.SIGMA_SLOPE
    maps = [np.zeros((x.size, phi.size)) for _ in range(2)]
    for m, d in zip(maps, (ref, dsigma)):
        m[valid] = brightness(x[valid], phi, d[valid], sig[valid], case.h_p, 0.3, None)
    a, b = maps[0][valid], maps[1][valid]
    sa, sb = (smoothed_image(SpiralTemplate(x=x, phi=phi, delta=m, mass=case.mu, tau0=0.3, beta=case.beta,
                                            h_p=case.h_p), 0.3) for m in maps)
    ncc = lambda u, v: float(np.sum(u * v) / np.sqrt(np.sum(u * u) * np.sum(v * v)))  # noqa: E731
    return {"against": f"{base.name} output {n} ({base.cells_per_h:g} cells per H)", "tau0": 0.3,
            "raw_rms_ratio": round(float(np.sqrt(np.mean(b**2) / np.mean(a**2))), 4), "raw_ncc": round(ncc(a, b), 4),
            "beam_rms_ratio": round(float(np.sqrt(np.sum(sb**2) / np.sum(sa**2))), 4),
            "beam_ncc": round(ncc(sa, sb), 4)}


def _orientation(x, phi, d, case: lib.Case, steady: dict) -> dict:
    """The hand check of the arms; where a vortex outshines the arm the map is not quasi-steady and the check
    is recorded as failed (the run's earlier, steady output was checked) instead of stopping the reduction."""
    try:
        return rc.check_orientation(x, phi, d, case.h_p)
    except RuntimeError as err:
        # the first entry is the change over the last 5 orbits (training.MAX_CHANGE's measure)
        change = next((v for k, v in steady.items() if k.startswith("rms_rel_diff")), 0.0)
        if change <= MAX_CHANGE:
            raise
        log.warning("%s: %s; kept, since its map is not quasi-steady (changes by %.0f%% in 5 orbits)",
                    case.name, err, 100 * change)
        return {"failed": str(err), "reason": f"not quasi-steady: changes by {change:.0%} in 5 orbits"}


def reduce_case(case: lib.Case, runs_dir: Path, x, phi, min_output: int):
    """The reduced record of one case, or None if it has fewer than ``min_output`` outputs."""
    run = runs_dir / case.name
    outs = ref3.outputs_available(run) if run.is_dir() else []
    if not outs or outs[-1] < min_output:
        return None
    n = outs[-1]
    params, _, _ = _params_and_grid(run)
    dz = float(params["DAMPINGZONE"]) ** (2.0 / 3.0)
    valid = (x >= float(params["YMIN"]) * dz) & (x <= float(params["YMAX"]) / dz)
    fluid = "dust1" if case.stokes > 0 else "gas"
    beta = case.beta > 0
    q = QUANTUM_BY_BATCH.get(case.batch, QUANTUM)
    main = reduce_output(run, n, x, phi, valid, fluid, temperature=beta)
    d = main["dsigma"]
    steady = {}
    for back in (1, 2):  # outputs every 5 orbits
        if n - back >= 1:
            old = reduce_output(run, n - back, x, phi, valid, fluid)
            tag = f"orbit_{old['t'] / lib.TWO_PI:.0f}"
            steady[f"rms_rel_diff_vs_{tag}"] = round(ref3.steadiness(d, old["dsigma"], x, valid), 4)
            steady[f"arm_vs_{tag}"] = rc.arm_steadiness(x, phi, d, old["dsigma"], case.h_p, valid)
    sig_ax = np.where(valid, main["mean"], x**-case.sigma_slope)
    tfac = main.get("tfac")
    datasets = {"dsigma": _quantise(d, q), "sigma_axisym": np.where(valid, main["mean"], np.nan).astype(np.float32),
                "valid": valid}
    for tau0 in TAU0S:
        full = np.zeros((x.size, phi.size), np.float32)
        full[valid] = brightness(x[valid], phi, d[valid], sig_ax[valid], case.h_p, tau0,
                                 None if tfac is None else tfac[valid], sigma_slope=case.sigma_slope)
        datasets[f"delta_tau{tau0:g}"] = _quantise(full, q)
    extra = {}
    if beta:
        datasets["dtemp"] = _quantise(np.where(valid[:, None], tfac - 1.0, 0.0), q)
        extra["dtemp_rms_over_dsigma_rms"] = round(arm_rms(tfac - 1.0, x, valid) / arm_rms(d, x, valid), 4)
    if case.stokes > 0:
        gas = reduce_output(run, n, x, phi, valid, "gas")
        datasets["dsigma_gas"] = _quantise(gas["dsigma"], q)
        extra["dust_over_gas_arm_rms"] = round(arm_rms(d, x, valid) / arm_rms(gas["dsigma"], x, valid), 4)
        extra["diagnostics_gas"] = rc.diagnostics(x, phi, gas["dsigma"], case.h_p, valid)
    if case.role == "res14":
        check = equal_time_check(case, runs_dir, n, x, phi, valid, d)
        if check is not None:
            extra["equal_time_check"] = check
    reader = reader_check(run, n, fluid, x, phi, datasets["delta_tau0.3"], valid, beta)
    timing = run_timing(runs_dir, case)
    orbits = main["t"] / lib.TWO_PI
    p = params
    attrs = {
        "run": case.name, "batch": case.batch,
        "variant": case.group.split("_", 2)[2] if case.group.count("_") >= 2 else "",
        "mu_Mth": case.mu, "mu_M1": 1.5 * case.mu, "h_p": case.h_p, "q_planet": case.q_planet,
        "beta": case.beta, "stokes": case.stokes, "dust_to_gas": 0.01 if case.stokes else 0.0,
        "gamma": float(p.get("GAMMA", 1.0)) if beta else 1.0, "fluid": fluid, "setup": case.setup,
        "eos": "adiabatic + beta cooling (our setup spiral_beta)" if beta else "locally isothermal",
        "q_cs": 0.5 - float(p["FLARINGINDEX"]), "p_sigma": float(p["SIGMASLOPE"]), "nu": float(p["NU"]),
        "alpha_at_rp": float(p["NU"]) / case.h_p**2, "nx_phi": int(p["NX"]), "ny_r": int(p["NY"]),
        "cells_per_H": round(int(p["NX"]) * case.h_p / lib.TWO_PI, 2), "ymin": float(p["YMIN"]),
        "ymax": float(p["YMAX"]), "damping_zone_period_ratio": float(p["DAMPINGZONE"]),
        "tau_damp": float(p["TAUDAMP"]), "mass_taper_orbits": float(p["MASSTAPER"]) / lib.TWO_PI,
        "thickness_smoothing_H": float(p["THICKNESSSMOOTHING"]), "frame": str(p["FRAME"]),
        "parameter_file": f"written by tools/fargo3d_library_cases.py (case {case.name})",
        "output": int(n), "orbits": round(orbits, 2), "orbits_planned": case.orbits,
        "complete": bool(n >= lib.n_outputs(case)), **timing,
        "wall_time_per_orbit_s": round(timing["wall_time_s"] / max(orbits, 1e-9), 1),
        **({"cpu_time_per_orbit_s": round(timing["cpu_time_s"] / max(orbits - timing["cpu_from_orbit"], 1e-9), 1)}
           if "cpu_time_s" in timing else {}),
        "valid_x_min": float(x[valid].min()), "valid_x_max": float(x[valid].max()),
        "outside_valid": "maps set to 0 (damping zones / outside the run)",
        "steadiness": steady, "arm_rms": round(arm_rms(d, x, valid), 5),
        "near_planet_peak": round(main["near_planet_peak"], 4),
        "near_planet_peak_def": "max Sigma/<Sigma>_phi - 1 within 1 H(r_p) of the planet, native grid",
        "orientation_check": _orientation(x, phi, d, case, steady),
        "diagnostics": rc.diagnostics(x, phi, d, case.h_p, valid), "package_reader": reader,
        "tau0": list(TAU0S), "quantisation": f"maps rounded to multiples of 2^{np.log2(q):.0f} = {q:.3g}", **extra,
    }
    return case.group, {"datasets": datasets, "attrs": attrs, "dataset_attrs": dataset_docs(fluid, beta)}


def brightness(x, phi, dsigma, sig_ax, h_p, tau0, tfac, sigma_slope: float = rc.SIGMA_SLOPE):
    """δ = I/<I>_φ − 1 from the package's transfer (T = T_0(x)·tfac; tfac None: isothermal; the disc's
    initial Σ ∝ x^-sigma_slope)."""
    from spiralbayes.templates.radiative import template_from_perturbation

    tmpl = template_from_perturbation(
        x, phi, dsigma, float(tau0), temperature_factor=tfac, sigma_axisym=np.asarray(sig_ax, float),
        hand="R", h_p=h_p, flaring=rc.FLARING, sigma_slope=sigma_slope, wavelength=rc.WAVELENGTH,
        mstar=rc.MSTAR, r_p_au=rc.R_P_AU, mu=rc.MU_GAS, store_brightness=False)
    return np.asarray(tmpl.delta, np.float32)


def reader_check(run: Path, n: int, fluid: str, x, phi, delta_ref, valid, adiabatic: bool) -> dict:
    """Read the run with :func:`spiralbayes.templates.read_fargo3d` (τ0 = 0.3) and compare δ."""
    from spiralbayes.templates import read_fargo3d

    tmpl = read_fargo3d(run, n, 0.3, fluid=fluid, x_range=None, eos="adiabatic" if adiabatic else "auto")
    sel = valid & (x >= tmpl.x[0]) & (x <= tmpl.x[-1])
    diff = np.abs(tmpl.evaluate(x[sel][:, None], phi[None, :], 1.0, 0.0) - delta_ref[sel])
    return {"status": f"read OK with fluid={fluid!r}", "reader_mass_Mth": round(float(tmpl.mass), 4),
            "rms_delta_difference_over_rms_delta":
                round(float(np.sqrt(np.mean(diff**2) / np.mean(delta_ref[sel] ** 2))), 4),
            "max_abs_delta_difference": round(float(diff.max()), 4)}


def dataset_docs(fluid: str, beta: bool) -> dict:
    t = "with T/T_0 from the run's energy field" if beta else "isothermal (T = T_0(r))"
    docs = {"dsigma": {"description": f"Sigma/<Sigma>_phi - 1 of {fluid}; 0 where not valid"},
            "sigma_axisym": {"description": f"<Sigma>_phi / Sigma_0(r_p) of {fluid}; NaN where not valid"},
            "valid": {"description": "x inside the undamped domain of the run"},
            "dsigma_gas": {"description": "Sigma/<Sigma>_phi - 1 of the gas (dust run)"},
            "dtemp": {"description": "T/T_0(r) - 1, T = (gamma - 1) e / Sigma, T_0 the initial profile"}}
    for tau0 in TAU0S:
        docs[f"delta_tau{tau0:g}"] = {"description": f"I/<I>_phi - 1 for tau0 = {tau0:g}, {t}; "
                                      "spiralbayes.templates.radiative.template_from_perturbation"}
    return docs


def existing_cases(path: Path, reduced_now: set) -> tuple[dict, str | None]:
    """The cases of an existing library file that were not reduced now, as written, and its β test.

    Raw FARGO3D outputs are large and kept outside git, so a later session (another machine) may hold
    only the runs it made; the cases reduced earlier are carried over unchanged (their attributes,
    including wall time and run state, describe the run that made them).
    """
    import h5py

    if not path.exists():
        return {}, None
    kept = {}
    with h5py.File(path, "r") as f:
        relax = f.attrs.get("beta_cooling_test")
        for name in f:
            if not isinstance(f[name], h5py.Group) or name in reduced_now:
                continue
            g = f[name]
            kept[name] = {"datasets": {k: g[k][()] for k in g},
                          "attrs": {k: _plain(v) for k, v in g.attrs.items()},
                          "dataset_attrs": {k: {a: _plain(v) for a, v in g[k].attrs.items()} for k in g}}
            log.info("%s: kept from %s (no raw outputs reduced now)", name, path.name)
    return kept, (None if relax is None else str(relax))


def _plain(v):
    """An HDF5 attribute value as written (JSON strings stay strings; NumPy scalars become Python)."""
    if isinstance(v, bytes):
        return v.decode()
    return v.item() if isinstance(v, np.generic) else v


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs-dir", type=Path, default=Path("/work/fargo_runs"))
    ap.add_argument("--fargo-dir", type=Path, default=Path("/work/fargo3d"))
    ap.add_argument("--min-output", type=int, default=2, help="skip runs with fewer outputs (5 orbits each)")
    ap.add_argument("--out", type=Path, default=rc.REPO / "tests/data/references/fargo3d_library.h5")
    ap.add_argument("--cases", nargs="*", default=None,
                    help="reduce only these runs (names of tools/fargo3d_library_cases.py; default all found)")
    ap.add_argument("--replace", action="store_true",
                    help="write only the cases reduced now (default: keep the file's other cases, whose raw "
                         "outputs may live on another machine)")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    x, phi = rc.reference_grid()
    cases = {}
    unknown = set(args.cases or ()) - set(lib.BY_NAME)
    if unknown:
        raise SystemExit(f"--cases: unknown {sorted(unknown)}; known: {list(lib.BY_NAME)}")
    for case in lib.CASES:
        if case.role == "relaxtest" or (args.cases is not None and case.name not in args.cases):
            continue
        rec = reduce_case(case, args.runs_dir, x, phi, args.min_output)
        if rec is None:
            log.info("%s: no usable output yet", case.name)
            continue
        cases[rec[0]] = rec[1]
        a = rec[1]["attrs"]
        log.info("%s: output %d (%.1f orbits, %s, %s s), arm rms %.4f, near-planet peak %.3f, steady %s",
                 rec[0], a["output"], a["orbits"], a["run_state"], a["wall_time_s"], a["arm_rms"],
                 a["near_planet_peak"], {k: v for k, v in a["steadiness"].items() if k.startswith("rms")})
    kept, kept_relax = ({}, None) if args.replace else existing_cases(args.out, set(cases))
    cases = {**kept, **cases}
    cases = {g: cases[g] for g in [c.group for c in lib.CASES if c.group in cases] + sorted(set(cases) - {
        c.group for c in lib.CASES})}
    relax = relaxation_test(args.runs_dir)
    if relax == "not run" and kept_relax not in (None, "not run"):  # a file written without the test says so
        relax = json.loads(kept_relax)
    commit = subprocess.run(["git", "-C", str(args.fargo_dir), "rev-parse", "HEAD"], capture_output=True,
                            text=True).stdout.strip() or "unknown"
    root = {
        "title": "FARGO3D hydrodynamic reference library (spiralbayes issue 21)",
        "source": f"FARGO3D commit {commit} (github.com/FARGO3D/fargo3d), CPU build (PARALLEL=0 GPU=0), "
                  "setups fargo (standard), spiral_beta and spiral_dust (ours, tools/fargo3d/setups/); "
                  "scripts/make.py patched for Python 3 (iterate over list(params.keys()))",
        "created_utc": rc.utc_now(), "script": "tools/fargo3d_library_reduce.py (driver: "
                                               "tools/make_fargo3d_library.py)", **rc.git_state(),
        "numpy_version": np.__version__, "python_version": sys.version.split()[0],
        "conventions": "x = r/r_p; phi in [-pi, pi), planet at phi = 0; hand R (FARGO3D's planet and gas "
                       "move towards +phi; trailing arms: outer arm at phi < 0 just outside r_p)",
        "mass_conventions": "mu_Mth = M_p/M_th, M_th = h_p^3 M_* (q_planet = mu h_p^3); mu_M1 = 1.5 mu_Mth",
        "radiative_transfer": "spiralbayes.templates.radiative.template_from_perturbation, tau = tau0 "
                              "Sigma/Sigma_0(r_p) with the run's own gap, M_* = 0.8 Msun, r_p = 50 au, "
                              f"wavelength {rc.WAVELENGTH} m",
        "beta_cooling_test": relax,
        "cases": list(cases),
    }
    path = rc.write_reference_file(args.out, root, x, phi, cases)
    log.info("wrote %s (%.2f MB, %d cases)", path, path.stat().st_size / 1e6, len(cases))


if __name__ == "__main__":
    main()
