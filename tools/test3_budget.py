"""What test 3 asks of a template where a real planet loses it (a measurement, not a feature).

For each case, planted and judged as the reference-detection table does
(:func:`tests.inference.detection.reference_detection.evaluate`: the map in a disc holding its run's
gap, that disc as the axisymmetric model), it takes the alternative that binds the nested test (the
smallest statistic) and splits test 3's statistic into Δχ² against the axisymmetric model:

* ``A``: the alternative alone (``k_alt`` parameters);
* ``S_bank``: the verdict's spiral alone at its nested position and hypothesis;
* ``S_own``: the reference map itself (the own template) the same way, the most any template
  could give;
* ``S_needed``: what a fixed-amplitude spiral alone (six parameters) must give to pass,
  ``A + (6 − k_alt) ln N + nested_threshold``.

``S_bank / S_own`` is how much of the true spiral the bank recovers and ``S_needed / S_own`` how
much it would have to. Where the joint fit (alternative + spiral) binds instead of the spiral alone,
the split is printed but the budget does not apply.

``--span`` asks whether *any* template of the variants' form could: at the true planet position and
the case's own mass, H/r, τ0 and β, the blocks the variants are made of — the generator's template
``T``, the broad wake ``W``, the near-planet peak ``B`` (:mod:`spiralbayes.templates.variants`) and
the co-orbital band ``D`` — are fitted to the data with free coefficients (least squares, no BIC
penalty: an upper bound for every variant of that form), and to the noise-free true spiral, whose
power they capture as the fraction ``|P S|² / |S|²`` (``P`` the projection onto their span; for one
template the squared correlation). A case written ``label@tau0@witness`` adds another reference
map, ``witness``, scored as a template the same way (e.g. the 200-orbit run for the 500-orbit
planet: a hydrodynamic template of another run). Usage (``PYTHONPATH=src:.``)::

    python tools/test3_budget.py                           # the three planets lost at test 3 alone
    python tools/test3_budget.py wakeflow:h0.05_mu1@0.3
    python tools/test3_budget.py --span                    # and the blocks' span at the truth
    python tools/test3_budget.py --span fargo3dlib:h0.07_mu1_orbits500@0.3@fargo3dlib:h0.07_mu1_orbits200

One JSON line per case, then a Markdown table.
"""

from __future__ import annotations

import argparse
import json
import logging

import numpy as np

from spiralbayes.inference.detection import DetectionSettings
from spiralbayes.inference.scan.statistics import N_SPIRAL_PARAMETERS
from tests.inference.detection import reference_detection as rd
from tests.templates.fidelity import PHYSICS_FILE

TEST3_CASES = ("wakeflow:h0.05_mu1@0.3", "fargo3dlib:h0.07_mu1_nu1e-04@0.3", "fargo3dlib:h0.05_mu3@0.3")
"""The planets of the reference-detection table placed right and lost at test 3 alone."""


def _case(label: str):
    for case in rd.detection_cases() + rd.detection_cases([PHYSICS_FILE]):
        if case.label == label:
            return case
    raise SystemExit(f"no reference case {label!r}; the labels are those of docs/verdict.md's detection table")


def budget(label: str, tau0: float) -> dict:
    keep: dict = {}
    r = rd.evaluate(_case(label), tau0, keep=keep)
    verdict, own = keep["verdict"], keep["own_nested"]
    if not verdict.nested or not own:
        return {"case": label, "tau0": tau0, "nested": None, "detected": r["detected"]}
    bank = min(verdict.nested, key=lambda f: f["delta_bic"])
    mine = next(f for f in own if f.alternative == bank["alternative"])
    ln_n = float(np.log(keep["bank"].n_data))
    k_alt = int(bank["n_alt_params"])
    a = float(bank["delta_chi2_alone"])
    needed = a + (N_SPIRAL_PARAMETERS - k_alt) * ln_n + DetectionSettings().nested_threshold
    s_bank, s_own = float(bank["delta_chi2_spiral_alone"]), float(mine.delta_chi2_spiral_alone)
    return {"case": label, "tau0": tau0, "detected": r["detected"], "versus": bank["alternative"],
            "nested_delta_bic": round(bank["delta_bic"], 1), "own_nested_delta_bic": round(mine.delta_bic, 1),
            "spiral_alone_binds": bool(bank["delta_bic"] == bank["delta_bic_spiral_alone"]),
            "hypothesis": bank["hypothesis"], "k_alt": k_alt, "ln_N": round(ln_n, 3),
            "alternative": round(a, 1), "bank": round(s_bank, 1), "own": round(s_own, 1),
            "needed": round(needed, 1), "bank_of_own": round(s_bank / s_own, 3),
            "needed_of_own": round(needed / s_own, 3)}


SPANS = (("T",), ("T", "B"), ("T", "W", "B"), ("T", "W", "B", "D"))


