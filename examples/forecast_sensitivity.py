"""Does 8 h on source bring much over 40 min? The paper's comparison as a forecast (docs/limits.md).

    python examples/forecast_sensitivity.py

For each right-handed template of the compromise bank (the paper's single morphology) at H/r = 0.07
(4 masses x 4 optical depths x 2 cooling times)
a planet at 50 au in the paper's power-law disc (140 pc, the disc's optical depth at 50 au equal to
the template's tau0), observed with the fiducial set (C-4 + C-7, 40 min, 35 uJy/beam) and the
high-sensitivity set (8 h, 10 uJy/beam): E[Δχ²], the threshold 6 ln N + 10 and P(ΔBIC > 10).
Then, per (tau0, beta) family, the mass at which E[Δχ²] reaches the threshold (P = 50 %),
interpolated in log E - log M (extrapolated below the lightest bank mass), for both sets and
their ratio.
"""

import numpy as np

import spiralbayes as sb
from spiralbayes.inference.limits import compare_setups, detectable_mass

R_P = 50.0 / 140.0
SETUPS = ("fiducial", "high_sensitivity")


def main():
    bank = list(sb.compromise_bank().select(hand="R", h_p=0.07))
    rows = compare_setups(lambda t: sb.DiscModel(distance=140.0, r_ref=50.0, tau_ref=t.tau0), bank, R_P, SETUPS)
    print(f"{'template':26s} {'E fid':>10s} {'P fid':>6s} {'E 8 h':>11s} {'P 8 h':>6s}")
    for r in rows:
        print(f"{r['template']:26s} {r['E_fiducial']:10.1f} {r['P_fiducial']:6.2f} "
              f"{r['E_high_sensitivity']:11.1f} {r['P_high_sensitivity']:6.2f}")
    print(f"thresholds 6 ln N + 10: fiducial {rows[0]['threshold_fiducial']:.1f}, "
          f"8 h {rows[0]['threshold_high_sensitivity']:.1f}")
    counts = {s: sum(r[f"P_{s}"] > 0.5 for r in rows) for s in SETUPS}
    print(f"templates with P > 0.5: fiducial {counts['fiducial']} of {len(rows)}, 8 h {counts['high_sensitivity']}")
    print("minimum detectable mass (P = 50 %) per family [M_th]: fiducial, 8 h, ratio")
    for tau0 in (0.1, 0.3, 1.0, 3.0):
        for beta in (0.0, 10.0):
            fam = sorted((r for r in rows if r["tau0"] == tau0 and r["beta"] == beta), key=lambda r: r["mass"])
            masses = [r["mass"] for r in fam]
            det = [detectable_mass(masses, [r[f"E_{s}"] for r in fam], fam[0][f"threshold_{s}"]) for s in SETUPS]
            slope = np.polyfit(np.log(masses), np.log([r["E_fiducial"] for r in fam]), 1)[0]
            text = ", ".join(f"{m:.3g}{' (extrapolated)' if ext else ''}" for m, ext in det)
            print(f"  tau0={tau0:g}, beta={beta:g}: {text}, x{det[0][0] / det[1][0]:.2f} (E ~ M^{slope:.1f})")

if __name__ == "__main__":
    main()
