"""Which simulated maps come close to a planted reference spiral: one planting of
:mod:`tests.inference.detection.reference_detection` scanned with the variant bank and the widest map
pool (every reference map but the planted one, its own source's included), each template's best
ΔBIC and place, and the verdict. docs/verdict.md ("What the six still lost would need").

``python -m tests.inference.detection.map_pool CASE TAU0 [NAME_PART ...]``, e.g.
``python -m tests.inference.detection.map_pool fargo3d:h0.07_mu1 0.3 nu1e-06``: the ten best
templates, then every template whose name holds one of the ``NAME_PART`` strings (the same planet
simulated another way), then the verdict's numbers. About two minutes a planting on one core.
"""

from __future__ import annotations

import logging
import sys

import numpy as np

from tests.inference.detection import reference_detection as rd

log = logging.getLogger(__name__)


def ranked(result) -> list[tuple]:
    """``(delta_bic, name, Δr_p [grid steps], Δφ_p [deg])`` of each template's best, highest first,
    relative to the planted position."""
    r_true, phi_true = rd.R_P_AU / rd.DISTANCE, np.radians(rd.PHI_P_DEG)
    rows = []
    for i, meta in enumerate(result.templates):
        peak = result.peak(i)
        rows.append((peak.delta_bic, meta["name"], (peak.r_p - r_true) / rd.RP_STEP,
                     float(np.degrees(np.angle(np.exp(1j * (peak.phi_p - phi_true)))))))
    return sorted(rows, reverse=True)


def main(label: str, tau0: str, *name_parts: str) -> None:
    logging.basicConfig(level=logging.WARNING)
    try:
        case = rd.find_case(label)
    except KeyError as err:
        raise SystemExit(str(err)) from None
    _, _, _, own, bank, templates = rd.plant_and_scan(case, float(tau0), maps=True, every_source=True)
    rows = ranked(bank)
    print(f"{label} tau0 {tau0}: own map Delta BIC {own.best.delta_bic:.1f}; {len(templates)} templates")

    def line(r):
        return f"{r[0]:9.1f}  {r[1]:52s} dr {r[2]:+.0f} steps, dphi {r[3]:+.0f} deg"

    for r in rows[:10]:
        print(line(r))
    for part in name_parts:
        for r in rows:
            if part in r[1]:
                print(f"[{part}] {line(r)}")
    row = rd.evaluate(case, float(tau0), maps=True, every_source=True)
    print({k: row[k] for k in ("template", "delta_bic", "dr_steps", "dphi_deg", "test1", "test2", "test3",
                               "nested_delta_bic", "nested_vs", "detected")})


if __name__ == "__main__":
    main(*sys.argv[1:])
