#!/usr/bin/env python
"""Figures for docs/templates.md from ``tests/data/references/fargo3d_library.h5`` (issue 21):
the case table, the mass and H/r scaling of the beam-smoothed spiral power (hydro and the
built-in generator), the resolution and softening checks and the dust/gas comparison.

    PYTHONPATH=src python tools/fargo3d_library_report.py

Spiral power E = Σ S² over the face-on image S = (δ · I_axi) ⊛ beam (the fiducial 0.061″ beam at
140 pc, r_p = 50 au, disc 10–110 au; ``tests.templates.fidelity.smoothed_image``), τ0 = 0.3.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
LIB = Path(os.environ.get("SPIRALBAYES_LIBRARY", REPO / "tests/data/references/fargo3d_library.h5"))
CHECK_ROLES = ("soft0.35", "res14", "orbits200")  # group suffixes of runs that repeat a library case


def gap_depth(f, group: str) -> float:
    """<Σ>_φ/Σ_0 at the planet's radius (1: no gap), from the stored azimuthal mean."""
    x, s = f["x"][()], f[group]["sigma_axisym"][()]
    ok = np.isfinite(s)
    return float(np.interp(1.0, x[ok], s[ok]) / np.interp(1.0, x[ok], x[ok] ** -1.0))


def _template(f, group: str, tau0: float, key: str | None = None):
    from spiralbayes.templates import SpiralTemplate

    g = f[group]
    return SpiralTemplate(x=f["x"][()], phi=f["phi"][()], delta=g[key or f"delta_tau{tau0:g}"][()].astype(float),
                          mass=float(g.attrs["mu_Mth"]), tau0=tau0, beta=float(g.attrs["beta"]),
                          h_p=float(g.attrs["h_p"]))


def power(template, tau0: float = 0.3) -> float:
    """Beam-smoothed spiral power E (arbitrary units, the same for every map)."""
    from tests.templates.fidelity import smoothed_image

    s = smoothed_image(template, tau0)
    return float(np.sum(s * s))


def compare(f, a: str, b: str, tau0: float = 0.3) -> dict:
    """RMS ratio (b/a) and NCC of the raw δ maps and of their beam-smoothed images."""
    from tests.templates.fidelity import smoothed_image

    ta, tb = _template(f, a, tau0), _template(f, b, tau0)
    va = f[a]["valid"][()] & f[b]["valid"][()]
    da, db = ta.delta[va], tb.delta[va]
    sa, sb = smoothed_image(ta, tau0), smoothed_image(tb, tau0)
    ncc = lambda u, v: float(np.sum(u * v) / np.sqrt(np.sum(u * u) * np.sum(v * v)))  # noqa: E731
    return {"raw_rms_ratio": float(np.sqrt(np.mean(db**2) / np.mean(da**2))), "raw_ncc": ncc(da, db),
            "beam_rms_ratio": float(np.sqrt(np.sum(sb**2) / np.sum(sa**2))), "beam_ncc": ncc(sa, sb),
            "near_planet_peak_ratio": float(f[b].attrs["near_planet_peak"] / f[a].attrs["near_planet_peak"])}


def table(f) -> str:
    rows = ["| case | grid (cells/H) | orbits | wall [min] | steadiness: Δrms vs 5 / 10 orbits earlier, arm peak Δ | "
            "arm RMS δΣ/Σ | near-planet peak | state |", "|" + "---|" * 8]
    for name in json.loads(f.attrs["cases"]):
        a = f[name].attrs
        st = json.loads(a["steadiness"])
        rms = [v for k, v in st.items() if k.startswith("rms")]
        arm = [v["arm_peak_median_rel_change"] for k, v in st.items() if k.startswith("arm")]
        rows.append(f"| {name} | {a['nx_phi']}×{a['ny_r']} ({a['cells_per_H']:.1f}) | {a['orbits']:.0f} | "
                    f"{a['wall_time_s'] / 60:.0f} | "
                    + (f"{' / '.join(f'{v:.3f}' for v in rms)}; {' / '.join(f'{v:.3f}' for v in arm)}" if rms else "–")
                    + f" | {a['arm_rms']:.4f} | {a['near_planet_peak']:.3f} | "
                    f"{a['run_state']} |")
    return "\n".join(rows)


