"""Benchmark the template bank: build time of the paper's 64-template grid and cache-load time.

Usage::

    python benchmarks/bench_templates.py [--n-x 320] [--n-phi 720] [--table]

Builds the default bank into a temporary cache directory (so the user's cache is untouched),
then loads it back from the cache. Targets (issue 4): build < 60 s on 2 cores, load < 1 s.
``--table`` also prints peak |δ| and the area-weighted RMS δ of every right-handed template.
"""

from __future__ import annotations

import argparse
import logging
import sys
import tempfile
import time

from spiralbayes.templates import default_bank

log = logging.getLogger("bench_templates")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n-x", type=int, default=320)
    ap.add_argument("--n-phi", type=int, default=720)
    ap.add_argument("--repeat", type=int, default=3, help="cache loads to time")
    ap.add_argument("--table", action="store_true", help="print the amplitude table")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s", stream=sys.stdout)
    opts = dict(n_x=args.n_x, n_phi=args.n_phi)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        bank = default_bank(cache_dir=tmp, **opts)
        build = time.perf_counter() - t0
        loads = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            default_bank(cache_dir=tmp, **opts)
            loads.append(time.perf_counter() - t0)
    log.info("grid %d x %d, %d templates, %.1f MB of float32 delta", args.n_x, args.n_phi, len(bank),
             bank.nbytes() / 1e6)
    log.info("build (generate + write cache): %.2f s   [target < 60 s]", build)
    log.info("load from cache: first %.3f s, best %.3f s   [target < 1 s]", loads[0], min(loads))
    if args.table:
        log.info("%-26s %10s %10s", "template", "peak|d|", "rms d")
        for t in bank.select(hand="R"):
            log.info("%-26s %10.3f %10.4f", t.name, t.peak(), t.rms())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
