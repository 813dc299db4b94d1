"""What antenna gain errors do to the verdict, with and without ``[calibration] solve``.

For each antenna phase rms and noise seed, the fiducial preset (C-4 + C-7, 36,120 visibilities, default
disc at 140 pc, inc 30 deg, PA 60 deg; ``--preset taurus`` for the faint Taurus set-up) is simulated
without a planet and with a 1 M_th planet (``--planet-mass``; the
command line's ``simulate --planet-mass 1``: the compromise template tau0 = 3, beta = 10, at 50 au,
phi_p = 0), corrupted by antenna gains (phase rms as given, 5 % amplitudes or ``--amp-rms``; 180-s phase and 600-s
amplitude coherence, as in the measurement that motivated the solve), and run through ``spiralbayes
scan`` (frank, the solve, the scan of the default bank's tau0 = 3 templates on the default grid, the
competing asymmetry models, the verdict and, when the geometry alternative is significant and nothing
is claimed, the rescan at the refitted geometry). Printed per run: whether a planet is claimed, the
best template and its position, ΔBIC, test 3's best alternative, the same after the geometry refit,
the solved phase rms and the residual antenna phase rms (:func:`spiralbayes.diagnose_calibration` of
the corrected data against the same observation without noise or gain errors). A Markdown table is
written to ``OUT/table.md``.

    python tools/calibration_table.py --out /tmp/caltable                 # 0, 10, 30 deg, seed 1, solve phase
    python tools/calibration_table.py --phase-rms 0 3 10 30 60 --seeds 1 2 3 --solve none phase
    python tools/calibration_table.py --preset taurus --planet-mass 3 --phase-rms 0 10 30 --solve none phase
    python tools/calibration_table.py --phase-rms 30 --candidate-min-snr 0   # the first solve only
"""

from __future__ import annotations

import argparse
import json
import logging
import time
from pathlib import Path

import spiralbayes as sb
from spiralbayes.config import merge_config
from spiralbayes.io import load_visibilities, save_visibilities
from spiralbayes.pipeline import run_scan
from spiralbayes.simulate import GainErrors, simulate_observation
from spiralbayes.templates import make_template
from spiralbayes._provenance import atomic_path

log = logging.getLogger("calibration_table")

PLANET_AU, DISTANCE = 50.0, 140.0


PRESET = "fiducial"
PLANET_MASS = 1.0
AMP_RMS = 0.05


def simulate(planet: bool, phase_rms: float, seed: int, noise: bool = True, preset: str = PRESET,
             mass: float = PLANET_MASS, amp_rms: float = AMP_RMS):
    perturbation = make_template(mass, 3.0, 10.0, "R") if planet else None
    gains = GainErrors(phase_rms, amp_rms, coherence_s=180.0, amp_coherence_s=600.0, seed=seed) if noise else None
    return simulate_observation(preset, perturbation=perturbation, r_p=PLANET_AU / DISTANCE if planet else None,
                                phi_p=0.0 if planet else None, seed=seed, gains=gains, add_noise=noise)


def run_case(out: Path, planet: bool, phase_rms: float, seed: int, solve: str, keep_position: bool = True,
             min_snr: float | None = None, preset: str = PRESET, mass: float = PLANET_MASS,
             candidate_min_snr: float | None = None, amp_rms: float = AMP_RMS) -> dict:
    name = f"{'planet' if planet else 'free'}_{phase_rms:g}deg_seed{seed}_{solve.replace('+', '')}" + \
        ("" if keep_position else "_nokeep") + ("" if min_snr is None else f"_snr{min_snr:g}") + \
        ("" if candidate_min_snr is None else f"_cand{candidate_min_snr:g}") + \
        ("" if amp_rms == AMP_RMS else f"_amp{amp_rms:g}")
    calibration = {"solve": solve, "keep_position": keep_position}
    if candidate_min_snr is not None:
        calibration["candidate_min_snr"] = candidate_min_snr
    if min_snr is not None:
        calibration["min_snr"] = min_snr
    folder = out / name
    data = save_visibilities(simulate(planet, phase_rms, seed, preset=preset, mass=mass, amp_rms=amp_rms),
                             out / f"{name}.h5")
    config = merge_config({"data": {"path": str(data)}, "geometry": {"inc": 30.0, "PA": 60.0, "distance": DISTANCE},
                           "calibration": calibration,
                           "templates": {"tau0": [3.0]},
                           "output": {"dir": str(folder), "plots": False}})
    t0 = time.perf_counter()
    run = run_scan(config, progress=False, overwrite=True)
    v = run.verdict
    follow = run.follow_up.verdict if run.follow_up is not None else None
    row = {"case": name, "planet": planet, "phase_rms": phase_rms, "seed": seed, "solve": solve,
           "detected": bool(v.detected), "template": v.template, "r_p_au": v.r_p * DISTANCE,
           "phi_p_deg": v.phi_p_deg, "delta_bic": v.delta_bic,
           "keep_position": keep_position, "min_snr": min_snr, "preset": preset, "planet_mass": mass,
           "candidate_min_snr": candidate_min_snr, "amp_rms": amp_rms,
           "test1": v.test1_passed, "test2": v.test2_passed,
           "test3": v.test3_passed, "best_alternative": v.best_alternative,
           "alternative_delta_bic": v.alternative_delta_bic, "explanation": v.explanation,
           "time_s": time.perf_counter() - t0,
           "refit": None if follow is None else {
               "detected": bool(follow.detected), "template": follow.template, "r_p_au": follow.r_p * DISTANCE,
               "phi_p_deg": follow.phi_p_deg, "delta_bic": follow.delta_bic,
               "best_alternative": follow.best_alternative, "alternative_delta_bic": follow.alternative_delta_bic,
               "explanation": follow.explanation}}
    # the residual errors against the truth: the diagnostic on the corrected data and the noise-free,
    # error-free observation (a per-integration solve against frank's fit to them finds nothing by construction)
    truth = simulate(planet, 0.0, seed, noise=False, preset=preset, mass=mass)
    raw = load_visibilities(data)
    corrected = raw if run.gains is None else run.gains.apply(raw)
    row.update(solved_phase_rms=None if run.gains is None else run.gains.phase_rms_deg,
               residual_phase_rms=sb.diagnose_calibration(corrected, truth.V).phase_rms_deg)
    print(json.dumps(row), flush=True)
    return row


