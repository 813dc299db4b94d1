"""How the cost of the search grows with the number of visibilities, with and without averaging.

Each size runs in its own process (so that its peak memory is its own): a synthetic disc with a
1 M_th planet observed with the high-sensitivity preset's antennas (C-4 + C-7, 2 + 6 h on source) in
integrations short enough to give the size asked for, then the stages a user runs — [averaging],
frank, the scan of the default bank at one τ0, the verdict (test 3's alternatives included), the
limits and a short posterior — each timed, with the peak resident memory of the stage (the kernel's
high-water mark, reset before each stage through ``/proc/self/clear_refs``).

    python benchmarks/bench_scale.py                          # 1e5 and 1e6, raw and averaged
    python benchmarks/bench_scale.py --sizes 1e7 --modes avg  # the archival size, averaged
    python benchmarks/bench_scale.py --sizes 1e7 --modes raw --skip posterior

Prints one table row per (size, mode, stage) and, at the end, the growth exponent
d ln t / d ln N of each stage between consecutive sizes of the same mode.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import subprocess
import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path

STAGES = ("simulate", "average", "frank", "scan", "verdict", "limits", "posterior")
ON_SOURCE_S = (120.0 + 360.0) * 60.0
N_BASELINES = 903


def _reset_peak() -> None:
    # not Linux, or not allowed: the peak is then the process's so far
    with contextlib.suppress(OSError):
        Path("/proc/self/clear_refs").write_text("5")


def _peak_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024.0
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def run_one(n: float, mode: str, skip: set, tau0: float, steps: int) -> list[dict]:
    import numpy as np

    import spiralbayes as sb
    from spiralbayes.averaging import average_visibilities
    from spiralbayes.inference.detection.alternatives import fit_alternatives
    from spiralbayes.inference.detection.verdict import detect_with_planet_peak

    warnings.simplefilter("ignore")
    rows = []

    def stage(name, fn, describe=None):
        if name in skip:
            return None
        _reset_peak()
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        rows.append({"n": n, "mode": mode, "stage": name, "wall_s": time.perf_counter() - t0,
                     "cpu_s": time.process_time() - c0, "peak_mb": _peak_mb(), **(describe(out) if describe else {})})
        print(json.dumps(rows[-1]), flush=True)
        return out

    preset = replace(sb.PRESETS["high_sensitivity"], integration_time=ON_SOURCE_S * N_BASELINES / n)
    disc = sb.DiscModel(distance=140.0, r_ref=50.0, tau_ref=tau0)
    geometry = sb.DiscGeometry(30.0, 60.0)
    planet = sb.make_template(mass=1.0, tau0=tau0, beta=0.0, wavelength=preset.wavelength)
    def size(v):
        return {"n_vis": v.n}

    vis = stage("simulate", lambda: sb.simulate_observation(preset, disc, geometry, planet, r_p=50 / 140,
                                                            phi_p=np.radians(40.0), seed=1), size)
    if mode == "avg":
        vis = stage("average", lambda: average_visibilities(vis, "time", r_out=sb.FrankSettings().Rmax,
                                                            geometry=geometry), size)
    axisym = stage("frank", lambda: sb.fit_axisymmetric(vis, geometry, progress=False))
    templates = list(sb.default_bank().select(tau0=tau0))
    result = stage("scan", lambda: sb.scan(vis, axisym, templates, geometry, distance=140.0, progress=False),
                   lambda r: {"templates": len(templates), "best_delta_bic": float(r.best.delta_bic)})

    def verdict():
        alts = fit_alternatives(vis, axisym, geometry, progress=False)
        return detect_with_planet_peak(result, vis, axisym, templates, geometry, alternatives=alts)

    stage("verdict", verdict, lambda v: {"detected": bool(v.detected)})
    stage("limits", lambda: sb.compute_limits(result, vis=vis, axisymmetric=axisym, distance=140.0))

    def posterior():
        import tempfile

        chosen = [t for t in templates if t.name == result.best.template][:1]
        with tempfile.TemporaryDirectory() as chains:
            return sb.sample_posterior(vis, axisym, chosen, scan_result=result, n_steps=steps, n_walkers=16,
                                       chains_dir=chains, progress=False)

    stage("posterior", posterior)
    return rows


def growth(rows: list[dict]) -> list[str]:
    import math

    lines = []
    for mode in sorted({r["mode"] for r in rows}):
        for name in STAGES:
            pts = sorted((r["n"], r["wall_s"], r["cpu_s"]) for r in rows if r["mode"] == mode and r["stage"] == name)
            for (n0, w0, c0), (n1, w1, c1) in zip(pts, pts[1:]):
                if w0 > 0 and w1 > 0 and c0 > 0 and c1 > 0:
                    # CPU time follows the work done whatever else the machine runs; wall time follows the load
                    lines.append(f"{mode:4s} {name:10s} {n0:.0e} -> {n1:.0e}: exponent "
                                 f"{math.log(c1 / c0) / math.log(n1 / n0):.2f} (CPU time), "
                                 f"{math.log(w1 / w0) / math.log(n1 / n0):.2f} (wall)")
    return lines


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", nargs="+", type=float, default=[1e5, 1e6])
    ap.add_argument("--modes", nargs="+", choices=("raw", "avg"), default=["raw", "avg"])
    ap.add_argument("--skip", nargs="*", default=[], choices=STAGES)
    ap.add_argument("--tau0", type=float, default=0.3)
    ap.add_argument("--steps", type=int, default=200, help="posterior steps per walker (16 walkers)")
    ap.add_argument("--out", type=Path, default=None, help="append the rows (JSON lines) to this file")
    ap.add_argument("--one", nargs=2, metavar=("N", "MODE"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one:
        run_one(float(args.one[0]), args.one[1], set(args.skip), args.tau0, args.steps)
        return
    rows = []
    for n in args.sizes:
        for mode in args.modes:
            cmd = [sys.executable, __file__, "--one", str(n), mode, "--tau0", str(args.tau0), "--steps",
                   str(args.steps), "--skip", *args.skip]
            proc = subprocess.run(cmd, capture_output=True, text=True)
            got = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
            if proc.returncode:
                print(proc.stderr[-2000:], file=sys.stderr)
            rows += got
    print(f"{'N':>8s} {'mode':4s} {'stage':10s} {'N_vis':>9s} {'wall s':>8s} {'CPU s':>8s} {'peak MB':>8s}")
    for r in rows:
        print(f"{r['n']:8.0e} {r['mode']:4s} {r['stage']:10s} {r.get('n_vis', ''):>9} {r['wall_s']:8.1f} "
              f"{r['cpu_s']:8.1f} {r['peak_mb']:8.0f}")
    for line in growth(rows):
        print(line)
    if args.out:
        with open(args.out, "a") as fh:
            for r in rows:
                fh.write(json.dumps(r) + "\n")


if __name__ == "__main__":
    main()
