"""Exclusion limits and injection–recovery completeness against the scan's own time (issue 10).

Fiducial set-up (C-4 + C-7, 0.87 mm, ~1e5 visibilities, the observation of bench_scan.py), the
16 templates of the compromise bank with tau0 = 3 (4 masses x 2 cooling times x 2 hands), the paper's
grid of 25 r_p x 90 phi_p. Prints, measured in the same run:

* the scan's wall time (serial, ducc0 on 2 threads);
* the exclusion limits (every family, flags included) and their ratio to the scan;
* completeness for one family (tau0 = 3, beta = 10, right-handed): 4 masses x 25 radii x
  8 azimuths = 800 injections by the fast cross-term path, and its ratio to the scan;
* brute-force injection–recovery (plant, re-scan all 16 templates, detect) timed on a subset,
  extrapolated to the 800 injections, the speed-up of the fast path, and the largest ΔBIC
  difference between the two on that subset.

    python benchmarks/bench_limits.py              # 2 brute-force re-scans
    python benchmarks/bench_limits.py --brute 4

Each time is given as wall time and as the process's CPU time (all threads): on a shared machine
the CPU-time ratios are the steadier ones.
"""

from __future__ import annotations

import argparse
import resource
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from bench_scan import GEOMETRY, N_PHI, R_P, observation

from spiralbayes.inference.limits.recovery import completeness, completeness_brute_force
from spiralbayes.inference.limits.exclusion import compute_limits
from spiralbayes.inference.scan.run import scan
from spiralbayes.templates import compromise_bank


class Clock:
    """Wall and process CPU time of a block."""

    def __enter__(self):
        self.w0, self.c0 = time.perf_counter(), time.process_time()
        return self

    def __exit__(self, *exc):
        self.wall, self.cpu = time.perf_counter() - self.w0, time.process_time() - self.c0


def ratio(a: Clock, b: Clock) -> str:
    return f"{a.wall / b.wall:.3g} x wall, {a.cpu / b.cpu:.3g} x CPU"


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--brute", type=int, default=2, help="injections re-scanned by brute force")
    parser.add_argument("--nthreads", type=int, default=2)
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    vis, axisym = observation()
    templates = list(compromise_bank().select(tau0=3.0, h_p=0.07))
    print(f"N_vis = {vis.n}, templates = {len(templates)}, grid = {R_P.size} r_p x {N_PHI} phi_p")

    with Clock() as t_scan:
        result = scan(vis, axisym, templates, GEOMETRY, r_p=R_P, n_phi_p=N_PHI, distance=140.0, progress=False,
                      nthreads=args.nthreads)
    print(f"scan: {t_scan.wall:.1f} s wall, {t_scan.cpu:.1f} s CPU")

    with Clock() as t_excl:
        limits = compute_limits(result, resolution=0.09, axisymmetric=axisym)
    with Clock() as t_beam:
        compute_limits(result, vis=vis, axisymmetric=axisym)
    print(f"exclusion limits ({len(limits.families)} families): {1e3 * t_excl.wall:.0f} ms = {ratio(t_excl, t_scan)} "
          f"the scan; with the beam fitted to the data: {1e3 * t_beam.wall:.0f} ms = {ratio(t_beam, t_scan)}")

    family = {"tau0": 3.0, "beta": 10.0}
    with Clock() as t_comp:
        fast = completeness(vis, axisym, templates, result, family=family, n_azimuths=8, progress=False,
                            nthreads=args.nthreads)
    n_inj = fast.recovered.size
    print(f"completeness, fast path: {n_inj} injections in {t_comp.wall:.1f} s wall, {t_comp.cpu:.1f} s CPU (engine "
          f"{fast.provenance['engine_time_s']:.1f} s wall) = {ratio(t_comp, t_scan)} the scan; "
          f"{1e3 * t_comp.wall / n_inj:.0f} ms per injection")
    print("  P(recovered) by mass (mean over radii): "
          + ", ".join(f"{m:g} M_th: {p:.2f}" for m, p in zip(fast.masses, fast.probability.mean(axis=1))))

    rng = np.random.default_rng(0)
    picks = [(float(fast.masses[rng.integers(fast.masses.size)]), float(R_P[rng.integers(5, R_P.size)]))
             for _ in range(args.brute)]
    brute_wall, brute_cpu, worst = 0.0, 0.0, 0.0
    for mass, r_p in picks:
        sub = dict(family=family, masses=[mass], radii=[r_p], n_azimuths=1)
        with Clock() as t_b:
            brute = completeness_brute_force(vis, axisym, templates, result, nthreads=args.nthreads, **sub)
        brute_wall, brute_cpu = brute_wall + t_b.wall, brute_cpu + t_b.cpu
        check = completeness(vis, axisym, templates, result, progress=False, nthreads=args.nthreads, **sub)
        worst = max(worst, float(np.max(np.abs(check.delta_bic - brute.delta_bic))))
        same = bool(np.all(check.recovered == brute.recovered))
        print(f"  brute force at {mass:g} M_th, r_p = {r_p:.2f}\": Delta BIC {brute.delta_bic.ravel()[0]:.2f} "
              f"(fast {check.delta_bic.ravel()[0]:.2f}), same verdict: {same}")
    per_wall, per_cpu = brute_wall / len(picks), brute_cpu / len(picks)
    print(f"brute force: {per_wall:.1f} s wall, {per_cpu:.1f} s CPU per injection (=> {per_wall * n_inj / 60:.0f} min "
          f"wall for {n_inj}); fast path x{per_wall * n_inj / t_comp.wall:.0f} faster (wall), "
          f"x{per_cpu * n_inj / t_comp.cpu:.0f} (CPU); largest |Delta BIC| difference {worst:.2e}")
    print(f"peak memory (whole process): {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")


if __name__ == "__main__":
    main()
