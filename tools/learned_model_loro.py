"""Leave-one-run-out error of the learned template model, beside the variant bank's.

For every isothermal gas run of the reference files (``spiralbayes.templates.learned.read_training_runs``:
the continuum design, the library, the ``physics`` set and the two older runs) the model is refitted
without it and predicted at the run's own (M_p, H/r, p, α, orbits); the held-out run's reduced δ map
at τ0 = 0.3 and 3 is planted noise-free in the fiducial observation (50 au, 30° inclination,
φ_p 40°, the unperturbed disc: ``tests/templates/variant_fit.truth_products``) and

* ``recovery`` = Δχ²(template) / Δχ²(own map) at the truth, ``Δχ²(T) = 2<S,T> − <T,T>`` with the
  amplitude fixed at 1 (the learned template; and the best template of the default variant bank at
  the run's τ0: any mass, H/r, variant, β and hand);
* ``beam_ncc`` = the beam-smoothed maps' normalised cross-correlation (``fidelity.beam_metrics``);
* ``expected`` = the model's own ``1 − relative_error²`` (``predict_uncertainty``), to check its
  uncertainty against the measured error.

Run (from the repository root)::

    PYTHONPATH=src:. python tools/learned_model_loro.py                 # the table (resumes)
    PYTHONPATH=src:. python tools/learned_model_loro.py --markdown      # for docs/templates.md
    PYTHONPATH=src:. python tools/learned_model_loro.py --n-components 6 --no-align   # another representation

Results are cached per (run, τ0, representation, training set) in ``--cache`` (a JSON-lines file),
so an interrupted run resumes and new runs reduced into the files are the only new work; the bank's
numbers do not depend on the representation and are cached once per run and τ0.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import logging
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
REFS = ROOT / "tests" / "data" / "references"
DEFAULT_FILES = (REFS / "continuum" / "fargo3d_continuum.h5", REFS / "fargo3d_library.h5",
                 REFS / "physics" / "fargo3d_library.h5", REFS / "fargo3d_isothermal.h5")
TAUS = (0.3, 3.0)
BANK_VERSION = 1
log = logging.getLogger("learned_model_loro")


def _file_key(paths) -> str:
    parts = []
    for p in paths:
        st = Path(p).stat()
        parts.append(f"{Path(p).name}:{st.st_size}")
    return "|".join(parts)


def reference_template(run, tau0: float):
    """The held-out run's own reduced δ map at ``tau0`` (hand R)."""
    import h5py

    from spiralbayes.templates import SpiralTemplate

    with h5py.File(run.file, "r") as f:
        delta = f[f"{run.group}/delta_tau{tau0:g}"][()].astype(float)
    return SpiralTemplate(x=run.x, phi=run.phi, delta=delta, mass=run.mass, tau0=tau0, beta=0.0, h_p=run.h_p,
                          name=f"ref_{run.name.replace(':', '_')}_tau{tau0:g}", provenance={"reference": run.name})


def recovery(cross, power, ss) -> np.ndarray:
    """``(2<S,T> − <T,T>) / <S,S>``: the fraction of the own map's Δχ² a fixed template recovers."""
    return (2.0 * np.asarray(cross) - np.asarray(power)) / ss


class Cache:
    """A JSON-lines store of finished rows (one per key)."""

    def __init__(self, path: Path):
        self.path = path
        self.rows: dict = {}
        self.reload()

    def reload(self) -> None:
        """Read the rows written since (by another process sharing the file, too)."""
        if self.path.exists():
            for line in self.path.read_text().splitlines():
                try:
                    row = json.loads(line)
                except ValueError:
                    continue
                self.rows[row["key"]] = row

    def get(self, key):
        return self.rows.get(key)

    def put(self, row: dict) -> None:
        self.rows[row["key"]] = row
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with open(self.path, "a") as f:
            f.write(json.dumps(row) + "\n")


