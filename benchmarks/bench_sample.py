"""Benchmark of the posterior likelihoods, the table build for the default prior, and a converged run.

    python benchmarks/bench_sample.py                 # likelihood timings (1e5 visibilities) + default-prior build
    python benchmarks/bench_sample.py --converge      # + the default run to convergence on fiducial data

Prints, for one log-likelihood evaluation on one core (CPU time, so that a loaded machine does not
inflate it): the profile-marginalised likelihood the sampler uses (its geometry and perturbation
parts too, and the geometry part with the 6-point stencil as a baseline), the conditional fast path
(tables + one type-2 NUFFT), the exact path (Hankel + type-3 NUFFT of the full quadrature) and the
naive path (render images, ``fourier.sample_image``),
with their ln L differences from the exact path. Then the likelihood tables for the **default
r_p prior** (``Priors.default``: R_eff / 25 to R_eff) — on the synthetic 1e5-visibility disc and on
a simulated fiducial observation with its frank fit — with their build time and node count, and
the build of the mirror template (shared table). ``--converge`` runs
:func:`spiralbayes.inference.posterior.sampler.sample_posterior` on the fiducial observation (frank fitted 3 deg
off in inclination) with the default settings — until every parameter's chain is longer than
50 tau and its ESS >= 400 — and reports the wall time. ``--planet-free`` runs the default posterior
on one synthetic set-up (``--pf-n-vis`` visibilities, start geometry 2 deg and 20 mas off) with
and without the planet and prints wall time, steps, the stopping rule that ended each chain and
P(planet) with its error (``--old-rule`` adds the planet-free run under the old rule, every
parameter > 50 tau, for the cost and P(planet) it replaces):

    python benchmarks/bench_sample.py --skip-likelihood --skip-build --planet-free [--old-rule]

``--bank`` runs the default posterior on one template family of the default (morphology-robust)
bank and of the single-morphology compromise bank, on the same set-up, and prints the ratio:

    python benchmarks/bench_sample.py --skip-likelihood --skip-build --bank

``--mass`` runs the default posterior on the ``--converge`` set-up twice, one after the other: for the
planet's template alone and with ``mass="continuous"`` for its family (49 mass nodes over 0.1-3 M_th),
and prints the wall times, their ratio (target <= 1.5) and the planet mass:

    python benchmarks/bench_sample.py --skip-likelihood --skip-build --mass

``--walker-pools`` times one ensemble step's log posteriors serially, with two walker threads (the
default where workers cannot be forked) and with two worker processes (the default on Linux), and
prints the ratios:

    python benchmarks/bench_sample.py --skip-likelihood --skip-build --walker-pools

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
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from spiralbayes.axisymmetric import AxisymmetricModel, fit_axisymmetric  # noqa: E402
from spiralbayes.geometry import DiscGeometry  # noqa: E402
from spiralbayes.inference.posterior.conditional import SpiralLikelihood  # noqa: E402
from spiralbayes.inference.posterior.likelihood import MarginalSpiralLikelihood, ProfileMarginal  # noqa: E402
from spiralbayes.inference.posterior.perturbation import FastPerturbation  # noqa: E402
from spiralbayes.inference.posterior.priors import Priors  # noqa: E402
from spiralbayes.model import perturbation_visibilities  # noqa: E402
from spiralbayes.templates import make_template  # noqa: E402
from spiralbayes.visibilities import Visibilities  # noqa: E402

TRUE = DiscGeometry(40.0, 70.0, 0.005, -0.01)
R_P, PHI_P = 0.35, 2.0
FIDUCIAL = DiscGeometry(30.0, 60.0)


def profile(r):
    r = np.asarray(r, dtype=float)
    return 5e10 * np.exp(-r / 0.3 - (r / 0.8) ** 6)


def synthetic(n_vis: int, uv_max: float, snr_planet: float, seed: int = 0, planet: bool = True):
    """A smooth disc (+ a planet of sqrt(chi2) = ``snr_planet``, or the same noise without it) and a start
    model 2 deg and 20 mas off."""
    template = make_template(1.0, 0.3, 0.0, "R")
    model = AxisymmetricModel.from_profile(profile, TRUE)
    rng = np.random.default_rng(seed)
    q = uv_max * np.sqrt(rng.uniform(4e-4, 1, n_vis))
    th = rng.uniform(0, 2 * np.pi, n_vis)
    u, v = q * np.cos(th), q * np.sin(th)
    dV = perturbation_visibilities(u, v, TRUE, model.brightness, template, R_P, PHI_P)
    sigma = np.sqrt(np.sum(np.abs(dV) ** 2) / snr_planet ** 2)
    V = model.visibilities(u, v, TRUE) + (dV if planet else 0.0) + sigma * (rng.normal(size=n_vis)
                                                                            + 1j * rng.normal(size=n_vis))
    start = AxisymmetricModel.from_profile(profile, DiscGeometry(42.0, 70.0, 0.025, -0.01))
    return Visibilities(u, v, V, np.full(n_vis, sigma ** -2)), start, template


def cpu_ms(fn, repeat: int) -> tuple[float, float]:
    """(min, median) CPU time of one call [ms]."""
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        times.append(time.process_time() - t0)
    return 1e3 * float(np.min(times)), 1e3 * float(np.median(times))


def bench_likelihood(args) -> dict:
    vis, model, template = synthetic(args.n_vis, args.uv_max, args.snr)
    t0 = time.perf_counter()
    lik = SpiralLikelihood(vis, model, template, (0.1, 0.6), epsilon=args.epsilon)
    build = time.perf_counter() - t0
    info = lik.describe()
    base = ProfileMarginal(vis, model)
    marg = MarginalSpiralLikelihood(base, FastPerturbation(base.u, base.v, base.weights, model.brightness, template,
                                                           (0.1, 0.6), model.geometry, epsilon=args.epsilon))
    print(f"data: {vis.n} visibilities up to {args.uv_max:.3g} lambda; template {template.name} "
          f"({info['n_cells']} quadrature cells); frank basis N = {model.N}, q grid {base.projector.n_grid} points "
          f"(order {base.projector.order})")
    print(f"tables (r_p 0.1-0.6 arcsec): {info['n_rp_nodes']} r_p nodes x {info['grid_N']}^2 grid, "
          f"{info['table_bytes'] / 2 ** 20:.1f} MB, built in {build:.1f} s")
    theta = np.array([R_P, PHI_P, 40.0, 70.0, 0.005, -0.01])
    base6 = ProfileMarginal(vis, model, order=6)  # the baseline: the 6-point stencil on its finer grid
    rows = {
        "marginal (profile and A integrated)": cpu_ms(lambda: marg(theta), args.repeat),
        "  its geometry part (q grid, Cholesky)": cpu_ms(lambda: base.raw_terms(theta[2:]), args.repeat),
        f"  the same, order 6 ({base6.projector.n_grid} points)": cpu_ms(lambda: base6.raw_terms(theta[2:]),
                                                                         args.repeat),
        "  its perturbation part (tables)": cpu_ms(lambda: marg.perturbation.disc_frame(*theta[:4]), args.repeat),
        "conditional fast (profile fixed)": cpu_ms(lambda: lik(theta), args.repeat),
        "exact (Hankel + type-3 NUFFT)": cpu_ms(lambda: lik.exact_log_likelihood(theta), max(3, args.repeat // 10)),
        "naive (images + sample_image)": cpu_ms(lambda: lik.naive_log_likelihood(theta), max(3, args.repeat // 10)),
    }
    ref = lik.exact_log_likelihood(theta)
    dl = {"conditional fast (profile fixed)": lik(theta) - ref,
          "naive (images + sample_image)": lik.naive_log_likelihood(theta) - ref}
    print(f"\none log-likelihood, {vis.n} visibilities, 1 core, CPU time (min / median ms; ln L - exact):")
    for name, (tmin, tmed) in rows.items():
        extra = f"   d lnL = {dl[name]:+.2e}" if name in dl else ""
        print(f"  {name:40s} {tmin:8.2f} / {tmed:8.2f} ms{extra}")
    small = vis.subset(np.arange(3000))
    b_small = ProfileMarginal(small, model, ln_ref=0.0)
    d_geo = max(abs(b_small.log_likelihood(g) - b_small.exact_log_likelihood(g))
                for g in (TRUE, DiscGeometry(41.0, 69.0, 0.0, 0.0), DiscGeometry(39.0, 71.5, 0.02, -0.02)))
    print(f"  marginal vs dense reference (3000 visibilities, 3 geometries): max |d ln L| = {d_geo:.1e}")
    return {"n_vis": vis.n, "build_s": build, "tables": info, "cpu_ms": rows, "marginal_vs_dense": d_geo,
            "naive_dlnL": dl["naive (images + sample_image)"]}


_FIDUCIAL_CACHE: dict = {}


def fiducial(out: Path, inc_offset: float = 3.0):
    """A fiducial observation (1 M_th planet at 50 au, phi_p = 40 deg) and frank fitted ``inc_offset`` off."""
    from spiralbayes.simulate import DiscModel, simulate_observation

    if inc_offset in _FIDUCIAL_CACHE:
        return _FIDUCIAL_CACHE[inc_offset]
    template = make_template(1.0, 3.0, 10.0, "R")
    vis = simulate_observation("fiducial", DiscModel(distance=140.0, tau_ref=3.0), FIDUCIAL, template,
                               r_p=50 / 140, phi_p=np.radians(40.0), seed=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = fit_axisymmetric(vis, FIDUCIAL.replace(inc=FIDUCIAL.inc + inc_offset), progress=False)
    _FIDUCIAL_CACHE[inc_offset] = vis, model, template
    return vis, model, template


def bench_default_build(args) -> dict:
    out = {}
    vis, model, template = synthetic(args.n_vis, args.uv_max, args.snr)
    cases = [("synthetic disc, 1e5 visibilities", vis, model, template)]
    fvis, fmodel, ftemplate = fiducial(Path(args.out))
    cases.append(("fiducial observation, frank fit", fvis, fmodel, ftemplate))
    print("\nlikelihood tables for the default r_p prior (Priors.default: R_eff / 25 to R_eff), one template:")
    for label, v, m, t in cases:
        r_range = Priors.default(m).r_p
        t0, c0 = time.perf_counter(), time.process_time()
        fp = FastPerturbation(v.u, v.v, v.weights, m.brightness, t, r_range, m.geometry)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        t1 = time.perf_counter()
        FastPerturbation(v.u, v.v, v.weights, m.brightness, t.mirror(), r_range, m.geometry, mirror_of=fp)
        mirror = time.perf_counter() - t1
        d = fp.describe()
        print(f"  {label}: r_p {r_range[0]:.3f}-{r_range[1]:.3f} arcsec, {d['n_rp_nodes']} nodes "
              f"({1e3 * d['rp_step_arcsec']:.2f} mas) x {d['grid_N']}^2, {d['table_bytes'] / 2 ** 20:.0f} MB, "
              f"{fp.n_node_builds} node grids built: {wall:.1f} s wall, {cpu:.1f} s CPU; mirror template {mirror:.2f} "
              f"s (load average {os.getloadavg()[0]:.1f})")
        out[label] = {"r_range": r_range, "wall_s": wall, "cpu_s": cpu, "mirror_s": mirror, **d}
    return out


def bench_converge(args) -> dict:
    from spiralbayes.inference.posterior.sampler import sample_posterior

    vis, model, template = fiducial(Path(args.out))
    priors = Priors.default(model, widths={"dRA": 0.02, "dDec": 0.02})
    out = Path(args.out)
    t0 = time.perf_counter()
    result = sample_posterior(vis, model, [template], priors=priors, run_name="bench_converge",
                              chains_dir=out / "chains", n_walkers=args.walkers, max_steps=args.max_steps,
                              check_every=args.check_every, processes=args.processes, convergence="warn",
                              progress=False)
    wall = time.perf_counter() - t0
    run = result.runs[0]
    d = run.diagnostics
    print(f"\nfiducial posterior (frank fitted 3 deg off), {template.name}: {d['n_steps']} steps x {d['n_walkers']} "
          f"walkers, {args.processes} processes: wall {wall / 60:.1f} min; converged = {d['converged']} "
          f"(load average {os.getloadavg()[0]:.1f})")
    print("  tau: " + ", ".join(f"{k} {v:.1f}" for k, v in d["tau"].items()))
    print("  ESS: " + ", ".join(f"{k} {v:.0f}" for k, v in d["ess"].items()))
    print("  " + result.verdict)
    from spiralbayes.plotting.posterior import plot_corner

    corner = out / "bench_converge_corner.png"
    truths = {"r_p": 50 / 140, "phi_p": np.radians(40.0), "A": 1.0, "inc": 30.0, "PA": 60.0, "dRA": 0.0, "dDec": 0.0}
    plot_corner(result, truths=truths, distance=140.0).savefig(corner, dpi=100)
    print(f"  corner plot: {corner}")
    return {"wall_s": wall, "diagnostics": {k: d[k] for k in ("tau", "ess", "n_steps", "converged", "acceptance")},
            "percentiles": run.percentiles(), "verdict": result.verdict, "corner": str(corner)}


def _ln_b_error(result) -> float:
    """Standard error of ln B from the importance-sampling errors of every evidence (independent draws)."""
    from scipy.special import softmax

    w = softmax(np.array([r.ln_evidence for r in result.runs]) + np.log(result.template_prior))
    err_planet = np.sqrt(np.sum((w * np.nan_to_num([r.ln_evidence_err for r in result.runs])) ** 2))
    return float(np.hypot(err_planet, result.null.ln_evidence_err))


def bench_planet_free(args) -> dict:
    """The default run on one set-up with and without the planet: wall time, steps, stopping rule, P(planet)."""
    from spiralbayes.inference.posterior.sampler import sample_posterior

    out, record = Path(args.out), {}
    cases = [("planet", True, True), ("planet-free", False, True)]
    if args.old_rule:
        cases.append(("planet-free, old rule (every parameter > 50 tau)", False, False))
    print(f"\nplanet vs planet-free, {args.pf_n_vis} visibilities up to {args.uv_max:.3g} lambda, planet sqrt(chi2) = "
          f"{args.snr:g}, start 2 deg / 20 mas off; {args.walkers} walkers, check every {args.check_every}, max "
          f"{args.max_steps} steps, {args.processes} processes:")
    for label, planet, rule in cases:
        vis, model, template = synthetic(args.pf_n_vis, args.uv_max, args.snr, seed=3, planet=planet)
        priors = Priors.default(model, r_p=(0.15, 0.6))
        t0, c0 = time.perf_counter(), time.process_time()
        result = sample_posterior(vis, model, [template], priors=priors, run_name=f"bench_pf_{planet}_{rule}",
                                  chains_dir=out / "chains", n_walkers=args.walkers, max_steps=args.max_steps,
                                  check_every=args.check_every, processes=args.processes, convergence="ignore",
                                  progress=False, stop_when_planet_free=rule, seed=args.seed)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        d = result.runs[0].diagnostics
        p, err = result.p_planet, _ln_b_error(result)
        p_err = p * (1 - p) * err
        print(f"  {label:50s} wall {wall / 60:5.1f} min (CPU of this process {cpu / 60:.1f} min), "
              f"{d['n_steps']:5d} steps, P(planet) = {p:.4g} +- {p_err:.2g} "
              f"(ln B = {result.ln_bayes_factor:.2f} +- {err:.2f}), tau r_p {d['tau']['r_p']:.0f}, max geometry tau "
              f"{max(d['tau'][k] for k in ('inc', 'PA', 'dRA', 'dDec')):.0f}; stopped on: "
              f"{d.get('stopping_rule') or 'max_steps'} (load average {os.getloadavg()[0]:.1f})")
        record[label] = {"wall_s": wall, "cpu_s": cpu, "n_steps": d["n_steps"], "p_planet": p, "p_planet_err": p_err,
                         "ln_b": result.ln_bayes_factor, "ln_b_err": err, "tau": d["tau"],
                         "stopping_rule": d.get("stopping_rule"), "verdict": result.verdict}
    ratio = record["planet-free"]["wall_s"] / record["planet"]["wall_s"]
    cpu_ratio = record["planet-free"]["cpu_s"] / record["planet"]["cpu_s"]
    print(f"  planet-free / planet: wall time {ratio:.2f}, CPU time {cpu_ratio:.2f} (CPU is the load-free figure "
          "with --processes 1)")
    return {**record, "wall_ratio": ratio, "cpu_ratio": cpu_ratio}


def bench_bank(args) -> dict:
    """The default posterior on the default (morphology-robust) bank against the single-morphology bank.

    One family (the planet's tau0, beta and H/r: 8 templates of the compromise bank, 24 of the
    default bank), scanned, then sampled with every default (templates within ``prune_delta_lnL`` of
    the scan's best are sampled by emcee, the others get a Laplace evidence) on the ``--planet-free``
    set-up with its planet.
    """
    from spiralbayes.inference.posterior.sampler import sample_posterior
    from spiralbayes.inference.scan.run import scan
    from spiralbayes.templates import compromise_bank, default_bank

    vis, model, template = synthetic(args.pf_n_vis, args.uv_max, args.snr, seed=3)
    family = {"tau0": template.tau0, "beta": template.beta, "h_p": template.h_p}
    out, record = Path(args.out), {}
    print(f"\nthe default posterior on one family ({family}), {args.pf_n_vis} visibilities, {args.walkers} walkers, "
          f"max {args.max_steps} steps, {args.processes} processes:")
    for label, bank in (("compromise bank", compromise_bank), ("default (robust) bank", default_bank)):
        templates = list(bank().select(**family))
        t0 = time.perf_counter()
        found = scan(vis, model, templates, progress=False, allow_other_data=True, nthreads=args.processes)
        scan_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        result = sample_posterior(vis, model, templates, scan_result=found,
                                  priors=Priors.default(model, r_p=(0.15, 0.6)),
                                  run_name=f"bench_bank_{len(templates)}",
                                  chains_dir=out / "chains", n_walkers=args.walkers, max_steps=args.max_steps,
                                  check_every=args.check_every, processes=args.processes, convergence="ignore",
                                  progress=False, seed=args.seed)
        wall = time.perf_counter() - t0
        n_mcmc = sum(r.mode == "mcmc" for r in result.runs)
        best = max(result.runs, key=lambda r: r.ln_evidence)
        print(f"  {label:22s} {len(templates):3d} templates ({n_mcmc} sampled by emcee, the rest Laplace): scan "
              f"{scan_s:.0f} s, posterior {wall / 60:.1f} min; P(planet) = {result.p_planet:.4g}, most probable "
              f"template {best.name} (load average {os.getloadavg()[0]:.1f})")
        record[label] = {"templates": len(templates), "mcmc_templates": n_mcmc, "scan_s": scan_s, "wall_s": wall,
                         "p_planet": result.p_planet, "best": best.name}
    ratio = record["default (robust) bank"]["wall_s"] / record["compromise bank"]["wall_s"]
    print(f"  default bank / compromise bank: posterior wall time {ratio:.2f} (target <= 1.5)")
    return {**record, "wall_ratio": ratio}


def bench_mass(args) -> dict:
    """The default posterior for one template against its continuous-mass family, on the same data."""
    from spiralbayes.inference.posterior.sampler import sample_posterior

    vis, model, template = fiducial(Path(args.out))
    priors = Priors.default(model, widths={"dRA": 0.02, "dDec": 0.02})
    out, record = Path(args.out), {}
    print(f"\nfiducial posterior (frank fitted 3 deg off), {template.name}: one template against its family "
          f"({args.walkers} walkers, {args.processes} processes):")
    for mode in ("bank", "continuous"):
        t0 = time.perf_counter()
        result = sample_posterior(vis, model, [template], priors=priors, run_name=f"bench_mass_{mode}",
                                  chains_dir=out / "chains", n_walkers=args.walkers, max_steps=args.max_steps,
                                  processes=args.processes, convergence="warn", progress=False, mass=mode,
                                  seed=args.seed)
        wall = time.perf_counter() - t0
        d = result.runs[0].diagnostics
        post = result.mass_posterior()
        mass = post["mth"] if post else None
        shown = (f"; M_p {mass['median']:.2f} M_th (95 %: {mass['lo95']:.2f}-{mass['hi95']:.2f})" if mass else "")
        print(f"  mass = {mode!r:13s} wall {wall / 60:.1f} min, {d['n_steps']} steps (largest tau "
              f"{max(d['tau'].values()):.1f}){shown} (load average {os.getloadavg()[0]:.1f})")
        record[mode] = {"wall_s": wall, "n_steps": d["n_steps"], "tau": d["tau"], "mass_posterior": mass}
    ratio = record["continuous"]["wall_s"] / record["bank"]["wall_s"]
    print(f"  family / one template: wall time {ratio:.2f} (target <= 1.5)")
    return {**record, "wall_ratio": ratio}


def bench_walker_pools(args) -> dict:
    """Wall time of one ensemble step's log posteriors (``--walkers`` positions around the planet), serial
    against walker threads and worker processes (the default on Linux), on the synthetic disc."""
    from spiralbayes.inference.posterior.chain_runner import walker_pool
    from spiralbayes.inference.posterior.sampler import LogPosterior

    vis, model, template = synthetic(args.n_vis, args.uv_max, args.snr)
    base = ProfileMarginal(vis, model)
    marg = MarginalSpiralLikelihood(base, FastPerturbation(base.u, base.v, base.weights, model.brightness, template,
                                                           (0.1, 0.6), model.geometry, epsilon=args.epsilon),
                                    amplitude_max=2.0)
    logpost = LogPosterior(marg, Priors.default(model, r_p=(0.1, 0.6)))
    rng = np.random.default_rng(1)
    centre = np.array([R_P, PHI_P, 40.0, 70.0, 0.005, -0.01])
    walkers = centre + rng.normal(size=(args.walkers, 6)) * np.array([0.01, 0.05, 0.2, 0.2, 0.002, 0.002])
    rows = {}
    for label, processes, threads in (("serial", None, 1), ("2 threads", None, 2), ("2 processes", 2, 1)):
        with walker_pool(None, processes, logpost, threads) as pool:
            list(pool.map(pool.log_prob, walkers))  # warm: workers started, tables in place
            times = []
            for _ in range(args.pool_repeat):
                t0 = time.perf_counter()
                values = [v[0] for v in pool.map(pool.log_prob, walkers)]
                times.append(time.perf_counter() - t0)
        rows[label] = (float(np.median(times)), values)
    serial = rows["serial"][0]
    print(f"\none ensemble step ({args.walkers} walkers, {vis.n} visibilities), wall time, median of "
          f"{args.pool_repeat} (load average {os.getloadavg()[0]:.2f}):")
    for label, (t, values) in rows.items():
        same = np.array_equal(values, rows["serial"][1])
        print(f"  {label:12s} {1e3 * t:8.1f} ms   {serial / t:4.2f}x serial   same values: {same}")
    return {label: t for label, (t, _) in rows.items()}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n-vis", type=int, default=100_000)
    parser.add_argument("--uv-max", type=float, default=2e6)
    parser.add_argument("--snr", type=float, default=30.0, help="sqrt(chi2) of the planted planet")
    parser.add_argument("--epsilon", type=float, default=1e-5)
    parser.add_argument("--repeat", type=int, default=30)
    parser.add_argument("--converge", action="store_true")
    parser.add_argument("--skip-build", action="store_true", help="skip the default-prior table builds")
    parser.add_argument("--processes", type=int, default=2)
    parser.add_argument("--walkers", type=int, default=32)
    parser.add_argument("--max-steps", type=int, default=20000)
    parser.add_argument("--check-every", type=int, default=500)
    parser.add_argument("--planet-free", action="store_true",
                        help="the default run with and without the planet on the same set-up (synthetic disc)")
    parser.add_argument("--old-rule", action="store_true",
                        help="with --planet-free: also the planet-free run under the old rule (every parameter)")
    parser.add_argument("--pf-n-vis", type=int, default=20_000, help="visibilities of the --planet-free set-up")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--bank", action="store_true",
                        help="the default posterior on the default (robust) bank against the compromise bank")
    parser.add_argument("--skip-likelihood", action="store_true", help="skip the likelihood timings")
    parser.add_argument("--mass", action="store_true",
                        help="the default posterior for one template against its continuous-mass family")
    parser.add_argument("--walker-pools", action="store_true",
                        help="one ensemble step serial, with 2 walker threads and 2 processes (the default on Linux)")
    parser.add_argument("--pool-repeat", type=int, default=10)
    parser.add_argument("--out", default="bench_sample_output")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    Path(args.out).mkdir(parents=True, exist_ok=True)
    record = {"load_average": os.getloadavg()}
    if not args.skip_likelihood:
        record["likelihood"] = bench_likelihood(args)
    if not args.skip_build:
        record["default_prior_build"] = bench_default_build(args)
    if args.converge:
        record["converge"] = bench_converge(args)
    if args.planet_free:
        record["planet_free"] = bench_planet_free(args)
    if args.bank:
        record["bank"] = bench_bank(args)
    if args.mass:
        record["mass"] = bench_mass(args)
    if args.walker_pools:
        record["walker_pools"] = bench_walker_pools(args)
    with open(Path(args.out) / "bench_sample.json", "w") as f:
        json.dump(record, f, indent=2, default=str)


if __name__ == "__main__":
    main()
