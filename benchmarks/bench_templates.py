"""Benchmark the template bank (build and cache-load times) and report the generator's fidelity.

Usage::

    python benchmarks/bench_templates.py [--n-x 320] [--n-phi 720] [--table]
    python benchmarks/bench_templates.py --fidelity [--maps-only] [--setups inclined|face-on|both] \
        [--source fargo3dlib ...]

Timing: builds the compromise bank (the paper's 64-template grid for H/r = 0.05, 0.07, 0.10: 192
templates) into a temporary cache directory (the user's cache is untouched), then loads it back.
Targets (issue 4, per 64 templates): build < 60 s on 2 cores, load < 1 s.
``--table`` also prints peak |δ| and the area-weighted RMS δ of every right-handed template.

``--fidelity`` compares the generator before (GENERATOR_VERSION 1 settings) and after the issue-9
calibration with every reference map in ``tests/data/references/`` (wakeflow 1.4.0 and our
FARGO3D runs; see tools/README.md and docs/templates.md): per case and τ0 the δ-map
cross-correlation and RMS ratio (raw, and beam-smoothed with the beam-smoothed recovery), and, on
the fiducial synthetic observation at 50 au (noise-free, true axisymmetric disc; the helper
``tests/templates/fidelity.py`` says why), the scan's recovery, position error and best bank mass.
"""

from __future__ import annotations

import argparse
import logging
import sys
import tempfile
import time
from pathlib import Path

from spiralbayes.templates import compromise_bank

log = logging.getLogger("bench_templates")


def timing(args) -> None:
    opts = dict(n_x=args.n_x, n_phi=args.n_phi)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        bank = compromise_bank(cache_dir=tmp, **opts)
        build = time.perf_counter() - t0
        loads = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            compromise_bank(cache_dir=tmp, **opts)
            loads.append(time.perf_counter() - t0)
    n64 = len(bank) / 64
    log.info("grid %d x %d, %d templates, %.1f MB of float32 delta", args.n_x, args.n_phi, len(bank),
             bank.nbytes() / 1e6)
    log.info("build (generate + write cache): %.2f s = %.2f s per 64 templates   [target < 60 s per 64]",
             build, build / n64)
    log.info("load from cache: first %.3f s, best %.3f s = %.3f s per 64   [target < 1 s per 64]",
             loads[0], min(loads), min(loads) / n64)
    if args.table:
        log.info("%-30s %10s %10s", "template", "peak|d|", "rms d")
        for t in bank.select(hand="R"):
            log.info("%-30s %10.3f %10.4f", t.name, t.peak(), t.rms())


def fidelity(args) -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from tests.templates import fidelity as F

    setups = {"inclined": F.SETUPS[1:], "face-on": F.SETUPS[:1], "both": F.SETUPS}[args.setups]
    for label, options in (("BEFORE (generator version 1 settings)", F.VERSION1), ("AFTER (calibrated)", {})):
        t0 = time.perf_counter()
        cases = [c for c in F.reference_cases() if not args.source or c.source in args.source]
        rows = F.map_table(cases, **options) if args.maps_only else F.fidelity_table(cases, setups=setups, **options)
        log.info("\n%s  [%.0f s]\n%s", label, time.perf_counter() - t0, F.format_table(rows, scan=not args.maps_only))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n-x", type=int, default=320)
    ap.add_argument("--n-phi", type=int, default=720)
    ap.add_argument("--repeat", type=int, default=3, help="cache loads to time")
    ap.add_argument("--table", action="store_true", help="print the amplitude table")
    ap.add_argument("--fidelity", action="store_true", help="compare with the reference maps instead of timing")
    ap.add_argument("--source", nargs="*", default=None,
                    help="with --fidelity: only these reference sources (wakeflow, fargo3d, fargo3dlib)")
    ap.add_argument("--maps-only", action="store_true", help="with --fidelity: δ-map metrics only (seconds)")
    ap.add_argument("--setups", choices=("inclined", "face-on", "both"), default="both",
                    help="with --fidelity: which fiducial observations to scan")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s", stream=sys.stdout)
    fidelity(args) if args.fidelity else timing(args)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
