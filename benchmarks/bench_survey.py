"""Survey benchmark: the six-disc Taurus example serially and on a LocalCluster, and a per-disc cost model.

Usage::

    python benchmarks/bench_survey.py [--out DIR] [--workers N] [--skip-serial] [--scaling]

Runs ``examples/taurus_survey.toml`` (six synthetic Taurus discs, 6 templates, the paper's
25 x 90 grid) twice from scratch, once with ``scheduler = "serial"`` and once on a LocalCluster
of ``--workers`` single-threaded processes, and prints the wall time, the time of each disc (sum
of its tasks' compute times), the engine start-up and the scheduler overhead (wall time minus
the ideal ``sum(task times) / workers``). ``--scaling`` adds one disc per observing preset
(taurus: 6.3e3 visibilities, fiducial: 3.6e4) to fit the per-disc cost model

    t_disc = t_frank(N) + t_setup(N) + n_templates * t_template(N) + t_alternatives(N) + t_limits

and prints discs per hour per worker and what a 100-disc survey needs. The machine's load
average is printed with the figures (the numbers scale with it on a shared machine).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import time
import warnings
from pathlib import Path

import numpy as np


def _load() -> str:
    return ", ".join(f"{x:.1f}" for x in os.getloadavg())


def run_example(out: Path, scheduler: str, workers: int) -> dict:
    from spiralbayes.pipeline.survey import run_survey
    from spiralbayes.pipeline.survey.demo import taurus_survey_toml

    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    path = out / "taurus_survey.toml"
    path.write_text(taurus_survey_toml())
    t0 = time.perf_counter()
    run = run_survey(path, scheduler=scheduler, n_workers=workers, progress=False)
    wall = time.perf_counter() - t0
    discs = run.timings["discs"]
    busy = sum(d["total_s"] for d in discs.values())
    n = 1 if scheduler == "serial" else (workers or len(os.sched_getaffinity(0)))
    return {"engine": run.engine, "load_after": _load(), "wall_s": wall,
            "engine_start_s": run.timings["engine_start_s"],
            "graph_s": run.timings["graph_s"], "task_s": busy, "overhead_s": run.timings["graph_s"] - busy / n,
            "per_disc_s": {k: round(v["total_s"], 2) for k, v in discs.items()},
            "stages_s": {k: {s: round(t, 2) for s, t in v["stages_s"].items()} for k, v in discs.items()},
            "failed": run.failed}


def scaling(presets=("taurus", "fiducial")) -> list[dict]:
    from spiralbayes import DiscGeometry, DiscModel, fit_axisymmetric, make_template, simulate_observation
    from spiralbayes.inference.detection.alternatives import fit_alternatives
    from spiralbayes.inference.limits import compute_limits
    from spiralbayes.inference.scan import scan

    out = []
    templates = []
    for m in (0.3, 1.0, 3.0):
        right = make_template(m, 0.3, 10.0, "R", wavelength=1.33e-3)
        templates += [right, right.mirror()]
    geometry = DiscGeometry(35.0, 120.0)
    for preset in presets:
        vis = simulate_observation(preset, DiscModel(distance=140.0, r_in=6, r_out=60), geometry, seed=1)
        t = {"preset": preset, "n_vis": int(vis.n)}
        t0 = time.perf_counter()
        ax = fit_axisymmetric(vis, geometry, progress=False)
        t["frank_s"] = time.perf_counter() - t0
        res = scan(vis, ax, templates, geometry, r_p=np.linspace(0.02, 0.5, 25), distance=140, progress=False)
        t["setup_s"] = res.provenance["timing_s"]["setup"] + res.provenance["timing_s"]["check"]
        t["per_template_s"] = res.provenance["timing_s"]["templates"] / len(templates)
        t0 = time.perf_counter()
        fit_alternatives(vis, ax, geometry, progress=False)
        t["alternatives_s"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        compute_limits(res, vis=vis, axisymmetric=ax, distance=140)
        t["limits_s"] = time.perf_counter() - t0
        out.append(t)
    return out


def cost_model(rows: list[dict], n_templates=(6, 64, 192), n_discs: int = 100) -> list[str]:
    lines = []
    for r in rows:
        for nt in n_templates:
            t = r["frank_s"] + r["setup_s"] + nt * r["per_template_s"] + r["alternatives_s"] + r["limits_s"]
            lines.append(f"N = {r['n_vis']:.2g} ({r['preset']}), {nt} templates: {t:.0f} s per disc, "
                         f"{3600 / t:.1f} discs/hour/worker; {n_discs} discs: {n_discs * t / 3600:.1f} worker-hours "
                         f"({n_discs * t / 3600 / 16:.2f} h on 16 workers)")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="bench-survey")
    parser.add_argument("--workers", type=int, default=0, help="LocalCluster workers (0: one per core)")
    parser.add_argument("--skip-serial", action="store_true")
    parser.add_argument("--skip-example", action="store_true")
    parser.add_argument("--scaling", action="store_true")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    report = {"cores": len(os.sched_getaffinity(0)), "load_before": _load()}
    out = Path(args.out)
    if not args.skip_example:
        if not args.skip_serial:
            report["serial"] = run_example(out / "serial", "serial", 1)
        report["local_cluster"] = run_example(out / "cluster", "", args.workers)
    if args.scaling:
        rows = scaling()
        report["scaling"] = rows
        report["cost_model"] = cost_model(rows)
    report["load_after"] = _load()
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
