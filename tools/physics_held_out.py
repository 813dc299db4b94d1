"""The physics posterior on held-out hydrodynamic planets: its H/r, mass, slope and viscosity against the truth.

Runs ``tests/_support/physics_setup.held_out_posterior`` (the slow test's cases: each FARGO3D ``physics``
run at τ0 0.3 and 3 planted in the weak observation, the learned model fitted without it) and prints
one row per case: the truth, the posterior's medians and 95 % intervals, whether each truth lies inside,
and ``ln`` offsets of the medians from the truth. Rows are cached in a JSON-lines file, so an
interrupted run resumes (about 10 minutes a case on 2 cores).

    PYTHONPATH=src:. python tools/physics_held_out.py               # every case (resumes)
    PYTHONPATH=src:. python tools/physics_held_out.py --cases physics:h0.08_mu2 --taus 3 --keep posteriors/
"""

from __future__ import annotations

import argparse
import hashlib
import logging
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from learned_model_loro import Cache, _file_key  # the tools' JSON-lines store and training-set key

VERSION = 4
"""Changes when the cases' set-up changes (cached rows of another version are recomputed)."""


def case_row(name: str, tau0: float, keep: Path | None = None) -> dict:
    from tests._support.physics_setup import held_out_posterior

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as cache:
        run, post = held_out_posterior(name, tau0, cache)
    if keep is not None:  # the whole lattice, for looking at it again without rerunning
        post.save(keep / f"{name.replace(':', '_')}_tau{tau0:g}_v{VERSION}.h5")
    ci = post.intervals(0.95)
    truth = {"h_p": run.h_p, "M_p": run.mass, "slope": run.slope, "alpha": run.alpha}
    row = {"run": name, "tau0": tau0, "truth": truth, "wall_s": time.perf_counter() - t0,
           "position_resolved": post.position_resolved(), "p_right": post.marginal("hand").get("R", 0.0),
           "position_levels": post.provenance.get("position_levels", [])}
    for key, value in truth.items():
        c = ci[key]
        row[key] = {**c, "inside": bool(c["lo"] <= value <= c["hi"]), "ln_offset": float(np.log(c["median"] / value))}
    return row


def _cell(row: dict, key: str, digits: int = 3) -> str:
    c, d = row[key], digits
    mark = "" if c["inside"] else " **outside**"
    return f"{row['truth'][key]:.{d}g}, {c['median']:.{d}g} ({c['lo']:.{d}g}–{c['hi']:.{d}g}){mark}"


def table(rows: list[dict]) -> str:
    lines = ["| run | τ0 | H/r: truth, median (95 %) | M_p [M_th]: truth, median (95 %) | slope: truth, median | "
             "α: truth, median | resolved |", "| --- | --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        cells = [_cell(r, "h_p"), _cell(r, "M_p"), _cell(r, "slope", 2), _cell(r, "alpha", 2)]
        lines.append(f"| {r['run']} | {r['tau0']:g} | " + " | ".join(cells) + f" | {r['position_resolved']} |")
    inside = {k: sum(r[k]["inside"] for r in rows) for k in ("h_p", "M_p", "slope", "alpha")}
    lines.append("")
    lines.append(f"{len(rows)} cases; truth inside the 95 % interval: " +
                 ", ".join(f"{k} {v}/{len(rows)}" for k, v in inside.items()))
    for key in ("h_p", "M_p"):
        off = np.array([r[key]["ln_offset"] for r in rows])
        if off.size:
            lines.append(f"ln(median / truth) of {key}: mean {off.mean():+.3f}, rms {np.sqrt(np.mean(off**2)):.3f}")
    return "\n".join(lines)


def main(argv=None) -> int:
    from tests._support.physics_setup import H_P, MASSES, ORBITS, R_P_GRID, RUNS, TAUS

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", nargs="*", default=list(RUNS), help="physics-set runs (default: all 7)")
    ap.add_argument("--taus", nargs="*", type=float, default=list(TAUS))
    ap.add_argument("--cache", default=None, help="JSON-lines cache (default: <cache dir>/physics_held_out.jsonl)")
    ap.add_argument("--keep", default=None, help="a folder to save each case's PhysicsPosterior in")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    from spiralbayes.templates.bank import default_cache_dir

    cache = Cache(Path(args.cache) if args.cache else default_cache_dir() / "physics_held_out.jsonl")
    from spiralbayes.templates.learned import MODEL_VERSION, reference_files

    # a row is the model's on these training files, fitted as this version of the model fits them
    training = f"{_file_key(reference_files())}|learned{MODEL_VERSION}"
    # the lattice is the cases' set-up too (its ages follow DEFAULT_AGES)
    lattice = repr([list(map(float, a)) for a in (H_P, MASSES, ORBITS, R_P_GRID)])
    training += f"|lattice{hashlib.sha256(lattice.encode()).hexdigest()[:12]}"
    rows = []
    for name in args.cases:
        for tau0 in args.taus:
            key = f"v{VERSION}|{name}|{tau0:g}|{training}"
            cache.reload()  # processes sharing the cache (``--cases``) skip each other's finished cases
            row = cache.get(key)
            if row is None:
                row = {"key": key, **case_row(name, tau0, Path(args.keep) if args.keep else None)}
                cache.put(row)
                logging.warning("%s tau0 %g done in %.0f s", name, tau0, row["wall_s"])
            rows.append(row)
    print(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