def bank_row(run, tau0, bank_templates, cache: Cache) -> dict:
    """The default variant bank's best recovery on the held-out map (cached by the map's bytes and the
    bank's template names, so that runs reduced into the files later leave it valid)."""
    from tests.templates import variant_fit as V

    ref = reference_template(run, tau0)
    blob = hashlib.sha256(np.ascontiguousarray(ref.delta, dtype=np.float32).tobytes())
    blob.update("|".join(t.name for t in bank_templates).encode())
    key = hashlib.sha256(f"bank{BANK_VERSION}|{run.name}|{tau0:g}|{blob.hexdigest()}".encode()).hexdigest()[:20]
    row = cache.get(key)
    if row is None:
        cross, power = V.truth_products(ref, bank_templates, tau0)
        rec = recovery(cross[1:], power[1:], power[0])
        best = int(np.argmax(rec))
        row = {"key": key, "kind": "bank", "run": run.name, "tau0": tau0, "own_dchi2": float(power[0]),
               "bank_recovery": float(rec[best]), "bank_best": bank_templates[best].name}
        cache.put(row)
    return row


def learned_rows(run, runs, options: dict, cache: Cache, file_key: str) -> list[dict]:
    """The learned model's held-out rows for ``run`` at every τ0 (cached; one refit)."""
    from spiralbayes.templates.learned import MODEL_VERSION, LearnedTemplateModel
    from tests.templates import fidelity as F
    from tests.templates import variant_fit as V

    train = [r for r in runs if r.name != run.name]
    opt_key = json.dumps(options, sort_keys=True)
    base = f"learned{MODEL_VERSION}|{run.name}|{opt_key}|{','.join(r.name for r in train)}|{file_key}"
    keys = {tau0: hashlib.sha256(f"{base}|{tau0:g}".encode()).hexdigest()[:20] for tau0 in TAUS}
    if all(cache.get(k) is not None for k in keys.values()):
        return [cache.get(keys[t]) for t in TAUS]
    t0 = time.perf_counter()
    model = LearnedTemplateModel.fit(train, **options)
    fit_s = time.perf_counter() - t0
    out = []
    for tau0 in TAUS:
        p = run.parameters
        tmpl = model.predict(**p, tau0=tau0, extrapolate=True)
        unc = model.predict_uncertainty(**p, tau0=tau0, extrapolate=True)
        ref = reference_template(run, tau0)
        cross, power = V.truth_products(ref, [tmpl], tau0)
        beam = F.beam_metrics(ref, tmpl)
        row = {"key": keys[tau0], "kind": "learned", "run": run.name, "tau0": tau0, "options": options,
               **{k: float(v) for k, v in p.items()}, "inside_box": bool(tmpl.provenance["learned"]["inside_box"]),
               "own_dchi2": float(power[0]), "recovery": float(recovery(cross[1], power[1], power[0])),
               "beam_ncc": beam["beam_ncc"], "beam_recovery": beam["beam_recovery"],
               "expected": unc.expected_recovery, "fit_s": fit_s}
        cache.put(row)
        out.append(row)
    return out


def set_of(name: str) -> str:
    return name.split(":", 1)[0]


def summarise(rows: list[dict], label: str) -> str:
    if not rows:
        return f"{label}: no runs"
    parts = []
    for tau0 in TAUS:
        lr = np.array([r[f"rec{tau0:g}"] for r in rows])
        br = np.array([r[f"bank{tau0:g}"] for r in rows])
        nc = np.array([r[f"ncc{tau0:g}"] for r in rows])
        parts.append(f"τ0 {tau0:g}: learned median {np.median(lr):.3f}, min {lr.min():.3f}; bank median "
                     f"{np.median(br):.3f}, min {br.min():.3f}; beam NCC median {np.median(nc):.3f}, "
                     f"min {nc.min():.3f}")
    return f"{label} ({len(rows)} runs) — " + " | ".join(parts)