def markdown(rows: list) -> str:
    lines = ["| data | phase rms [deg] | seed | solve | claimed | best template (r_p au, phi_p deg) | Delta BIC | "
             "tests 1/2/3 | test 3's best alternative (Delta BIC) | explanation | after the geometry refit | "
             "solved rms [deg] | residual rms [deg] |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        tests = "/".join({True: "p", False: "f", None: "-"}[r[k]] for k in ("test1", "test2", "test3"))
        solved = "-" if r["solved_phase_rms"] is None else f"{r['solved_phase_rms']:.1f}"
        f = r["refit"]
        refit = "-" if f is None else (f"{'claimed' if f['detected'] else 'not claimed'}: {f['template']} "
                                       f"({f['r_p_au']:.0f}, {f['phi_p_deg']:.0f}), Delta BIC {f['delta_bic']:.0f}; "
                                       f"{f['best_alternative']} ({f['alternative_delta_bic']:.0f}); "
                                       f"explanation {f.get('explanation')}")
        solve = r["solve"] + ("" if r.get("keep_position", True) else ", keep_position false") + \
            ("" if r.get("min_snr") is None else f", min_snr {r['min_snr']:g}") + \
            ("" if r.get("candidate_min_snr") is None else f", candidate_min_snr {r['candidate_min_snr']:g}")
        lines.append(f"| {'planet' if r['planet'] else 'no planet'} | {r['phase_rms']:g} | {r['seed']} | "
                     f"{solve} | {'yes' if r['detected'] else 'no'} | {r['template']} ({r['r_p_au']:.0f}, "
                     f"{r['phi_p_deg']:.0f}) | {r['delta_bic']:.0f} | {tests} | {r['best_alternative']} "
                     f"({r['alternative_delta_bic']:.0f}) | {r.get('explanation')} | {refit} | {solved} | "
                     f"{r['residual_phase_rms']:.1f} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("calibration-table"))
    parser.add_argument("--phase-rms", type=float, nargs="+", default=[0.0, 10.0, 30.0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1])
    parser.add_argument("--solve", nargs="+", default=["phase"], choices=["none", "phase", "amplitude+phase"])
    parser.add_argument("--no-keep-position", action="store_true", help="[calibration] keep_position = false")
    parser.add_argument("--min-snr", type=float, default=None, help="[calibration] min_snr (default: the package's)")
    parser.add_argument("--candidate-min-snr", type=float, default=None,
                        help="[calibration] candidate_min_snr (the second solve; 0: none; default: the package's)")
    parser.add_argument("--data", choices=["both", "no-planet", "planet"], default="both",
                        help="which simulations to run (default both)")
    parser.add_argument("--preset", default=PRESET, help="observation preset (fiducial, taurus, ...)")
    parser.add_argument("--planet-mass", type=float, default=PLANET_MASS, help="planet mass [M_th]")
    parser.add_argument("--amp-rms", type=float, default=AMP_RMS,
                        help=f"antenna amplitude error rms, fractional (default {AMP_RMS})")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    args.out.mkdir(parents=True, exist_ok=True)
    keep = not args.no_keep_position
    rows = [run_case(args.out, planet, rms, seed, solve, keep, args.min_snr, args.preset, args.planet_mass,
                     args.candidate_min_snr, args.amp_rms)
            for solve in args.solve
            for planet in {"both": (False, True), "no-planet": (False,), "planet": (True,)}[args.data]
            for rms in args.phase_rms for seed in args.seeds]
    (args.out / "table.md").write_text(markdown(rows))
    with atomic_path(args.out / "rows.json") as tmp:
        tmp.write_text(json.dumps(rows, indent=1))
    print(markdown(rows))


if __name__ == "__main__":
    main()
