"""Cost of the continuous-mass likelihood against one fixed template's, on the same data.

Prints the time per likelihood call of :class:`~spiralbayes.inference.posterior.MassLikelihood` (four
mass nodes' grids summed, one NUFFT) and of :class:`~spiralbayes.inference.posterior.MarginalSpiralLikelihood`
for one template, their ratio, and the table build per mass node against one template's build.
``--runs`` also times whole posteriors on the posterior tests' small observation (1500 baselines, a
0.5 M_th planet): one family with the mass sampled against the same family's four bank templates
sampled one by one (today's discrete run), same walkers and steps.

``--node-tables VIS AXISYMMETRIC`` builds mass-node tables of two families on an observation and its
frank fit (e.g. ``spiralbayes simulate``'s file and ``spiralbayes scan``'s ``axisymmetric.h5``) over the
default ``r_p`` prior, and prints for each node its build time, its step against the heaviest node's,
the error at the checked midpoints and, built afresh, at every midpoint (``--all-nodes``: all 49).

    python benchmarks/bench_mass.py --n-vis 100000
    python benchmarks/bench_mass.py --runs --skip-calls
    python benchmarks/bench_mass.py --skip-calls --node-tables vis.h5 out/axisymmetric.h5
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

from spiralbayes.axisymmetric import AxisymmetricModel
from spiralbayes.geometry import DiscGeometry
from spiralbayes.inference.posterior import (
    FamilyPerturbation,
    MarginalSpiralLikelihood,
    MassLikelihood,
    ProfileMarginal,
    family_of,
)
from spiralbayes.inference.posterior.perturbation import FastPerturbation
from spiralbayes.templates import make_template
from spiralbayes.visibilities import Visibilities


def observation(n: int, uv_max: float, seed: int = 0):
    geometry = DiscGeometry(40.0, 70.0, 0.0, 0.0)
    model = AxisymmetricModel.from_profile(lambda r: 5e10 * np.exp(-np.asarray(r) / 0.3 - (np.asarray(r) / 0.8) ** 6),
                                           geometry, N=150)
    rng = np.random.default_rng(seed)
    q = uv_max * np.sqrt(rng.uniform(1e-4, 1, n))
    th = rng.uniform(0, 2 * np.pi, n)
    u, v = q * np.cos(th), q * np.sin(th)
    V = model.visibilities(u, v, geometry) + 0.01 * (rng.normal(size=n) + 1j * rng.normal(size=n))
    return Visibilities(u, v, V, np.full(n, 1e4)), model, geometry


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n-vis", type=int, default=100_000)
    parser.add_argument("--uv-max", type=float, default=2e6)
    parser.add_argument("--repeat", type=int, default=40)
    parser.add_argument("--runs", action="store_true", help="also time whole posteriors (a few minutes)")
    parser.add_argument("--skip-calls", action="store_true", help="skip the per-call timings")
    parser.add_argument("--steps", type=int, default=600)
    parser.add_argument("--walkers", type=int, default=28)
    parser.add_argument("--node-tables", nargs=2, metavar=("VIS", "AXISYMMETRIC"),
                        help="check the families' node tables on these data (several minutes)")
    parser.add_argument("--all-nodes", action="store_true", help="with --node-tables: every node (~10 min)")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    if not args.skip_calls:
        calls(args)
    if args.runs:
        runs(args)
    if args.node_tables:
        node_tables(*args.node_tables, nodes=range(48) if args.all_nodes else (0, 8, 16, 24, 32, 40))


def node_tables(vis_path: str, model_path: str, nodes=(0, 8, 16, 24, 32, 40)) -> None:
    from spiralbayes.inference.posterior import Priors
    from spiralbayes.io import load_visibilities
    from spiralbayes.templates.variants import variant_template

    vis = load_visibilities(vis_path)
    model = AxisymmetricModel.load(model_path)
    r_range = tuple(Priors.default(model).r_p)
    print(f"{vis.u.size} visibilities, r_p prior {r_range[0]:.4f}-{r_range[1]:.4f} arcsec")
    for variant, tau0, beta in (("wakeflow", 3.0, 10.0), ("compromise", 0.3, 0.0)):
        family = family_of(variant_template(1.0, tau0, beta, "R", variant))
        fp = FamilyPerturbation(vis.u, vis.v, vis.weights, model.brightness, family, r_range, model.geometry)
        heaviest = family.masses.size - 1
        for j in (heaviest, *nodes):
            t = time.perf_counter()
            table = fp.node_table(j)
            built = time.perf_counter() - t
            every = table.midpoint_errors()[1].max()
            rounds = [f"{r['max_midpoint_error']:.2e}" + (f" ({r['midpoints_checked']} checked)"
                                                          if "midpoints_checked" in r else "")
                      for r in table.table.refinement]
            step, ref_step = table.table.step * 1e3, fp.node_table(heaviest).table.step * 1e3
            print(f"{variant} tau0 {tau0:g} beta {beta:g}, node {j} ({family.masses[j]:.3g} M_th): {built:.1f} s, "
                  f"step {step:.3f} mas (heaviest node {ref_step:.3f}); rounds {', '.join(rounds)}; "
                  f"every midpoint {every:.2e} (rp_tolerance 0.01)", flush=True)


def runs(args) -> None:
    import sys
    import tempfile
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the tests' small observation

    from spiralbayes.inference.posterior import Priors
    from spiralbayes.inference.posterior.sampler import sample_posterior
    from tests._support.mass_setup import bank_members, planted_observation
    from tests._support.posterior_setup import R_RANGE, TRUE_GEOMETRY, profile

    vis = planted_observation(0.5)
    model = AxisymmetricModel.from_profile(profile, TRUE_GEOMETRY, N=80)
    members = bank_members()
    common = dict(priors=Priors.default(model, r_p=R_RANGE), n_walkers=args.walkers, n_steps=args.steps,
                  evidence_draws=400, progress=False, convergence="ignore", likelihood_kwargs={"rp_tolerance": 0.05},
                  seed=1, processes=1, threads=1)  # one core each: the comparison is of work, not of pools
    times = {}
    with tempfile.TemporaryDirectory() as tmp:
        for mode in ("bank", "continuous"):
            t = time.perf_counter()
            post = sample_posterior(vis, model, members, mass=mode, chains_dir=Path(tmp) / mode,
                                    mcmc_templates=[t.name for t in members] if mode == "bank" else None, **common)
            times[mode] = time.perf_counter() - t
            print(f"{mode:>10}: {times[mode]:.0f} s for {len(post.runs)} run(s) of {args.walkers} walkers x "
                  f"{args.steps} steps; {post.verdict[:90]}", flush=True)
    print(f"whole run, continuous family / four bank templates: {times['continuous'] / times['bank']:.2f}; "
          f"per bank template: {times['continuous'] / (times['bank'] / len(members)):.2f}")


def calls(args) -> None:
    from spiralbayes.inference.posterior.forked import pin_threads

    pin_threads()  # one BLAS thread, as in the chain's walker processes
    vis, model, geometry = observation(args.n_vis, args.uv_max)
    base = ProfileMarginal(vis, model)
    r_range = (0.15, 0.6)
    template = make_template(1.0, 0.3, 0.0, "R")
    t0 = time.perf_counter()
    fixed = MarginalSpiralLikelihood(base, FastPerturbation(vis.u, vis.v, vis.weights, model.brightness, template,
                                                            r_range, geometry))
    t_fixed_build = time.perf_counter() - t0
    family = family_of(template)
    fp = FamilyPerturbation(vis.u, vis.v, vis.weights, model.brightness, family, r_range, geometry)
    mass = MassLikelihood(base, fp)
    rng = np.random.default_rng(1)
    thetas = np.column_stack([rng.uniform(0.2, 0.55, args.repeat), rng.uniform(0, 2 * np.pi, args.repeat),
                              rng.normal(40, 0.3, args.repeat), rng.normal(70, 0.3, args.repeat),
                              np.zeros(args.repeat), np.zeros(args.repeat)])
    ln_m = rng.uniform(np.log(0.7), np.log(1.4), args.repeat)
    for th, lm in zip(thetas, ln_m):  # build the nodes the calls need before timing
        mass.amplitude_terms(np.append(th, lm))
    n_nodes = len(fp.tables)
    per_node = fp.build_time_s / n_nodes

    def timed(f, xs):
        t = time.perf_counter()
        for x in xs:
            f(x)
        return (time.perf_counter() - t) / len(xs)

    t_fixed = timed(fixed.amplitude_terms, thetas)
    t_mass = timed(mass.amplitude_terms, [np.append(th, lm) for th, lm in zip(thetas, ln_m)])
    print(f"{args.n_vis} visibilities, {args.repeat} calls each")
    print(f"fixed template:   {1e3 * t_fixed:.2f} ms per call; table build {t_fixed_build:.1f} s")
    print(f"continuous mass:  {1e3 * t_mass:.2f} ms per call; {n_nodes} mass-node tables, {per_node:.1f} s each")
    print(f"ratio per call (continuous / fixed): {t_mass / t_fixed:.2f}")


if __name__ == "__main__":
    main()
