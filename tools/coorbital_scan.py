"""What a free-amplitude co-orbital dust block would do to detection (a measurement, not a feature).

Each case is planted and scanned as the reference-detection table does
(:mod:`tests.inference.detection.reference_detection`: fiducial observation, 50 au, φ_p 40°, the
true disc as the axisymmetric model, the 72-template variant bank at the case's τ0 and β on
5 radii × 90 azimuths). Every bank template ``T`` then gets the co-orbital block ``D`` of its own
mass, τ0, H/r and hand (:func:`spiralbayes.templates.variants.coorbital_template`) with a free
amplitude ``c >= 0``. With the terms of :func:`spiralbayes.inference.scan.pair_terms` at every
planet position,

* ``S = 2 X_T - P_TT``: the scan's Δχ² (the template at its fixed amplitude);
* ``S + max(0, X_D - P_TD)² / P_DD``: the template with the block ("with block"; one more
  parameter, so its ΔBIC subtracts ``7 ln N``);
* ``G = max(0, X_D)² / P_DD``: the block alone at that position;
* ``A = (with block) - G``: what the template's arms add to the block ("arms").

For the best instance with the block it prints tests 1 and 2 of
:func:`spiralbayes.inference.detection.detect` on the scores with the block, the handedness ratio and
localisation recomputed on ``A`` (the mirror template with its own block, whose band half a turn
on is the same band), and where ``A`` itself peaks; with ``--nested``, test 3 with the block
(:func:`nested_with_block`). Usage (``PYTHONPATH=src:.``)::

    python tools/coorbital_scan.py                      # the library's dust runs, τ0 0.3 and 3
    python tools/coorbital_scan.py fargo3dlib:h0.07_mu1@0.3 --width 1.0
    python tools/coorbital_scan.py fargo3dlib:h0.07_mu1_st0.03@0.3 --nested   # and test 3 with the block
    python tools/coorbital_scan.py --false-alarms planet_free,lopsided,eccentric_ring,arc 15

One JSON line per case, then a Markdown table.
"""

from __future__ import annotations

import argparse
import json
import logging
from dataclasses import replace

import numpy as np

from spiralbayes.inference.detection import DetectionSettings, detect
from spiralbayes.inference.detection.verdict import handedness_ratio, localisation
from spiralbayes.inference.scan import ScanContext, bic_threshold, pair_terms
from spiralbayes.templates.variants import coorbital_template
from tests.inference.detection import reference_detection as rd

log = logging.getLogger("coorbital_scan")

SETTINGS = DetectionSettings()
N_WITH_BLOCK = 7
"""Parameters of a template with the block: the scan's six and the block's amplitude."""

DUST_CASES = ("fargo3dlib:h0.07_mu1_st0.03", "fargo3dlib:h0.07_mu1_st0.01", "fargo3dlib:h0.07_mu1_st0.1",
              "fargo3dlib:h0.07_mu1_st0.1_orbits200", "fargo3dlib:h0.07_mu3_st0.01")


