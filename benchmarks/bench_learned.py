"""The learned template model's cost beside the generator's: making templates, scanning them, sampling.

``bank``       per template, on the scan benchmark's observation (~1e5 visibilities, C-4 + C-7, 0.87 mm,
               25 r_p x 90 phi_p, 2 threads): the learned model's prediction
               (``LearnedTemplateModel.predict``) against the generator's ``make_template`` (the
               compromise morphology, the paper's grid), and the scan's CPU and wall time per template of
               ``--templates`` learned templates (one disc, the paper's masses and τ0, both hands) against as
               many of the compromise bank's at the same masses, τ0 and H/r, in the same process. Target: the
               learned bank's scan costs at most 2x the generator's per template.
``posterior``  wall time of the continuous-mass posterior (``mass="continuous"``) on the posterior tests'
               weak observation (1500 baselines): one learned family (``learned_family``) against the
               generator's family at the same τ0, hand and H/r, same walkers, steps and seed.
``physics``    wall time of the posterior with the physics free (``physics_posterior``) on the same data:
               H/r 0.05-0.10 every 0.005, the learned bank's three slopes and viscosities, ``--masses``
               masses, both hands, the default position grid (100 r_p x 360 phi_p), and what it finds; beside
               the continuous-mass posterior's time for one family (``posterior``), a run of which per disc
               and H/r value would be the alternative.

    python benchmarks/bench_learned.py                  # every case (10-20 minutes)
    python benchmarks/bench_learned.py --case bank --templates 16

The learned model is fitted to the repository's reference files once per run (``--model FILE`` reuses a
saved one: ``spiralbayes templates --fit-learned FILE``); ratios are measured in one process, so the
machine's load affects both sides alike.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from spiralbayes import AxisymmetricModel
from spiralbayes.inference.scan.run import scan
from spiralbayes.templates import compromise_bank, make_template
from spiralbayes.templates.learned import LearnedTemplateModel, learned_bank, learned_family, reference_files
from spiralbayes.templates.wake import PAPER_MASSES, PAPER_TAUS

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_scan import GEOMETRY, N_PHI, R_P, observation  # the scan benchmark's observation and grid

DISC = {"h_ps": 0.07, "slopes": 1.0, "alphas": 2e-3, "orbits": 20.0}


def load_model(path: str | None) -> tuple[LearnedTemplateModel, float]:
    t0 = time.perf_counter()
    model = LearnedTemplateModel.load(path) if path else LearnedTemplateModel.from_references(reference_files())
    return model, time.perf_counter() - t0


def timed_scan(vis, axisym, templates) -> tuple[float, float]:
    t0, c0 = time.perf_counter(), time.process_time()
    scan(vis, axisym, templates, GEOMETRY, r_p=R_P, n_phi_p=N_PHI, progress=False, nthreads=2)
    return time.perf_counter() - t0, time.process_time() - c0


def case_bank(args, model) -> dict:
    out: dict = {"load_before": os.getloadavg()[0]}
    n_make = 8
    t0 = time.perf_counter()
    for m in PAPER_MASSES:
        for tau0 in PAPER_TAUS[:2]:
            model.predict(m, 0.07, 1.0, 2e-3, 20.0, tau0)
    out["predict_s_per_template"] = (time.perf_counter() - t0) / n_make
    t0 = time.perf_counter()
    for m in PAPER_MASSES:
        for tau0 in PAPER_TAUS[:2]:
            make_template(m, tau0, 0.0, "R", h_p=0.07)
    out["generator_s_per_template"] = (time.perf_counter() - t0) / n_make
    out["predict_over_generator"] = out["predict_s_per_template"] / out["generator_s_per_template"]

    vis, axisym = observation()
    with tempfile.TemporaryDirectory() as cache:
        learned = list(learned_bank(model, PAPER_MASSES, tau0s=PAPER_TAUS, cache_dir=cache, **DISC))[: args.templates]
    wanted = {(t.mass, t.tau0, t.hand) for t in learned}
    generator = [t for t in compromise_bank().select(h_p=0.07, beta=0.0) if (t.mass, t.tau0, t.hand) in wanted]
    out.update({"N_vis": vis.n, "templates": len(learned), "generator_templates": len(generator),
                "learned_grid": list(np.shape(learned[0].delta)), "generator_grid": list(np.shape(generator[0].delta))})
    timed_scan(vis, axisym, generator[:1])  # one-off set-up (tables, threads) outside both timings
    wall_g, cpu_g = timed_scan(vis, axisym, generator)
    wall_l, cpu_l = timed_scan(vis, axisym, learned)
    out.update({"generator_scan_s_per_template": wall_g / len(generator),
                "generator_scan_cpu_s_per_template": cpu_g / len(generator),
                "learned_scan_s_per_template": wall_l / len(learned),
                "learned_scan_cpu_s_per_template": cpu_l / len(learned)})
    out["scan_cpu_ratio"] = out["learned_scan_cpu_s_per_template"] / out["generator_scan_cpu_s_per_template"]
    out["scan_wall_ratio"] = out["learned_scan_s_per_template"] / out["generator_scan_s_per_template"]
    out["load_after"] = os.getloadavg()[0]
    return out


def case_posterior(args, model) -> dict:
    from spiralbayes.inference.posterior import MassPrior, Priors
    from spiralbayes.inference.posterior.mass import family_of
    from spiralbayes.inference.posterior.sampler import sample_posterior

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from tests._support.mass_setup import planted_observation
    from tests._support.posterior_setup import R_RANGE, TRUE_GEOMETRY, profile

    vis = planted_observation(1.0)
    axisym = AxisymmetricModel.from_profile(profile, TRUE_GEOMETRY, N=80)
    tau0 = 0.3
    families = {"generator": family_of(make_template(1.0, tau0, 0.0, "R", h_p=0.07), (0.1, 3.0)),
                "learned": learned_family(model, 0.07, 1.0, 2e-3, 20.0, tau0)}
    out: dict = {"N_vis": vis.n, "n_walkers": args.walkers, "n_steps": args.steps}
    for name, family in families.items():
        with tempfile.TemporaryDirectory() as chains, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t0, c0 = time.perf_counter(), time.process_time()
            post = sample_posterior(vis, axisym, [family], priors=Priors.default(axisym, r_p=R_RANGE),
                                    mass="continuous", mass_prior=MassPrior(), chains_dir=chains,
                                    n_walkers=args.walkers, n_steps=args.steps, evidence_draws=200, progress=False,
                                    convergence="ignore", seed=1)
            out[f"{name}_wall_s"] = time.perf_counter() - t0
            out[f"{name}_cpu_s"] = time.process_time() - c0
            out[f"{name}_M_p_median"] = post.mass_posterior()["mth"]["median"]
    out["wall_ratio"] = out["learned_wall_s"] / out["generator_wall_s"]
    return out


def case_physics(args, model) -> dict:
    from spiralbayes.inference.posterior import MassPrior, Priors
    from spiralbayes.inference.posterior.physics import physics_posterior

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from tests._support.mass_setup import planted_observation
    from tests._support.posterior_setup import R_RANGE, TRUE_GEOMETRY, profile

    vis = planted_observation(1.0)
    axisym = AxisymmetricModel.from_profile(profile, TRUE_GEOMETRY, N=80)
    h_p = np.round(np.arange(0.05, 0.1001, 0.005), 4)
    with tempfile.TemporaryDirectory() as cache, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0, c0 = time.perf_counter(), time.process_time()
        post = physics_posterior(vis, axisym, model, 0.3, h_p=h_p, masses=np.geomspace(0.1, 3.0, args.masses),
                                 priors=Priors.default(axisym, r_p=R_RANGE), mass_prior=MassPrior(), cache_dir=cache,
                                 progress=False, nthreads=2)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    ci = post.intervals(0.95)
    return {"N_vis": vis.n, "templates": int(post.ln_bayes.size), "wall_s": wall, "cpu_s": cpu,
            "wall_per_template_s": wall / post.ln_bayes.size, "position_resolved": post.position_resolved(),
            "h_p_95": [ci["h_p"]["lo"], ci["h_p"]["hi"]], "M_p_95": [ci["M_p"]["lo"], ci["M_p"]["hi"]],
            "discs_x_h_p_x_hands": int(post.ln_bayes.size // post.mass.size)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--case", choices=("bank", "posterior", "physics", "all"), default="all")
    ap.add_argument("--templates", type=int, default=32, help="learned templates scanned (of 32)")
    ap.add_argument("--walkers", type=int, default=28)
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--masses", type=int, default=8, help="masses of the physics case's lattice")
    ap.add_argument("--model", default=None, help="a saved LearnedTemplateModel (default: fit one now)")
    args = ap.parse_args(argv)
    model, fit_s = load_model(args.model)
    results: dict = {"model_s": fit_s, "training_runs": len(model.run_names)}
    if args.case in ("bank", "all"):
        results["bank"] = case_bank(args, model)
    if args.case in ("posterior", "all"):
        results["posterior"] = case_posterior(args, model)
    if args.case in ("physics", "all"):
        results["physics"] = case_physics(args, model)
    print(json.dumps(results, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
