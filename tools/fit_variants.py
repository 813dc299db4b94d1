"""Fit the morphology variants of ``spiralbayes.templates.variants`` to the reference maps (issue 22).

For each reference case (``tests/templates/fidelity.py:acceptance_cases``: wakeflow, the FARGO3D
runs of ``fargo3d_isothermal.h5`` and the library's finished ``role = library`` runs) × each τ0
it was reduced for: the noise-free inner products at the truth of the reference S with the
generator's template T of the same (M_p, H/r, τ0, β), the near-planet peak B and the broad wake W
(``tests/templates/variant_fit.py``). ``hydro`` is fitted to every FARGO3D case (T, B, W),
``wakeflow`` to the wakeflow maps (T, B) (:func:`tests.templates.variant_fit.fit_source`: least
squares, powers of M_p on a grid, one shrink per reference mass so that every map has
``A_hat >= 1/margin``, margin 0.8; the binding maps are printed). Prints the constants, the A_up
table at the truth (noise-free) and the leave-one-source-out table (noise-free A_up of the held-out
maps).

    PYTHONPATH=src:. python tools/fit_variants.py [--cache FILE.json] [--exclude CASE ...]
"""

from __future__ import annotations

import argparse
import json
import logging
import os
from pathlib import Path


from tests.templates import fidelity as F
from tests.templates import variant_fit as VF

log = logging.getLogger("fit_variants")


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--exclude", nargs="*", default=[])
    p.add_argument("--cache", help="JSON file to keep the inner products in (outside git)")
    args = p.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    logging.getLogger("spiralbayes").setLevel(logging.ERROR)
    rows = _rows(args.cache, args.exclude)
    fits = VF.fit_variants(rows)
    for name, f in fits.items():
        log.info("%s: %s", name, {k: (round(v, 4) if isinstance(v, float) else v) for k, v in f.items()})
    log.info("A_up at the truth (noise-free): compromise / %s / robust max", " / ".join(fits))
    for case, tau0, g in rows:
        ups = [VF.upper_limit(g, 1.0, 0.0)[1]] + [VF.upper_limit(g, *VF.fitted_amplitudes(f, case.mu))[1]
                                                    for f in fits.values()]
        log.info("%-34s tau0=%-4g %s  robust %.3f", case.label, tau0, " ".join(f"{u:6.3f}" for u in ups), max(ups))
    log.info("leave one source out: best A_up (noise-free) of the held-out maps over compromise + refitted variants")
    for source in VF.SOURCES:
        held = [r for r in rows if VF.calibration_source(r[0]) == source]
        refit = VF.fit_variants([r for r in rows if VF.calibration_source(r[0]) != source])
        worst = min((max([VF.upper_limit(g, 1.0, 0.0)[1]] + [VF.upper_limit(g, *VF.fitted_amplitudes(f, c.mu))[1]
                                                             for f in refit.values()]), c.label, t)
                    for c, t, g in held)
        log.info("%-20s %d maps; worst held-out robust A_up %.3f (%s tau0 %g)", source, len(held), *worst)


def _rows(cache, exclude):
    store = json.loads(Path(cache).read_text()) if cache and os.path.exists(cache) else {}
    rows = []
    for c in F.acceptance_cases():
        if c.label in exclude:
            continue
        for t in c.taus:
            key = f"{c.label}|{t:g}"
            if key not in store:
                store[key] = VF.case_gram(c, t)
            rows.append((c, t, {k: float(v) for k, v in store[key].items()}))
    if cache:
        with open(cache + ".tmp", "w") as f:
            json.dump(store, f)
        os.replace(cache + ".tmp", cache)
    return rows


if __name__ == "__main__":
    main()