def span(label: str, tau0: float, witness: str | None = None) -> dict:
    """The variants' blocks at the truth (module docstring, ``--span``): per variant template and per
    span of :data:`SPANS`, Δχ² on the data (free coefficients) and the captured fraction of the true
    spiral's power without noise; with ``witness``, that reference map as a template too."""
    from spiralbayes.inference.scan.engine import ScanContext
    from spiralbayes.model import perturbation_visibilities
    from spiralbayes.templates import make_template
    from spiralbayes.templates.variants import (DEFAULT_VARIANTS, blob_template, broad_template, coorbital_template,
                                                variant_template)
    from tests.templates.fidelity import reference_template

    case = _case(label)
    vis, axisym, geometry, *_ = rd.plant_and_scan(case, tau0)
    vis = vis.standardised()
    r_p, phi_p = rd.R_P_AU / rd.DISTANCE, float(np.radians(rd.PHI_P_DEG))
    residual = vis.V - axisym.visibilities(vis.u, vis.v, geometry)
    m, h, b = case.mu, case.h_p, case.beta
    blocks = {"T": make_template(m, tau0, b, "R", h_p=h, store_brightness=False),
              "W": broad_template(m, tau0, b, "R", h_p=h), "B": blob_template(m, tau0, b, "R", h_p=h),
              "D": coorbital_template(m, tau0, b, "R", h_p=h)}
    blocks.update({v: variant_template(m, tau0, b, "R", v, h_p=h) for v in DEFAULT_VARIANTS})
    profile = ScanContext.build(vis, axisym, geometry, [r_p], 8, x_max=3.0).profile

    def visibilities(t):
        return perturbation_visibilities(vis.u, vis.v, geometry, profile, t, r_p, phi_p)

    def inner(a, c):
        return float(np.sum(vis.weights * np.real(np.conj(a) * c)))

    truth = visibilities(reference_template(case, tau0))
    vb = {k: visibilities(t) for k, t in blocks.items()}
    own = inner(truth, truth)
    out = {"case": label, "tau0": tau0, "own_fixed": round(2 * inner(truth, residual) - own, 1),
           "own_free": round(inner(truth, residual) ** 2 / own, 1)}
    for v in DEFAULT_VARIANTS:
        x = vb[v]
        out[v] = {"fixed": round(2 * inner(x, residual) - inner(x, x), 1),
                  "free": round(inner(x, residual) ** 2 / inner(x, x), 1),
                  "captured": round(inner(x, truth) ** 2 / inner(x, x) / own, 3)}
    if witness is not None:
        x = visibilities(reference_template(_case(witness), tau0))
        out["witness"] = {"label": witness, "fixed": round(2 * inner(x, residual) - inner(x, x), 1),
                          "free": round(inner(x, residual) ** 2 / inner(x, x), 1),
                          "captured": round(inner(x, truth) ** 2 / inner(x, x) / own, 3)}
    for names in SPANS:
        cols = [vb[n] for n in names]
        gram = np.array([[inner(a, c) for c in cols] for a in cols])
        data = np.array([inner(a, residual) for a in cols])
        signal = np.array([inner(a, truth) for a in cols])
        out["+".join(names)] = {"free": round(float(data @ np.linalg.solve(gram, data)), 1),
                                "captured": round(float(signal @ np.linalg.solve(gram, signal)) / own, 3)}
    return out


def format_span_table(rows) -> str:
    keys = ["compromise", "hydro", "wakeflow", *("+".join(n) for n in SPANS)]
    lines = ["| case | τ0 | own map: Δχ² (A = 1, free A) | " + " | ".join(keys) + " | witness: Δχ² (A = 1) |",
             "|" + " --- |" * (4 + len(keys))]
    for r in rows:
        cells = [f"{r[k]['free']:.0f} ({100 * r[k]['captured']:.0f} %)" for k in keys]
        w = r.get("witness")
        cells.append("–" if w is None else f"{w['label']}: {w['fixed']:.0f} ({100 * w['captured']:.0f} %)")
        lines.append(f"| {r['case']} | {r['tau0']:g} | {r['own_fixed']:.0f}, {r['own_free']:.0f} | " + " | ".join(cells)
                     + " |")
    return "\n".join(lines)


def format_table(rows) -> str:
    lines = ["| case | τ0 | vs | Δχ² alternative alone | bank spiral / own map | needed | bank / own | "
             "needed / own | nested ΔBIC: bank, own |", "|" + " --- |" * 9]
    for r in rows:
        if "versus" not in r:
            lines.append(f"| {r['case']} | {r['tau0']:g} | – | – | – | – | – | – | no nested test |")
            continue
        lines.append(f"| {r['case']} | {r['tau0']:g} | {r['versus']} | {r['alternative']:.1f} "
                     f"| {r['bank']:.1f} / {r['own']:.1f} | {r['needed']:.1f} | {100 * r['bank_of_own']:.0f} % "
                     f"| {100 * r['needed_of_own']:.0f} % "
                     f"| {r['nested_delta_bic']:.1f}, {r['own_nested_delta_bic']:.1f} |")
    return "\n".join(lines)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="*", help="label@tau0, or label@tau0@witness with --span (default: the three "
                                                 "cases lost at test 3 alone)")
    parser.add_argument("--span", action="store_true",
                        help="instead: the variants' blocks at the truth with free coefficients (module docstring)")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    rows = []
    for item in args.cases or TEST3_CASES:
        label, tau0, *witness = item.split("@")
        if witness and not args.span:
            parser.error(f"{item}: a witness map (label@tau0@witness) needs --span")
        rows.append(span(label, float(tau0), *witness) if args.span else budget(label, float(tau0)))
        print(json.dumps(rows[-1]), flush=True)
    print((format_span_table if args.span else format_table)(rows))


if __name__ == "__main__":
    main()