def main(argv=None) -> int:
    from spiralbayes.templates.learned import AZIMUTH_SCALING

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--references", nargs="+", default=[str(p) for p in DEFAULT_FILES],
                    help="reduced reference files (default: continuum, library, physics, isothermal)")
    ap.add_argument("--runs", nargs="*", default=None, help="hold out only these runs (substrings of their names)")
    ap.add_argument("--n-components", type=int, default=10)
    ap.add_argument("--n-gap-components", type=int, default=5)
    ap.add_argument("--no-align", action="store_true", help="fit the basis to unaligned maps")
    ap.add_argument("--restarts", type=int, default=2, help="extra starts of each process's optimiser")
    ap.add_argument("--sharing", choices=("grouped", "independent"), default="grouped",
                    help="one kernel per group of outputs (default) or per output")
    ap.add_argument("--trend", choices=("disc", "map", "amplitudes", "all", "none"), default="disc",
                    help="outputs regressed on a linear trend under the processes (default: disc)")
    ap.add_argument("--no-gap-depth", action="store_true", help="a basis of the log gap itself (no depth × shape)")
    ap.add_argument("--patch", action="store_true", help="model the near-planet patch apart (off by default)")
    ap.add_argument("--n-patch-components", type=int, default=6)
    ap.add_argument("--min-length-scale", type=float, default=None,
                    help="lower bound of the processes' length scales [box sides] (default: the model's)")
    ap.add_argument("--azimuth-scaling", type=float, default=AZIMUTH_SCALING,
                    help=f"power q of the aligned maps' azimuth scaling (h_p/h_min)^q (default {AZIMUTH_SCALING:g}; "
                         "0: off)")
    ap.add_argument("--no-bank", action="store_true", help="skip the variant bank's recovery")
    ap.add_argument("--cache", default=None, help="JSON-lines cache (default: <cache dir>/learned_loro.jsonl)")
    ap.add_argument("--markdown", action="store_true", help="print the per-run table as Markdown")
    ap.add_argument("--drop-transients", action="store_true",
                    help="leave out maps whose run is not quasi-steady at a later age (read_training_runs)")
    ap.add_argument("-v", "--verbose", action="store_true")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(message)s")
    if not args.verbose:  # the scan's accuracy notes on noise-free plantings in a tabulated disc
        logging.getLogger("spiralbayes").setLevel(logging.ERROR)

    from spiralbayes.templates.bank import default_cache_dir
    from spiralbayes.templates.learned import read_training_runs

    t_start = time.perf_counter()
    files = [Path(p) for p in args.references]
    runs = read_training_runs(files, drop_transients=args.drop_transients)
    file_key = _file_key(files)
    cache = Cache(Path(args.cache) if args.cache else default_cache_dir() / "learned_loro.jsonl")
    options = {"n_components": args.n_components, "n_gap_components": args.n_gap_components,
               "align": not args.no_align, "restarts": args.restarts, "sharing": args.sharing,
               "trend": args.trend, "gap_depth": not args.no_gap_depth, "patch": args.patch,
               "n_patch_components": args.n_patch_components}
    if args.min_length_scale is not None:
        options["min_length_scale"] = args.min_length_scale
    options["azimuth_scaling"] = args.azimuth_scaling
    held = [r for r in runs if args.runs is None or any(s in r.name for s in args.runs)]
    bank = None
    if not args.no_bank:
        from spiralbayes.templates.variants import default_bank

        full = default_bank()
        bank = {tau0: [t for t in full if np.isclose(t.tau0, tau0)] for tau0 in TAUS}
    print(f"{len(runs)} training runs; holding out {len(held)}; options {options}", file=sys.stderr)
    table = []
    for i, run in enumerate(held):
        t0 = time.perf_counter()
        lrows = learned_rows(run, runs, options, cache, file_key)
        row = {"run": run.name, **run.parameters, "inside_box": lrows[0]["inside_box"]}
        for lr in lrows:
            tau0 = lr["tau0"]
            row[f"rec{tau0:g}"] = lr["recovery"]
            row[f"ncc{tau0:g}"] = lr["beam_ncc"]
            row[f"exp{tau0:g}"] = lr["expected"]
            row[f"own{tau0:g}"] = lr["own_dchi2"]
            if bank is not None:
                br = bank_row(run, tau0, bank[tau0], cache)
                row[f"bank{tau0:g}"] = br["bank_recovery"]
                row[f"best{tau0:g}"] = br["bank_best"]
            else:
                row[f"bank{tau0:g}"] = float("nan")
                row[f"best{tau0:g}"] = ""
        table.append(row)
        print(f"[{i + 1}/{len(held)}] {run.name}: learned {row['rec0.3']:.3f} / {row['rec3']:.3f}, bank "
              f"{row['bank0.3']:.3f} / {row['bank3']:.3f} ({time.perf_counter() - t0:.0f} s)", file=sys.stderr)

    print_table(table, args.markdown)
    print()
    print(summarise(table, "all"))
    for s in sorted({set_of(r["run"]) for r in table}):
        print(summarise([r for r in table if set_of(r["run"]) == s], s))
    inside = [r for r in table if r["inside_box"]]
    print(summarise(inside, "inside the training box of the others"))
    exp = np.array([[r["exp0.3"], r["exp3"]] for r in table])
    got = np.array([[r["rec0.3"], r["rec3"]] for r in table])
    if len(table) > 2:
        print(f"the model's expected recovery against the measured one: Spearman ρ "
              f"{_spearman(exp.ravel(), got.ravel()):.2f}; measured below expected − 0.2 in "
              f"{int(np.sum(got < exp - 0.2))} of {got.size}")
    print(f"options {options}; {len(runs)} runs; {time.perf_counter() - t_start:.0f} s "
          f"(cache {cache.path}; pid {os.getpid()})")
    return 0


