"""Cost of the antenna gain solve and of one self-calibration round, against a scan of the same data.

The fiducial observation (C-4 + C-7, 36,120 visibilities, 86 antennas, 40 one-minute integrations) of
the default disc with 10 deg rms antenna phases and 5 % amplitudes (300-s coherence). Timed in one
process, in this order:

* ``solve_gains`` against the true axisymmetric model, ``phase`` and ``amplitude+phase`` at the default
  60-s interval (median of ``--repeat`` runs);
* the frank fit (paper's hyperparameters, fixed geometry) and one self-calibration round
  (``selfcal(n_iterations=1)`` from that fit: a solve and a frank refit to the corrected data);
* the scan of ``--templates`` templates of the default bank (tau0 = 3, beta = 10, H/r = 0.07, every
  morphology; the demo's selection) on the default grid, serial.

Printed: each time [s] and its ratio to the scan, and per scanned template.

    python benchmarks/bench_gains.py
    python benchmarks/bench_gains.py --templates 6 --repeat 3
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import spiralbayes as sb
from spiralbayes.calibration import selfcal, solve_gains
from spiralbayes.simulate import GainErrors, get_preset, simulate_observation

GEOMETRY = sb.DiscGeometry(30.0, 60.0)


def timed(func, repeat: int = 1):
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = func()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--templates", type=int, default=18, help="templates scanned (default 18)")
    parser.add_argument("--repeat", type=int, default=5, help="repeats of each solve (median)")
    args = parser.parse_args(argv)

    cov = get_preset("fiducial").coverage()
    truth = simulate_observation(coverage=cov, add_noise=False).V
    vis = simulate_observation(coverage=cov, seed=1, gains=GainErrors(10.0, 0.05, coherence_s=300.0, seed=1))
    t_phase, sol = timed(lambda: solve_gains(vis, truth, mode="phase"), args.repeat)
    t_amp, _ = timed(lambda: solve_gains(vis, truth, mode="amplitude+phase"), args.repeat)
    t_frank, disc = timed(lambda: sb.fit_axisymmetric(vis, GEOMETRY, progress=False))
    t_round, result = timed(lambda: selfcal(vis, model=disc, solve="phase", n_iterations=1))
    templates = list(sb.default_bank().select(tau0=3.0, beta=10.0, h_p=0.07))[: args.templates]
    t_scan, _ = timed(lambda: sb.scan(result.corrected, result.model, templates, progress=False))

    print(f"fiducial observation: {vis.n} visibilities, {sol.antennas.size} antennas, {sol.n_intervals} intervals of "
          f"{sol.interval_s:g} s; solved phase rms {sol.phase_rms_deg:.2f} deg (input 10)")
    print(f"scan of {len(templates)} templates (default grid): {t_scan:.2f} s ({t_scan / len(templates):.3f} s per "
          "template)")
    rows = [("solve_gains, phase", t_phase), ("solve_gains, amplitude+phase", t_amp), ("frank fit", t_frank),
            ("one self-calibration round (solve + frank refit)", t_round)]
    for name, t in rows:
        print(f"{name:50s} {t:8.3f} s   x{t / t_scan:.4f} of the scan   = {t / (t_scan / len(templates)):.2f} "
              "templates' scan time")


if __name__ == "__main__":
    main()
