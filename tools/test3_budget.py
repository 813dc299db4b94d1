"""What test 3 asks of a template where a real planet loses it (a measurement, not a feature).

For each case, planted and judged as the reference-detection table does
(:func:`tests.inference.detection.reference_detection.evaluate`, the true disc as the axisymmetric
model), it takes the alternative that binds the nested test (the smallest statistic) and splits
test 3's statistic into Δχ² against the axisymmetric model:

* ``A``: the alternative alone (``k_alt`` parameters);
* ``S_bank``: the verdict's spiral alone at its nested position and hypothesis;
* ``S_own``: the reference map itself (the own template) the same way, the most any template
  could give;
* ``S_needed``: what a fixed-amplitude spiral alone (six parameters) must give to pass,
  ``A + (6 − k_alt) ln N + nested_threshold``.

``S_bank / S_own`` is how much of the true spiral the bank recovers and ``S_needed / S_own`` how
much it would have to. Where the joint fit (alternative + spiral) binds instead of the spiral alone,
the split is printed but the budget does not apply. Usage (``PYTHONPATH=src:.``)::

    python tools/test3_budget.py                           # the four arm cases lost to an arc at τ0 0.3
    python tools/test3_budget.py wakeflow:h0.05_mu1@0.3

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

ARM_CASES = ("wakeflow:h0.05_mu1@0.3", "fargo3dlib:h0.07_mu1_orbits200@0.3", "fargo3dlib:h0.07_mu1_orbits500@0.3",
             "fargo3dlib:h0.07_mu1_nu1e-04@0.3")


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
    parser.add_argument("cases", nargs="*", help="label@tau0 (default: the four arm cases lost to an arc at τ0 0.3)")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    rows = []
    for item in args.cases or ARM_CASES:
        label, tau0 = item.split("@")
        rows.append(budget(label, float(tau0)))
        print(json.dumps(rows[-1]), flush=True)
    print(format_table(rows))


if __name__ == "__main__":
    main()
