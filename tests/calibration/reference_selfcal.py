"""Does the gain solve of ``spiralbayes scan`` take planted reference spirals out of data without gain errors?

Shared by ``test_reference_selfcal.py`` (slow) and ``python -m tests.calibration.reference_selfcal`` (prints
the table of docs/calibration.md and writes it as JSON).

Set-up: the planted references of the detection table (:mod:`tests.inference.detection.reference_detection`:
every reference map at τ0 0.3 and 3 in the fiducial observation, 50 au, φ_p 40°, the true disc as the
axisymmetric model, the case's own map and the variant bank at its τ0 and β scanned over five radii
and 90 azimuths), without antenna gain errors. The gains are solved as the pipeline's second solve
does (:func:`spiralbayes.pipeline.calibrate.run_candidate_calibration`): per 60-s integration against
the disc plus the bank's best spiral at its scan peak, from visibilities down to model S/N 1. The
candidate is taken from the scan of the data as they are (the pipeline takes it from a scan of the data
after a first solve, which for data without gain errors differ from them by the noise that solve fits).
Both scans and the verdict's tests 1 and 2 are repeated on the corrected data.
"""

from __future__ import annotations

import json
import logging
import sys

import numpy as np

from tests.inference.detection import reference_detection as rd
from spiralbayes._provenance import atomic_path

log = logging.getLogger(__name__)


def evaluate(case, tau0: float, seed: int = rd.SEED, min_snr: float = 1.0) -> dict:
    """One row: the own map's and the bank's best Δχ² before and after the solve, and tests 1 and 2."""
    from spiralbayes.calibration import solve_gains
    from spiralbayes.inference.detection import detect
    from spiralbayes.inference.scan.run import scan
    from spiralbayes.pipeline.calibrate import candidate_spiral

    # docs/calibration.md's table was measured with the maps in the unperturbed disc
    vis, axisym, geometry, own, bank, templates = rd.plant_and_scan(case, tau0, seed, gap=False)
    vis = vis.standardised()
    dv, about = candidate_spiral(bank, vis, axisym, templates)
    disc = np.asarray(axisym.visibilities(vis.u, vis.v))
    ref = rd.reference_template(case, tau0)
    row = {"case": case.label, "tau0": tau0, "candidate": about["template"], "own_dchi2": own.best.delta_chi2,
           "bank_dchi2": bank.best.delta_chi2, "template": bank.best.template}
    v1 = detect(bank)
    row.update(bank_delta_bic=v1.delta_bic, tests12=[bool(v1.test1_passed), bool(v1.test2_passed)])
    # the first solve (the disc alone, S/N >= 5) and the second (the disc and the candidate, S/N >= min_snr)
    for key, model, snr in (("first", disc, 5.0), ("second", disc + dv, min_snr)):
        solution = solve_gains(vis, model, solve="phase", min_snr=snr)
        again = scan(solution.apply(vis), axisym, [ref, *templates], geometry, r_p=bank.r_p, distance=rd.DISTANCE,
                     progress=False)
        own2, bank2 = rd._rows(again, slice(0, 1)), rd._rows(again, slice(1, None))
        v2 = detect(bank2)
        row[key] = {"own_dchi2": own2.best.delta_chi2, "bank_dchi2": bank2.best.delta_chi2,
                    "bank_delta_bic": v2.delta_bic, "template": v2.template,
                    "position_kept": bool(bank.best.i_rp == bank2.best.i_rp and bank.best.i_phi == bank2.best.i_phi),
                    "tests12": [bool(v2.test1_passed), bool(v2.test2_passed)],
                    "solved_phase_rms_deg": solution.phase_rms_deg}
    return row


def format_table(rows) -> str:
    """Markdown table: one line per case × τ0; each cell ``as they are / first solve / second solve``."""
    lines = ["| case | τ0 | own Δχ² | bank best Δχ² | bank ΔBIC | same template and peak | tests 1/2 |",
             "| " + " | ".join(["---"] * 7) + " |"]

    def tests(t):
        return "".join("pf"[not x] for x in t)

    for r in rows:
        a, b = r["first"], r["second"]
        same = "/".join("yes" if s["template"] == r["template"] and s["position_kept"] else "**no**" for s in (a, b))
        lines.append(f"| {r['case']} | {r['tau0']:g} | {r['own_dchi2']:.0f} / {a['own_dchi2']:.0f} / "
                     f"{b['own_dchi2']:.0f} | {r['bank_dchi2']:.0f} / {a['bank_dchi2']:.0f} / {b['bank_dchi2']:.0f} | "
                     f"{r['bank_delta_bic']:.0f} / {a['bank_delta_bic']:.0f} / {b['bank_delta_bic']:.0f} | {same} | "
                     f"{tests(r['tests12'])} / {tests(a['tests12'])} / {tests(b['tests12'])} |")
    return "\n".join(lines)


def main(out: str = "reference_selfcal.json") -> None:
    logging.basicConfig(level=logging.WARNING)
    rows = []
    for case in sorted(rd.detection_cases(), key=lambda c: -c.mu):
        for tau0 in rd.TAUS:
            rows.append(evaluate(case, tau0))
            print(json.dumps(rows[-1]), flush=True)
            with atomic_path(out) as tmp:  # a run stopped mid-write keeps the rows it had
                tmp.write_text(json.dumps(rows, indent=1, default=float))
    print(format_table(rows))


if __name__ == "__main__":
    main(*sys.argv[1:])
