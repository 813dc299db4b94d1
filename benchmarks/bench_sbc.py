"""Simulation-based calibration of the posterior on fiducial observations.

    nohup nice -n 5 python benchmarks/bench_sbc.py --out calib > calib.log 2>&1 &
    python benchmarks/bench_sbc.py --out calib --report     # the table from what is done

Draws >= 30 planets (r_p, phi_p, A) and geometry offsets from the inference priors, simulates
fiducial observations, fits frank at the nominal geometry (so every profile starts from a wrong
geometry), samples, and reports per parameter the coverage of the 68 % and 95 % intervals (with
the binomial error expected at the nominal rate) and the rank histogram; then P(planet | data)
on >= 5 planet-free datasets. Each dataset's record is appended to ``OUT/records.jsonl`` as soon
as it is done, so the benchmark resumes where it stopped. See
:mod:`spiralbayes.inference.validation.sbc`.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import logging  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from spiralbayes.inference.validation.sbc import CalibrationSetup, run_dataset, setup_dict, summarise  # noqa: E402
from spiralbayes.simulate import preset_coverage  # noqa: E402


def report(records, setup: dict, wall_s=None) -> None:
    """The table of ``records``; ``setup`` is the run's ``setup.json`` (:func:`setup_dict`)."""
    s = summarise(records)
    n_p = sum(r["planet"] for r in records)
    print(f"\nsimulation-based calibration: {n_p} planet datasets, {len(records) - n_p} planet-free "
          f"({setup.get('preset')}, template {setup.get('template')}, {setup.get('sampler')})")
    print(f"{'parameter':>9} | {'68 % coverage':>15} | {'95 % coverage':>15} | rank histogram (5 bins)")
    for name, row in s["parameters"].items():
        print(f"{name:>9} | {row['coverage68']:6.2f} +- {row['coverage68_err']:.2f}  | "
              f"{row['coverage95']:6.2f} +- {row['coverage95_err']:.2f}  | {row['rank_histogram']}")
    pooled68 = np.mean([r["inside68"][k] for r in records if r["planet"] for k in r["inside68"]])
    pooled95 = np.mean([r["inside95"][k] for r in records if r["planet"] for k in r["inside95"]])
    print(f"{'pooled':>9} | {pooled68:6.2f}           | {pooled95:6.2f}           |")
    print("P(planet | data) on planet-free data: " + ", ".join(f"{p:.3g}" for p in s["null_p_planet"]))
    pairs = sorted(s["planet_p_planet"])
    print("P(planet | data) with a planet (A: P): " + ", ".join(f"{a:.2f}: {p:.3g}" for a, p in pairs))
    times = [r["time_s"] for r in records]
    if times:
        print(f"time per dataset: median {np.median(times) / 60:.1f} min (frank "
              f"{np.median([r['time_fit_s'] for r in records]):.0f} s), "
              f"largest tau {np.median([r['tau_max'] for r in records if r['tau_max']]):.1f} (median), "
              f"load average {os.getloadavg()[0]:.1f}")
    if wall_s is not None:
        print(f"total wall time of this session: {wall_s / 3600:.2f} h")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="bench_sbc_output")
    parser.add_argument("--n-planet", type=int, default=30)
    parser.add_argument("--n-null", type=int, default=5)
    parser.add_argument("--preset", default="fiducial")
    parser.add_argument("--walkers", type=int, default=24)
    parser.add_argument("--steps", type=int, default=600)
    parser.add_argument("--evidence-draws", type=int, default=800)
    parser.add_argument("--processes", type=int, default=1)
    parser.add_argument("--frank-n", type=int, default=200, help="frank's N (100 already reaches 8.6 Mlambda at Rmax "
                                                                 "= 1.2\")")
    parser.add_argument("--seed", type=int, default=2024)
    parser.add_argument("--mass", choices=("bank", "continuous"), default="bank",
                        help="'continuous': draw M_p log-uniform over 0.1-3 M_th and sample it")
    parser.add_argument("--indices", default=None, help="only these planet datasets, 'a:b' (run two processes "
                                                         "on one --out to use two cores)")
    parser.add_argument("--no-null", action="store_true", help="skip the planet-free datasets")
    parser.add_argument("--mass-nodes", type=int, default=None, help="mass nodes of the family (--mass continuous; "
                                                                      "default 49)")
    parser.add_argument("--rp-tolerance", type=float, default=None, help="the tables' r_p tolerance (default 0.01)")
    parser.add_argument("--report", action="store_true", help="only print the table of the records so far")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
    for noisy in ("arviz", "spiralbayes.inference.posterior.perturbation", "spiralbayes.inference.posterior.optimise"):
        logging.getLogger(noisy).setLevel(logging.WARNING)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    sampler = {"n_walkers": args.walkers, "n_steps": args.steps, "evidence_draws": args.evidence_draws}
    if args.rp_tolerance is not None:
        sampler["likelihood_kwargs"] = {"rp_tolerance": args.rp_tolerance}
    setup = CalibrationSetup(preset=args.preset, sampler=sampler, frank={"N": args.frank_n, "Rmax": 1.2},
                             mass=args.mass, n_mass_nodes=args.mass_nodes)
    path = out / "records.jsonl"
    records = [json.loads(line) for line in path.read_text().splitlines() if line.strip()] if path.exists() else []
    wanted = json.loads(json.dumps(setup_dict(setup)))  # as it reads back from the file
    written = out / "setup.json"
    if args.report:
        report(records, json.loads(written.read_text()) if written.exists() else wanted)
        return
    if written.exists() and records:
        before = json.loads(written.read_text())
        changed = sorted(k for k in set(before) | set(wanted) if before.get(k) != wanted.get(k))
        if changed:
            raise SystemExit(f"{out} holds {len(records)} records of another set-up (differing: {changed}); "
                             "give the options of that run to resume it, or a new --out")
    written.write_text(json.dumps(wanted, indent=2))
    done = {(r["index"], r["planet"]) for r in records}
    coverage = preset_coverage(args.preset)
    template = setup.make_template()
    a, b = (int(x) for x in args.indices.split(":")) if args.indices else (0, args.n_planet)
    todo = [(i, True) for i in range(a, b)] + [(i, False) for i in range(0 if args.no_null else args.n_null)]
    family = setup.family(template) if args.mass == "continuous" else None
    t0 = time.perf_counter()
    for index, planet in todo:
        if (index, planet) in done:
            continue
        record = run_dataset(setup, index, out / "chains", planet=planet, coverage=coverage, template=template,
                             seed=args.seed, processes=args.processes if args.processes > 1 else None,
                             family=family)
        records.append(record)
        with open(path, "a") as f:
            f.write(json.dumps(record) + "\n")
    report(records, wanted, time.perf_counter() - t0)


if __name__ == "__main__":
    main()