def _spearman(a, b) -> float:
    ra, rb = np.argsort(np.argsort(a)), np.argsort(np.argsort(b))
    return float(np.corrcoef(ra, rb)[0, 1])


def print_table(table, markdown: bool) -> None:
    if markdown:
        print("| run | M_p [M_th] | H/r | p | α | orbits | learned τ0 0.3 / 3 | beam NCC 0.3 / 3 | bank τ0 0.3 / 3 | "
              "bank's best (τ0 3) |")
        print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
        for r in table:
            flag = "" if r["inside_box"] else " (outside the others' box)"
            print(f"| {r['run']}{flag} | {r['mass']:g} | {r['h_p']:g} | {r['slope']:g} | {r['alpha']:.1e} | "
                  f"{r['orbits']:g} | {r['rec0.3']:.2f} / {r['rec3']:.2f} | {r['ncc0.3']:.3f} / {r['ncc3']:.3f} | "
                  f"{r['bank0.3']:.2f} / {r['bank3']:.2f} | {r['best3']} |")
        return
    head = (f"{'run':48s} {'M_p':>5s} {'H/r':>5s} {'p':>5s} {'alpha':>8s} {'orb':>4s} {'box':>3s} | "
            f"{'lrn0.3':>6s} {'lrn3':>6s} {'exp0.3':>6s} {'exp3':>6s} {'ncc0.3':>6s} {'ncc3':>6s} | "
            f"{'bank0.3':>7s} {'bank3':>6s}")
    print(head)
    print("-" * len(head))
    for r in table:
        print(f"{r['run']:48s} {r['mass']:5g} {r['h_p']:5g} {r['slope']:5g} {r['alpha']:8.1e} {r['orbits']:4g} "
              f"{'in' if r['inside_box'] else 'out':>3s} | {r['rec0.3']:6.3f} {r['rec3']:6.3f} {r['exp0.3']:6.3f} "
              f"{r['exp3']:6.3f} {r['ncc0.3']:6.3f} {r['ncc3']:6.3f} | {r['bank0.3']:7.3f} {r['bank3']:6.3f}")


if __name__ == "__main__":
    sys.exit(main())
