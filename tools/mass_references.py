"""The continuous-mass posterior on planted reference spirals: how far is the median from the truth?

For each reference map (``tests/data/references``, read with ``tests/templates/fidelity.py``)
planted in the fiducial observation (with its thermal noise) at 50 au, φ_p = 40°, inclination 30°,
frank is fitted at the true geometry and ``sample_posterior(..., mass="continuous")`` runs with the
families of the robust bank at the reference's τ0, β and H/r (one per morphology variant, right-handed).
Prints, per reference, the template mass's posterior (median, 68 and 95 % intervals, mixed over the
families by their evidences; the mismatch systematic left out) and each family's share, and appends
it to ``<out>/rows.jsonl``. ``--calibrate`` reads such rows and prints the maximum-likelihood
mismatch systematic (:data:`spiralbayes.inference.posterior.mass.MASS_SYSTEMATIC`), and whether each
source's cases, held out, fall inside their 95 % intervals widened by the other sources' systematic.

    PYTHONPATH=src:. python tools/mass_references.py --cases fargo3dlib:h0.07_mu1 wakeflow:h0.07_mu0.3
    PYTHONPATH=. python tools/mass_references.py --calibrate mass_references_output/rows.jsonl
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import warnings
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402


def run_case(label: str, tau0: float, out: Path, variants, steps: int, walkers: int, references=None) -> dict:
    import spiralbayes as sb
    from spiralbayes.simulate import DiscModel, simulate_observation
    from spiralbayes.templates.variants import variant_template
    from tests.templates import fidelity as F

    case = next(c for c in F.reference_cases(references) if c.label == label)
    ref = F.reference_template(case, tau0)
    geometry = sb.DiscGeometry(30.0, 60.0)
    r_true, phi_true = F.R_P_AU / F.DISTANCE, np.radians(40.0)
    disc = DiscModel(distance=F.DISTANCE, r_ref=F.R_P_AU, tau_ref=tau0)
    vis = simulate_observation("fiducial", disc, geometry, ref, r_p=r_true, phi_p=phi_true, seed=3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = sb.fit_axisymmetric(vis, geometry, progress=False)
    members = [variant_template(1.0, tau0, case.beta, "R", v, h_p=case.h_p) for v in variants]
    priors = sb.Priors.default(model, r_p=(r_true - 0.08, r_true + 0.08))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # the template's mass as the likelihood sees it: the mismatch systematic is what these runs calibrate
        post = sb.sample_posterior(vis, model, members, priors=priors, mass="continuous", chains_dir=out,
                                   mass_prior=sb.MassPrior(systematic=0.0),
                                   run_name=f"{label.replace(':', '_')}_tau{tau0:g}", n_walkers=walkers,
                                   n_steps=steps, evidence_draws=400, convergence="ignore", progress=False,
                                   likelihood_kwargs={"rp_tolerance": 0.05})
    m = post.mass_posterior()["mth"]
    return {"case": label, "tau0": tau0, "truth": case.mu, "median": m["median"], "lo": m["lo"], "hi": m["hi"],
            "lo95": m["lo95"], "hi95": m["hi95"], "families": post.template_probabilities,
            "p_planet": post.p_planet,
            "per_family": {r.name: r.percentiles()["M_p"]["median"] for r in post.runs}}


def source_of(label: str, references) -> str:
    """The code or run set a case comes from: the calibration holds one of them out at a time."""
    if references:
        return Path(references[0]).parent.name
    return {"fargo3dlib": "fargo3d library", "fargo3d": "fargo3d library"}.get(label.split(":")[0], label.split(":")[0])


def calibrate(paths: list[str]) -> None:
    """Print the mismatch systematic from all rows and, one source held out at a time, whether the
    held-out cases' 95 % intervals widened by the others' systematic hold their truth."""
    from tests._support.mass_calibration import held_out, load_rows, systematic_ml

    rows = load_rows(paths)
    print(f"{len(rows)} planted references from {len({row['source'] for row in rows})} sources; maximum-likelihood "
          f"systematic over all: {systematic_ml(rows):.3f} in ln M_p")
    print("| held out | case | truth [M_th] | median | ln(truth/median) | own σ (95 % / 1.96) | systematic from the "
          "others | z | inside 95 % |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for row in held_out(rows):
        inside = "yes" if row["inside95"] else "no"
        print(f"| {row['source']} | {row['case']} | {row['truth']:g} | {row['median']:.2f} | {row['ln_offset']:+.2f} | "
              f"{row['sigma95']:.2f} | {row['systematic']:.3f} | {row['z']:+.2f} | {inside} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cases", nargs="+", default=["fargo3dlib:h0.07_mu1", "fargo3dlib:h0.07_mu0.3"])
    parser.add_argument("--tau0", type=float, default=3.0)
    parser.add_argument("--variants", nargs="+", default=["compromise", "hydro", "wakeflow"])
    parser.add_argument("--steps", type=int, default=600)
    parser.add_argument("--walkers", type=int, default=20)
    parser.add_argument("--out", default="mass_references_output")
    parser.add_argument("--references", nargs="+", default=None,
                        help="reduced reference files to take the cases from (default: the committed ones)")
    parser.add_argument("--calibrate", nargs="+", metavar="ROWS", default=None,
                        help="no runs: the mismatch systematic from these rows.jsonl files, one source held out "
                             "at a time")
    args = parser.parse_args()
    if args.calibrate:
        calibrate(args.calibrate)
        return
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
    for noisy in ("arviz", "spiralbayes.inference.posterior.perturbation", "spiralbayes.inference.posterior.mass"):
        logging.getLogger(noisy).setLevel(logging.WARNING)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for label in args.cases:
        row = run_case(label, args.tau0, out, args.variants, args.steps, args.walkers, args.references)
        row["source"] = source_of(label, args.references)
        with open(out / "rows.jsonl", "a") as f:
            f.write(json.dumps(row) + "\n")
        shares = ", ".join(f"{k}: P {v:.2f}, M {row['per_family'][k]:.2f}" for k, v in row["families"].items())
        print(f"{row['case']} tau0 {row['tau0']:g}: truth {row['truth']:g} M_th; median {row['median']:.2f} "
              f"(68 %: {row['lo']:.2f}-{row['hi']:.2f}; 95 %: {row['lo95']:.2f}-{row['hi95']:.2f}); "
              f"P(planet) {row['p_planet']:.3g}; {shares}", flush=True)


if __name__ == "__main__":
    main()
