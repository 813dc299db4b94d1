"""Benchmark of the posterior likelihood and of a converged single-template posterior.

    python benchmarks/bench_sample.py                 # likelihood timings (1e5 visibilities)
    python benchmarks/bench_sample.py --converge      # + a posterior run to convergence (2 processes)

Prints, for one log-likelihood evaluation on one core: the fast path (tables + one small type-2
NUFFT), the exact path (Hankel + type-3 NUFFT of the full quadrature) and the naive path
(render the perturbation and disc images, ``fourier.sample_image``, chi2), with their ln L
differences from the exact path. ``--converge`` runs :func:`spiralbayes.inference.sampler.sample_posterior`
for one template until every parameter has chain length > 50 tau and ESS > 400, and reports the
wall time.

BLAS threads are pinned to one (emcee #199): numpy's BLAS calls with two threads on a loaded
2-core machine were measured ~100x slower for these array sizes.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import logging  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from spiralbayes.axisymmetric import AxisymmetricModel  # noqa: E402
from spiralbayes.geometry import DiscGeometry  # noqa: E402
from spiralbayes.model import perturbation_visibilities  # noqa: E402
from spiralbayes.inference.likelihood import SpiralLikelihood  # noqa: E402
from spiralbayes.templates import make_template  # noqa: E402
from spiralbayes.visibilities import Visibilities  # noqa: E402

TRUE = DiscGeometry(40.0, 70.0, 0.005, -0.01)
R_P, PHI_P = 0.35, 2.0


def profile(r):
    r = np.asarray(r, dtype=float)
    return 5e10 * np.exp(-r / 0.3 - (r / 0.8) ** 6)


def synthetic(n_vis: int, uv_max: float, snr_planet: float, seed: int = 0):
    template = make_template(1.0, 0.3, 0.0, "R")
    model = AxisymmetricModel.from_profile(profile, TRUE)
    rng = np.random.default_rng(seed)
    q = uv_max * np.sqrt(rng.uniform(4e-4, 1, n_vis))
    th = rng.uniform(0, 2 * np.pi, n_vis)
    u, v = q * np.cos(th), q * np.sin(th)
    dV = perturbation_visibilities(u, v, TRUE, model.brightness, template, R_P, PHI_P)
    sigma = np.sqrt(np.sum(np.abs(dV) ** 2) / snr_planet ** 2)
    V = model.visibilities(u, v, TRUE) + dV + sigma * (rng.normal(size=n_vis) + 1j * rng.normal(size=n_vis))
    start = AxisymmetricModel.from_profile(profile, DiscGeometry(42.0, 70.0, 0.025, -0.01))
    return Visibilities(u, v, V, np.full(n_vis, sigma ** -2)), start, template


def timeit(fn, repeat: int) -> tuple[float, float]:
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.min(times)), 1e3 * float(np.median(times))


def bench_likelihood(args) -> dict:
    vis, model, template = synthetic(args.n_vis, args.uv_max, args.snr)
    t0 = time.perf_counter()
    lik = SpiralLikelihood(vis, model, template, (0.1, 0.6), epsilon=args.epsilon)
    build = time.perf_counter() - t0
    info = lik.describe()
    print(f"data: {vis.n} visibilities up to {args.uv_max:.3g} lambda; template {template.name} "
          f"({info['n_cells']} quadrature cells)")
    print(f"tables: {info['n_rp_nodes']} r_p nodes ({1e3 * info['rp_step_arcsec']:.2f} mas apart) x "
          f"{info['grid_N']}^2 grid, {info['table_bytes'] / 2 ** 20:.1f} MB, built in {build:.1f} s; "
          f"axisymmetric table max rel. error {lik.axis_table.max_error(model):.1e}")
    theta = np.array([R_P, PHI_P, 40.0, 70.0, 0.005, -0.01])
    rng = np.random.default_rng(1)
    fast = timeit(lambda: lik(theta), args.repeat)
    exact = timeit(lambda: lik.exact_log_likelihood(theta), max(3, args.repeat // 10))
    naive = timeit(lambda: lik.naive_log_likelihood(theta), max(3, args.repeat // 10))
    ref = lik.exact_log_likelihood(theta)
    errors = []
    for _ in range(10):
        t = theta + rng.normal(size=6) * np.array([0, 0, 1.0, 1.0, 0.005, 0.005])
        t[0], t[1] = rng.uniform(0.1, 0.6), rng.uniform(0, 2 * np.pi)
        errors.append(abs(lik(t) - lik.exact_log_likelihood(t)))
    rows = {"fast": fast, "exact (Hankel + type-3 NUFFT)": exact, "naive (images + sample_image)": naive}
    dl = {"fast": lik(theta) - ref, "exact (Hankel + type-3 NUFFT)": 0.0,
          "naive (images + sample_image)": lik.naive_log_likelihood(theta) - ref}
    print(f"\none log-likelihood, {vis.n} visibilities, 1 core (min / median ms; ln L - exact):")
    for name, (tmin, tmed) in rows.items():
        print(f"  {name:34s} {tmin:8.2f} / {tmed:8.2f} ms   d lnL = {dl[name]:+.2e}")
    print(f"  fast vs exact at 10 random points: max |d ln L| = {max(errors):.2e} (ln L at truth {ref:.1f})")
    return {"n_vis": vis.n, "build_s": build, "tables": info, "fast_ms": fast, "exact_ms": exact, "naive_ms": naive,
            "naive_dlnL": dl["naive (images + sample_image)"], "fast_max_abs_dlnL": max(errors)}


def bench_converge(args) -> dict:
    from spiralbayes.inference.priors import Priors
    from spiralbayes.inference.sampler import sample_posterior

    vis, model, template = synthetic(args.n_vis, args.uv_max, args.snr)
    priors = Priors.default(model, r_p=(0.1, 0.6))
    out = Path(args.out)
    t0 = time.perf_counter()
    result = sample_posterior(vis, model, template, priors=priors, run_name="bench_converge",
                              chains_dir=out / "chains", n_walkers=args.walkers, n_steps=None, max_steps=args.max_steps,
                              check_every=args.check_every, min_ess=400, processes=args.processes,
                              convergence="warn", evidence_draws=1000, progress=False)
    wall = time.perf_counter() - t0
    run = result.runs[0]
    d = run.diagnostics
    print(f"\nposterior of {template.name}: {d['n_steps']} steps x {d['n_walkers']} walkers, "
          f"{args.processes} processes: wall {wall / 60:.1f} min; converged = {d['converged']}")
    print("  tau: " + ", ".join(f"{k} {v:.1f}" for k, v in d["tau"].items()))
    print("  ESS: " + ", ".join(f"{k} {v:.0f}" for k, v in d["ess"].items()))
    from spiralbayes.plotting.posterior import plot_corner

    corner = out / "bench_converge_corner.png"
    plot_corner(result, truths=[R_P, PHI_P, 40.0, 70.0, 0.005, -0.01]).savefig(corner, dpi=100)
    print(f"  corner plot: {corner}")
    return {"wall_s": wall, "diagnostics": {k: d[k] for k in ("tau", "ess", "n_steps", "converged", "acceptance")},
            "corner": str(corner)}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n-vis", type=int, default=100_000)
    parser.add_argument("--uv-max", type=float, default=2e6)
    parser.add_argument("--snr", type=float, default=30.0, help="sqrt(chi2) of the planted planet")
    parser.add_argument("--epsilon", type=float, default=1e-5)
    parser.add_argument("--repeat", type=int, default=50)
    parser.add_argument("--converge", action="store_true")
    parser.add_argument("--processes", type=int, default=2)
    parser.add_argument("--walkers", type=int, default=32)
    parser.add_argument("--max-steps", type=int, default=20000)
    parser.add_argument("--check-every", type=int, default=500)
    parser.add_argument("--out", default="bench_sample_output")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    Path(args.out).mkdir(parents=True, exist_ok=True)
    record = {"likelihood": bench_likelihood(args), "load_average": os.getloadavg()}
    if args.converge:
        record["converge"] = bench_converge(args)
    with open(Path(args.out) / "bench_sample.json", "w") as f:
        json.dump(record, f, indent=2, default=str)


if __name__ == "__main__":
    main()