def scaling(f) -> list[str]:
    from spiralbayes.templates import make_template

    out = []
    groups = json.loads(f.attrs["cases"])
    iso = [g for g in groups if f[g].attrs["variant"] == ""]
    by_h: dict[float, list] = {}
    for g in iso:
        a = f[g].attrs
        by_h.setdefault(round(float(a["h_p"]), 3), []).append((float(a["mu_Mth"]), power(_template(f, g, 0.3)), g))
    for h, rows in sorted(by_h.items()):
        rows.sort()
        gen = [power(make_template(mu, 0.3, 0.0, "R", h_p=h)) for mu, _, _ in rows]
        line = f"H/r {h:g}: " + ", ".join(f"{mu:g} M_th E = {e:.3g} (generator {eg:.3g})"
                                          for (mu, e, _), eg in zip(rows, gen))
        if len(rows) >= 2:
            lm = np.log([r[0] for r in rows])
            s_h = np.polyfit(lm, np.log([r[1] for r in rows]), 1)[0]
            s_g = np.polyfit(lm, np.log(gen), 1)[0]
            pairs = [f"{np.log(rows[i + 1][1] / rows[i][1]) / np.log(rows[i + 1][0] / rows[i][0]):.2f}"
                     for i in range(len(rows) - 1)]
            line += f"; slope d ln E/d ln M: hydro {s_h:.2f} (pairwise {', '.join(pairs)}), generator {s_g:.2f}"
        out.append(line)
    for mu in sorted({m for rows in by_h.values() for m, _, _ in rows}):
        pts = [(h, e) for h, rows in by_h.items() for m, e, _ in rows if m == mu]
        if len(pts) >= 2:
            pts.sort()
            gen = [power(make_template(mu, 0.3, 0.0, "R", h_p=h)) for h, _ in pts]
            s_h = np.polyfit(np.log([p[0] for p in pts]), np.log([p[1] for p in pts]), 1)[0]
            s_g = np.polyfit(np.log([p[0] for p in pts]), np.log(gen), 1)[0]
            out.append(f"{mu:g} M_th: E vs H/r " + ", ".join(f"{h:g}: {e:.3g}" for h, e in pts)
                       + f"; d ln E/d ln h hydro {s_h:.2f}, generator {s_g:.2f}")
    return out


def coorbital(f, group: str, key: str = "dsigma", half_width: float = 0.1, exclude_h: float = 2.0) -> float:
    """RMS of a δΣ/Σ map in the co-orbital band |x − 1| < ``half_width`` away from the planet
    (|φ| > ``exclude_h`` H(r_p)/r_p): the horseshoe region's azimuthal structure, planet excluded."""
    x, phi, g = f["x"][()], f["phi"][()], f[group]
    band = np.abs(x - 1.0) < half_width
    far = np.abs(phi) > exclude_h * float(g.attrs["h_p"])
    return float(np.sqrt(np.mean(g[key][()][band][:, far].astype(float) ** 2)))


def residual_location(f, gas: str, dust: str, tau0: float = 0.3, band: float = 0.15) -> tuple[float, float]:
    """What the beam sees of the dust that the gas run does not: the dust image minus the gas
    run's image scaled to it by least squares. Returns (residual power / dust power, the share of
    the residual power within |r − r_p| < ``band`` r_p: the co-orbital region)."""
    from tests.templates.fidelity import _image_grid, smoothed_image

    sd, sg = smoothed_image(_template(f, dust, tau0), tau0), smoothed_image(_template(f, gas, tau0), tau0)
    res = sd - np.sum(sd * sg) / np.sum(sg * sg) * sg
    r = _image_grid()[0]
    return float(np.sum(res**2) / np.sum(sd**2)), float(np.sum(res[np.abs(r - 1.0) < band] ** 2) / np.sum(res**2))


def rings(f, group: str, bands=((0.6, 0.9), (0.9, 1.1), (1.1, 1.5))) -> str:
    """Largest and smallest <Σ>_φ/Σ_initial (the stored mean over x^-1) and where, in each band:
    the dust's rings at the gap edges, its gap and its co-orbital ring."""
    x, s = f["x"][()], f[group]["sigma_axisym"][()] / f["x"][()] ** -1.0
    out = []
    for lo, hi in bands:
        m = np.isfinite(s) & (x > lo) & (x < hi)
        i, j = np.argmax(s[m]), np.argmin(s[m])
        out.append(f"{lo:g}–{hi:g} r_p: max {s[m][i]:.2f} at {x[m][i]:.2f}, min {s[m][j]:.2f} at {x[m][j]:.2f}")
    return "; ".join(out)


