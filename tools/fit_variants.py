"""Fit the morphology variants of ``spiralbayes.templates.variants`` to the reference maps (issue 22).

For each reference case × τ0 ∈ {0.3, 3}: the noise-free inner products at the truth of the
reference S with the compromise template T and the near-planet peak B
(``tests/templates/variant_fit.py``). A source's variant ``scale T + blob μ^slope B`` minimises
``Σ_cases |S − scale T − blob μ^slope B|² / |S|²`` (linear least squares in scale and blob for each
slope tried), then both are multiplied by the largest ``k ≤ margin`` for which every case of the
source has ``A_hat ≥ 1/margin``... (printed: the binding case). Prints the before/after A_up table.

    PYTHONPATH=src:. python tools/fit_variants.py [--source fargo3d|wakeflow] [--exclude CASE ...]
"""

from __future__ import annotations

import argparse
import logging

import numpy as np

from tests.templates import fidelity as F
from tests.templates.variant_fit import case_gram, fit_source, upper_limit

log = logging.getLogger("fit_variants")


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--exclude", nargs="*", default=[])
    p.add_argument("--cache", help="JSON file to keep the inner products in (outside git)")
    args = p.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    logging.getLogger("spiralbayes").setLevel(logging.ERROR)
    rows = _rows(args.cache, args.exclude)
    for case, tau0, g in rows:
        a_hat, a_up = upper_limit(g, 1.0, 0.0)
        opt = np.linalg.solve([[g["TT"], g["TB"]], [g["TB"], g["BB"]]], [g["ST"], g["SB"]])
        log.info("%-22s tau0=%-3g compromise A_hat=%.3f A_up=%.3f sigma=%.3f | per-case LS scale=%.3f blob=%.3f",
                 case.label, tau0, a_hat, a_up, 1 / np.sqrt(g["TT"]), opt[0], opt[1])
    fits = {}
    for source in ("fargo3d", "wakeflow"):
        sub = [r for r in rows if r[0].source == source]
        if sub:
            fits[source] = fit_source(sub)
            log.info("%s: %s", source, fits[source])
    log.info("A_up at the truth (noise-free): compromise / fargo3d-fit / wakeflow-fit / robust max")
    for case, tau0, g in rows:
        ups = [upper_limit(g, 1.0, 0.0)[1]] + [
            upper_limit(g, f["scale_final"], f["blob_final"] * case.mu ** f["slope"])[1] for f in fits.values()]
        log.info("%-22s tau0=%-3g %s  robust %.3f", case.label, tau0, " ".join(f"{u:6.3f}" for u in ups), max(ups))


def _rows(cache, exclude):
    import json
    import os

    store = json.load(open(cache)) if cache and os.path.exists(cache) else {}
    rows = []
    for c in F.reference_cases():
        if c.label in exclude:
            continue
        for t in F.TAUS:
            key = f"{c.label}|{t:g}"
            if key not in store:
                store[key] = case_gram(c, t)
            rows.append((c, t, {k: float(v) for k, v in store[key].items()}))
    if cache:
        with open(cache + ".tmp", "w") as f:
            json.dump(store, f)
        os.replace(cache + ".tmp", cache)
    return rows


if __name__ == "__main__":
    main()
