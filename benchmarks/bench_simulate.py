"""Synthetic observations: the preset table, timings and the convergence of the rendered model.

Run: ``python benchmarks/bench_simulate.py`` (about half a minute on 2 cores).

1. Preset table (Stevenson et al. 2024, Table 1): configurations, time on source, N, 6 ln N beside
   the paper's value, nominal resolution and the fitted natural-weighted beam, requested,
   radiometer-predicted and measured (dirty-image RMS) noise.
2. Timings of the coverage and of ``simulate_observation`` per preset (median of 3).
3. Convergence of the rendered parts with pixel size and supersampling: the whole power-law disc
   rendered vs its exact Hankel transform, and the perturbation part ``I delta`` of a spiral
   template (``templates.make_template``, if available) vs a 1-mas, 5x5 reference, as relative
   errors of ``sum w |Delta V|^2`` (the quantity that sets Delta chi^2).
"""

from __future__ import annotations

import time

import numpy as np

from spiralbayes.geometry import DiscGeometry
from spiralbayes.simulate import (
    PRESETS,
    DiscModel,
    disc_visibilities,
    hankel_visibilities,
    preset_table,
    simulate_observation,
)


def _median_time(fn, repeat=3):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times))


def print_preset_table():
    t = time.perf_counter()
    rows = preset_table()
    elapsed = time.perf_counter() - t
    head = (f"{'preset':17s} {'configs':8s} {'lam':>5s} {'t_src':>6s} {'N':>7s} {'6lnN':>6s} "
            f"{'paper':>5s} {'res.':>6s} {'beam (maj x min, PA)':>24s} {'req.':>6s} {'radiom.':>7s} "
            f"{'meas.':>6s}")
    print("Preset table (times in min, angles in arcsec, noise in uJy/beam)")
    print(head)
    for r in rows:
        beam = f"{r['beam']:.3f} ({r['beam_major']:.3f}x{r['beam_minor']:.3f},{r['beam_pa']:+.0f})"
        print(f"{r['name']:17s} {r['configurations']:8s} {r['wavelength_mm']:5.2f} "
              f"{r['time_on_source_min']:6.1f} {r['N']:7d} {r['6lnN']:6.2f} {r['paper_6lnN']:5.0f} "
              f"{r['resolution']:6.3f} {beam:>24s} {r['sensitivity'] * 1e6:6.1f} "
              f"{r['radiometer_noise'] * 1e6:7.1f} {r['measured_noise'] * 1e6:6.1f}")
    print(f"(table with beam fits and noise images: {elapsed:.1f} s)\n")


def print_timings():
    print("Timings (median of 3, s): coverage | simulate_observation (axisymmetric, Hankel) | with a "
          "perturbation (rendered 4 mas, 3x3)")
    def blob(r, phi):
        return 2.0 * np.exp(-0.5 * ((r * np.cos(phi) - 0.4) ** 2 + (r * np.sin(phi)) ** 2) / 0.02**2)

    for name, p in PRESETS.items():
        cov = p.coverage()
        tc = _median_time(p.coverage)
        ta = _median_time(lambda: simulate_observation(name, coverage=cov))  # noqa: B023  (timed in this iteration)
        tp = _median_time(lambda: simulate_observation(name, perturbation=blob, coverage=cov))  # noqa: B023
        print(f"  {name:17s} N={cov.n:7d}  {tc:6.3f} | {ta:6.3f} | {tp:6.3f}")
    print()


def print_convergence():
    cov = PRESETS["fiducial"].coverage()
    u, v, w = cov.u, cov.v, np.ones(cov.n)
    geom = DiscGeometry(30.0, 60.0, 0.0, 0.0)
    disc = DiscModel()
    prof = disc.profile(cov.wavelength)
    Vh = hankel_visibilities(prof, u, v, geom, disc.r_min, disc.r_max)
    norm = np.sqrt(np.sum(np.abs(Vh) ** 2))
    print("Whole power-law disc rendered (edges at 10 and 110 au) vs exact Hankel: relative RMS error")
    for pix, K, corr in [(0.008, 3, True), (0.004, 1, True), (0.004, 3, False), (0.004, 3, True),
                         (0.002, 3, True), (0.004, 5, True)]:
        t = time.perf_counter()
        Vi = disc_visibilities(u, v, prof, geom, disc.r_max, method="image",
                               pixel_size=pix, supersample=K, pixel_window_correction=corr)
        dt = time.perf_counter() - t
        err = np.sqrt(np.sum(np.abs(Vi - Vh) ** 2)) / norm
        print(f"  pixel {pix * 1e3:3.0f} mas, {K}x{K}, window correction {corr!s:5s}: {err:.2e}  "
              f"({dt:.2f} s)")

    try:
        from spiralbayes.templates import make_template
        template = make_template(1.0, 0.3, 0.0, "R")
    except Exception as exc:  # the template module is developed separately
        print(f"\n(no spiral template available: {exc!r})")
        return
    r_p, phi_p = 0.4, 1.0
    print(f"\nPerturbation part of template {template.name or 'm1 tau0.3 b0 R'} at r_p = {r_p}\", "
          f"phi_p = {phi_p}: sum|dV|^2 vs 1 mas 5x5 reference")

    def dV(pix, K, corr=True):
        return disc_visibilities(u, v, prof, geom, disc.r_max, r_min=disc.r_min, perturbation=template,
                                 r_p=r_p, phi_p=phi_p, pixel_size=pix, supersample=K,
                                 pixel_window_correction=corr) - Vh

    ref = dV(0.001, 5)
    s_ref = np.sum(w * np.abs(ref) ** 2)
    for pix, K, corr in [(0.016, 1, False), (0.008, 3, True), (0.004, 1, True), (0.004, 3, False),
                         (0.004, 3, True), (0.002, 3, True)]:
        t = time.perf_counter()
        d = dV(pix, K, corr)
        dt = time.perf_counter() - t
        rel = np.sum(w * np.abs(d) ** 2) / s_ref - 1
        diff = np.sqrt(np.sum(np.abs(d - ref) ** 2) / np.sum(np.abs(ref) ** 2))
        print(f"  pixel {pix * 1e3:3.0f} mas, {K}x{K}, corr {corr!s:5s}: sum|dV|^2 {rel:+.2e}, "
              f"rel. RMS of dV {diff:.2e}  ({dt:.2f} s)")


if __name__ == "__main__":
    print_preset_table()
    print_timings()
    print_convergence()