def dust_table(f) -> str:
    """Each dust run against its own gas and against the gas-only run of the same planet.

    Columns: arm RMS of δΣ/Σ dust/gas (the run's two fluids); gap depth <Σ>_φ/Σ_0 at r_p of the dust
    and of the gas-only run; co-orbital RMS (:func:`coorbital`) dust/gas; near-planet peak dust and
    gas-only; and at τ0 0.3 the dust δ map against the gas-only run's: raw and beam-smoothed RMS
    ratio and normalised cross-correlation (:func:`compare`), and the residual after the scaled
    gas image (:func:`residual_location`): its share of the dust image's power and the share of it
    in the co-orbital band |r − r_p| < 0.15 r_p.
    """
    rows = ["| dust run | St | arm RMS dust/gas | gap at r_p dust (gas run) | co-orbital RMS dust/gas | "
            "near-planet peak dust (gas run) | vs gas run, τ0 0.3: raw RMS ratio, NCC | beam RMS ratio, NCC | "
            "beam residual / dust power, its co-orbital share |", "|" + "---|" * 9]
    groups = json.loads(f.attrs["cases"])
    for g in groups:
        a = f[g].attrs
        if float(a["stokes"]) <= 0:
            continue
        gas = f"h{float(a['h_p']):.2f}_mu{float(a['mu_Mth']):g}" + ("_orbits200" if "orbits200" in g else "")
        c = compare(f, gas, g) if gas in groups else None
        res = residual_location(f, gas, g) if gas in groups else (float("nan"),) * 2
        co = coorbital(f, g) / coorbital(f, g, "dsigma_gas")
        rows.append(f"| {g} | {float(a['stokes']):g} | {float(a['dust_over_gas_arm_rms']):.2f} | "
                    f"{gap_depth(f, g):.3f} ({gap_depth(f, gas) if gas in groups else float('nan'):.3f}) | "
                    f"{co:.2f} | {float(a['near_planet_peak']):.2f} "
                    f"({float(f[gas].attrs['near_planet_peak']) if gas in groups else float('nan'):.2f}) | "
                    + (f"{c['raw_rms_ratio']:.2f}, {c['raw_ncc']:.2f} | "
                       f"{c['beam_rms_ratio']:.2f}, {c['beam_ncc']:.2f} |" if c else "– | – |")
                    + f" {res[0]:.2f}, {res[1]:.2f} |")
    return "\n".join(rows)


def main() -> None:
    import h5py

    with h5py.File(LIB, "r") as f:
        groups = json.loads(f.attrs["cases"])
        print(table(f))
        print()
        for line in scaling(f):
            print("-", line)
        for g in groups:  # numerical checks and longer runs against the library case they repeat
            base = max((b for b in groups if g.startswith(b + "_") and f[g].attrs["variant"].endswith(CHECK_ROLES)),
                       key=len, default=None)  # the longest prefix: a dust run's check against that dust run
            if base is not None and "equal_time_check" in f[g].attrs:  # a check run stopped early
                print(f"- {g}, at equal time: {f[g].attrs['equal_time_check']}")
            elif base is not None:
                print(f"- {g} vs {base}: {json.dumps({k: round(v, 3) for k, v in compare(f, base, g).items()})}"
                      + (f"; gap {gap_depth(f, base):.3f} -> {gap_depth(f, g):.3f}" if "orbits" in g else ""))
        for g in groups:
            a = f[g].attrs
            if float(a["beta"]) > 0:
                iso = g.split("_beta")[0]
                extra = compare(f, iso, g) if iso in groups else {}
                print(f"- {g}: δT/T rms / δΣ/Σ rms = {a['dtemp_rms_over_dsigma_rms']}; vs {iso} (τ0 0.3): "
                      f"{json.dumps({k: round(v, 3) for k, v in extra.items()})}")
                for tau0 in (0.3, 3.0):
                    e_b = power(_template(f, g, tau0), tau0)
                    e_i = power(_template(f, iso, tau0), tau0) if iso in groups else float("nan")
                    print(f"    τ0 {tau0:g}: beam power β=10 / isothermal = {e_b / e_i:.2f}")
        print("- relaxation test:", f.attrs["beta_cooling_test"])
        print()
        print(dust_table(f))
        for g in groups:
            a = f[g].attrs
            if float(a["stokes"]) > 0:
                dg, dd = json.loads(a["diagnostics_gas"]), json.loads(a["diagnostics"])
                print(f"- {g}: <Σ>_φ/Σ_initial {rings(f, g)}")
                print(f"- {g}: pitch [deg] dust/gas: "
                      + ", ".join(f"{k} {dd[k]['pitch_deg']}/{dg[k]['pitch_deg']} (φ {dd[k]['phi_peak_deg']}/"
                                  f"{dg[k]['phi_peak_deg']}, peak {dd[k]['peak']}/{dg[k]['peak']})"
                                  for k in dd if k in dg))


if __name__ == "__main__":
    main()