def _offsets(result, i_rp: int, i_phi: int) -> tuple[int, float]:
    dphi = np.degrees(np.angle(np.exp(1j * (result.phi_p[i_phi] - np.radians(rd.PHI_P_DEG)))))
    return int(i_rp - rd.N_RP // 2), round(float(dphi), 1)


def block_scores(vis, axisym, geometry, result, templates, width: float = 1.0):
    """Per template and planet position of ``result``: the block at its best amplitude added to the
    template (Δχ²), the block alone (Δχ²), and that amplitude; and two views of ``result`` whose
    fixed-amplitude Δχ² are "with the block" and "arms" (module docstring)."""
    ctx = ScanContext.build(vis.standardised(), axisym, geometry, np.asarray(result.r_p), result.phi_p.size,
                            x_max=max(float(t.x[-1]) for t in templates))
    block, band, amplitude = (np.empty_like(result.cross) for _ in range(3))
    blocks: dict = {}
    for k, t in enumerate(templates):
        key = (t.mass, t.tau0, t.h_p, t.hand)
        if key not in blocks:
            blocks[key] = coorbital_template(t.mass, t.tau0, t.beta, t.hand, h_p=t.h_p, width=width)
        x_t, p_t, x_d, p_d, p_td = pair_terms(ctx, t, blocks[key])
        lift = np.maximum(x_d - p_td, 0.0)
        block[k] = 2 * x_t - p_t + lift**2 / p_d
        amplitude[k] = lift / p_d
        band[k] = np.maximum(x_d, 0.0) ** 2 / p_d

    def view(values):  # a ScanResult whose Δχ² (fixed amplitude, 2 cross − power) is ``values``
        return replace(result, cross=0.5 * (values + result.power))

    return block, band, amplitude, view(block), view(block - band)


def measure(label: str, tau0: float, width: float = 1.0, nested: bool = False) -> dict:
    case = next(c for c in rd.detection_cases() if c.label == label)
    vis, axisym, geometry, own, bank, templates = rd.plant_and_scan(case, tau0)
    block, band, amplitude, with_block, arms = block_scores(vis, axisym, geometry, bank, templates, width)
    first = detect(bank)
    verdict = detect(with_block)
    best = with_block.best
    k, i, j = best.template_index, best.i_rp, best.i_phi
    a = arms.delta_chi2()
    top = np.unravel_index(int(np.argmax(a)), a.shape)
    delta_bic = float(block[k, i, j] - bic_threshold(bank.n_data, N_WITH_BLOCK))
    out = {
        "case": label, "tau0": tau0, "width_Hp": width, "own_delta_bic": round(own.best.delta_bic, 1),
        "scan": {"delta_bic": round(first.delta_bic, 1), "template": bank.best.template,
                 "offset": _offsets(bank, bank.best.i_rp, bank.best.i_phi), "test1": first.test1_passed,
                 "test2": first.test2_passed},
        "with_block": {"delta_bic": round(delta_bic, 1),
                       "template": best.template, "offset": _offsets(bank, i, j),
                       "amplitude": round(float(amplitude[k, i, j]), 3), "block_alone": round(float(band[k, i, j]), 1),
                       "arms": round(float(a[k, i, j]), 1), "test1": delta_bic > SETTINGS.bic_threshold_value,
                       "test2": verdict.test2_passed, "handedness_ratio": round(verdict.handedness_ratio, 3),
                       "localisation": round(verdict.localisation, 3),
                       "arms_handedness_ratio": round(handedness_ratio(arms, k, i, j), 3),
                       "arms_localisation": round(localisation(arms, k), 3)},
        "arms_peak": {"template": templates[top[0]].name, "offset": _offsets(bank, top[1], top[2]),
                      "arms": round(float(a[top]), 1)},
    }
    if nested:
        out["nested_with_block"] = nested_with_block(vis, axisym, geometry, with_block, templates, k,
                                                     float(amplitude[k, i, j]), width)
    return out


def nested_with_block(vis, axisym, geometry, with_block, templates, k: int, c: float, width: float) -> list[dict]:
    """Test 3 (the nested test of :mod:`spiralbayes.inference.detection.nested`) with the spiral
    ``T + c D``: the best template with its block at the scanned amplitude ``c`` (held fixed in the
    joint fits), scored with one more parameter than the nested test counts for ``T``."""
    from spiralbayes.inference.detection import fit_alternatives
    from spiralbayes.inference.detection.nested import nested_test

    t = templates[k]
    d = coorbital_template(t.mass, t.tau0, t.beta, t.hand, h_p=t.h_p, width=width)
    joined = list(templates)
    joined[k] = replace(t, delta=t.delta + c * d.delta, name=f"{t.name}+{c:.3g}D")
    alternatives = fit_alternatives(vis, axisym, geometry, progress=False)
    fits = nested_test(with_block, vis, axisym, joined, alternatives, geometry, template=k,
                       n_alternatives=SETTINGS.nested_alternatives)
    ln_n = float(np.log(with_block.n_data))
    return [{"versus": f.alternative, "delta_bic": round(f.delta_bic - ln_n, 1),
             "joint": round(f.delta_bic_joint - ln_n, 1), "spiral_alone": round(f.delta_bic_spiral_alone - ln_n, 1),
             "hypothesis": f.hypothesis, "dphi_deg": round(f.phi_p_deg - rd.PHI_P_DEG, 1),
             "passes": f.delta_bic - ln_n > SETTINGS.nested_threshold} for f in fits]


def false_alarm_probe(kinds, n: int, width: float = 1.0) -> list[dict]:
    """The block on the false-alarm set's data (:mod:`tests.inference.detection.false_alarms`: its
    24-template scan, ``n`` datasets of each kind): test 1 with the block (7 parameters) and test 2's
    mirror ratio and localisation on the arms at the best instance with the block. ``flag``: all
    three pass (a claim before test 3)."""
    from spiralbayes.inference.scan.run import scan
    from tests.inference.detection import false_alarms as fa, planet_free as pf

    rows = []
    for i in range(n):
        for kind in kinds:
            seed = fa.seeds(kind)[i]
            vis, axisym, geometry, _ = fa.dataset(kind, seed)
            templates = pf.bank_templates()
            result = scan(vis, axisym, list(templates), geometry, r_p=pf.R_GRID, distance=pf.DISTANCE, progress=False)
            block, band, amplitude, with_block, arms = block_scores(vis, axisym, geometry, result, templates, width)
            b = with_block.best
            k, i_rp, i_phi = b.template_index, b.i_rp, b.i_phi
            delta_bic = float(block[k, i_rp, i_phi] - bic_threshold(result.n_data, N_WITH_BLOCK))
            ratio, area = handedness_ratio(arms, k, i_rp, i_phi), localisation(arms, k)
            rows.append({"kind": kind, "seed": seed, "scan_delta_bic": round(detect(result).delta_bic, 1),
                         "with_block_delta_bic": round(delta_bic, 1),
                         "block_alone": round(float(band[k, i_rp, i_phi]), 1),
                         "amplitude": round(float(amplitude[k, i_rp, i_phi]), 3),
                         "arms_handedness_ratio": round(ratio, 3), "arms_localisation": round(area, 3),
                         "flag": bool(delta_bic > SETTINGS.bic_threshold_value and ratio < SETTINGS.max_handedness_ratio
                                      and area < SETTINGS.max_localisation)})
            print(json.dumps(rows[-1]), flush=True)
    for kind in kinds:
        mine = [r for r in rows if r["kind"] == kind]
        passed = SETTINGS.bic_threshold_value
        print(f"{kind}: {len(mine)} datasets, test 1 passed {sum(r['scan_delta_bic'] > passed for r in mine)} without "
              f"the block and {sum(r['with_block_delta_bic'] > passed for r in mine)} with it, "
              f"flagged {sum(r['flag'] for r in mine)}")
    return rows


def format_table(rows) -> str:
    head = ("| case | τ0 | own ΔBIC | scan: ΔBIC, best (Δr_p, Δφ_p), tests 1/2 "
            "| with block: ΔBIC, best (Δr_p, Δφ_p), c | block alone / arms at that place "
            "| handedness ratio: all / arms | arms peak (Δr_p, Δφ_p) |")
    lines = [head, "|" + " --- |" * 8]
    yes = {True: "pass", False: "fail"}

    def where(d):
        return f"{d['template']} ({d['offset'][0]:+d}, {d['offset'][1]:+.0f}°)"

    for r in rows:
        s, w, p = r["scan"], r["with_block"], r["arms_peak"]
        lines.append(
            f"| {r['case']} | {r['tau0']:g} | {r['own_delta_bic']:.0f} "
            f"| {s['delta_bic']:.0f}, {where(s)}, {yes[s['test1']]}/{yes[s['test2']]} "
            f"| {w['delta_bic']:.0f}, {where(w)}, {w['amplitude']:.2f} | {w['block_alone']:.0f} / {w['arms']:.0f} "
            f"| {w['handedness_ratio']:.2f} / {w['arms_handedness_ratio']:.2f} | {p['arms']:.0f}, {where(p)} |")
    return "\n".join(lines)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="*", help="label@tau0 (default: the library's dust runs at τ0 0.3 and 3)")
    parser.add_argument("--width", type=float, default=1.0, help="the band's Gaussian width [H_p] (default 1)")
    parser.add_argument("--nested", action="store_true",
                        help="also test 3 (nested, the best two alternatives) with the block at its scanned amplitude")
    parser.add_argument("--false-alarms", nargs=2, metavar=("KINDS", "N"),
                        help="instead: the false-alarm set's data, N datasets of each of KINDS (comma-separated, "
                             "e.g. planet_free,lopsided,eccentric_ring,arc)")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    if args.false_alarms:
        false_alarm_probe(args.false_alarms[0].split(","), int(args.false_alarms[1]), args.width)
        return
    items = args.cases or [f"{c}@{t:g}" for c in DUST_CASES for t in rd.TAUS]
    rows = []
    for item in items:
        label, tau0 = item.split("@")
        rows.append(measure(label, float(tau0), args.width, args.nested))
        print(json.dumps(rows[-1]), flush=True)
    print(format_table(rows))


if __name__ == "__main__":
    main()
