"""Scan cost and accuracy (issues 5 and 11): every case runs in its own process (its peak memory).

``bank``      ~1e5 visibilities (C-4 + C-7, 0.87 mm), the authors' grid of 25 r_p x 90 phi_p: the
              default bank (576 templates: 64 x 3 h_p x 3 morphologies, scanned through their
              building blocks; target <= 60 s on 2 cores), the single-morphology banks it
              extends (the paper's 64 and the 192 at h_p = 0.05, 0.07, 0.10), serial on 2 threads
              and the 64 on a Dask LocalCluster (2 workers); the naive loop (image +
              NUFFT + chi^2 per instance, as the authors' galario loop) timed on 20 instances in the
              same run, and the ratio.
``as209``     the real 196-visibility AS 209 sample (frank's geometry): frank with the sparse-data
              default N, then the full 64-template scan on the default grid: time and peak memory.
``million``   ~1e6 visibilities (the high-sensitivity preset twice, two noise draws): set-up, the
              first template (one-off work), later templates, peak memory.
``accuracy``  the scan's error estimate against an independent, converged reference
              (tests/_support/quadrature_reference.py) on a subset (3 templates x 3 r_p x 9 phi_p) of the
              fiducial observation (inclined, offset phase centre), and the earlier midpoint rule's
              error on the same subset.

    python benchmarks/bench_scan.py                      # every case
    python benchmarks/bench_scan.py --case bank --templates 8   # quicker
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from spiralbayes import AxisymmetricModel, DiscGeometry, Visibilities
from spiralbayes.fourier import ImageSampler
from spiralbayes.inference.scan.run import scan
from spiralbayes.inference.scan.statistics import chi2
from spiralbayes.model import render_perturbation_image
from spiralbayes.simulate import DiscModel, observe, uv_coverage
from spiralbayes.templates import compromise_bank

ROOT = Path(__file__).resolve().parents[1]
GEOMETRY = DiscGeometry(30.0, 60.0)
R_P = np.linspace(0.02, 0.5, 25)
N_PHI = 90
NAIVE_PIXEL = 0.004  # arcsec; the converged direct evaluation needs <= 2-4 mas (DESIGN.md)
H_P = (0.05, 0.07, 0.10)


def peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def observation():
    wavelength = 0.87e-3
    cov = uv_coverage(["C-4", "C-7"], -25.0, [(-0.12, 0.12), (-0.35, 0.35)], 30.0, wavelength)
    disc = DiscModel(tau_ref=3.0)
    axisym = AxisymmetricModel.from_profile(disc.profile(wavelength), GEOMETRY)
    vis = observe(lambda u, v: axisym.visibilities(u, v, GEOMETRY), cov, sensitivity=35e-6, seed=0)
    return vis, axisym


def naive_time_per_instance(vis: Visibilities, axisym, templates, n_instances: int) -> float:
    """Build the image for each instance and sample it, as the authors' loop does."""
    n = int(2 * 2.25 * R_P[-1] / NAIVE_PIXEL) + 16
    n += n % 2
    sampler = ImageSampler(vis.u, vis.v, (n, n), NAIVE_PIXEL, GEOMETRY, epsilon=1e-6)
    VA = axisym.visibilities(vis.u, vis.v, GEOMETRY)
    rng = np.random.default_rng(0)
    t0 = time.perf_counter()
    for _ in range(n_instances):
        template = templates[int(rng.integers(len(templates)))]
        r_p, phi_p = R_P[int(rng.integers(R_P.size))], 2 * np.pi * int(rng.integers(N_PHI)) / N_PHI
        image = render_perturbation_image(axisym.brightness, template, r_p, phi_p, GEOMETRY.inc, (n, n),
                                          NAIVE_PIXEL, supersample=1)
        chi2(VA + sampler.sample(image), vis.V, vis.weights)
    return (time.perf_counter() - t0) / n_instances


def _current_rss_mb() -> float:
    import psutil

    return psutil.Process().memory_info().rss / 1e6


def h_p_bank(n: int):
    """The compromise bank.s templates at three aspect ratios (H/r as a bank dimension)."""
    bank = compromise_bank()  # all three aspect ratios
    base = list(bank.select(h_p=0.07))[:n]
    return [bank.get(t.mass, t.tau0, t.beta, t.hand, h_p=h) for h in H_P for t in base]


def variant_subset(big):
    """The default bank's templates (every morphology) of the single-morphology templates in ``big``
    (all 576 of the default bank when ``big`` is the whole 192)."""
    from spiralbayes.templates import default_bank

    wanted = {(t.mass, t.tau0, t.beta, t.hand, t.h_p) for t in big}
    return [t for t in default_bank() if (t.mass, t.tau0, t.beta, t.hand, t.h_p) in wanted]


# --- cases ----------------------------------------------------------------------------------------
def case_bank(args) -> dict:
    out0 = {"load_before": os.getloadavg()[0]}
    vis, axisym = observation()
    bank = list(compromise_bank().select(h_p=0.07))[: args.templates]  # the paper's 64
    out = {**out0, "N_vis": vis.n, "templates": len(bank)}
    t0 = time.perf_counter()
    serial = scan(vis, axisym, bank, GEOMETRY, r_p=R_P, n_phi_p=N_PHI, progress=False, nthreads=2)
    out["serial_s"] = time.perf_counter() - t0
    out["peak_after_serial_MB"] = peak_mb()
    out["max_error_estimate"] = float(np.nanmax(serial.delta_chi2_error()))
    out["power_check"] = serial.provenance.get("power_check", {}).get("power")
    big = h_p_bank(args.templates)
    t0, c0 = time.perf_counter(), time.process_time()
    scan(vis, axisym, big, GEOMETRY, r_p=R_P, n_phi_p=N_PHI, progress=False, nthreads=2)
    out["serial_3hp_s"], out["templates_3hp"] = time.perf_counter() - t0, len(big)
    out["serial_3hp_cpu_s"] = time.process_time() - c0
    if not args.no_variants:
        variants = variant_subset(big)
        t0, c0 = time.perf_counter(), time.process_time()
        res = scan(vis, axisym, variants, GEOMETRY, r_p=R_P, n_phi_p=N_PHI, progress=False, nthreads=2)
        out["variants_s"], out["templates_variants"] = time.perf_counter() - t0, len(variants)
        out["variants_cpu_s"] = time.process_time() - c0
        out["variants_violations"] = int(res.accuracy_violations().sum())
        out["variants_blocks_s"] = res.provenance["timing_s"]["building_blocks"]
        out["variants_max_error_estimate"] = float(np.nanmax(res.delta_chi2_error()))
        out["load_after_variants"] = os.getloadavg()[0]
    if not args.no_dask:
        from dask.distributed import Client, LocalCluster

        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
                Client(cluster) as client:
            t0 = time.perf_counter()
            parallel = scan(vis, axisym, bank, GEOMETRY, r_p=R_P, n_phi_p=N_PHI, progress=False, scheduler=client)
            out["dask_s"] = time.perf_counter() - t0
            out["dask_worker_MB"] = list(client.run(_current_rss_mb).values())
        out["serial_vs_dask_max_rel"] = float(np.max(np.abs(serial.dchi2 - parallel.dchi2) / parallel.power))
    out["naive_ms"] = 1e3 * naive_time_per_instance(vis, axisym, bank, args.naive)
    return out


def case_as209(args) -> dict:
    from spiralbayes import load_visibilities
    from spiralbayes.axisymmetric import fit_axisymmetric

    geometry = DiscGeometry(inc=34.97, PA=85.76, dRA=-1.9e-3, dDec=2.5e-3)
    vis = load_visibilities(ROOT / "tests" / "data" / "AS209_DSHARP_subsample_uvtable.txt")
    t0 = time.perf_counter()
    axisym = fit_axisymmetric(vis, geometry, progress=False)
    out = {"N_vis": vis.n, "frank_s": time.perf_counter() - t0, "frank_N": axisym.hyperparameters["N"],
           "frank_iterations": axisym.provenance["iterations"], "peak_after_frank_MB": peak_mb()}
    bank = list(compromise_bank())[: args.templates]
    t0 = time.perf_counter()
    result = scan(vis, axisym, bank, progress=False)
    out.update(templates=len(bank), scan_s=time.perf_counter() - t0, peak_MB=peak_mb(),
               r_p_max=float(result.r_p[-1]), path=result.provenance["quadrature"]["power_path_used"],
               max_error_estimate=float(np.nanmax(result.delta_chi2_error())))
    return out


def case_million(args) -> dict:
    from spiralbayes.simulate import simulate_observation

    disc = DiscModel(tau_ref=3.0)
    parts = [simulate_observation("high_sensitivity", disc, GEOMETRY, seed=s) for s in (1, 2)]
    vis = Visibilities(*(np.concatenate([getattr(p, k) for p in parts]) for k in ("u", "v", "V", "weights")))
    del parts
    axisym = AxisymmetricModel.from_profile(disc.profile(0.87e-3), GEOMETRY)
    out = {"N_vis": vis.n, "peak_after_data_MB": peak_mb()}
    bank = list(compromise_bank())[: args.templates]
    t0 = time.perf_counter()
    result = scan(vis, axisym, bank, GEOMETRY, r_p=R_P, n_phi_p=N_PHI, progress=False, nthreads=2)
    timing = result.provenance["timing_s"]
    out.update(templates=len(bank), scan_s=time.perf_counter() - t0, peak_MB=peak_mb(), setup_s=timing["setup"],
               check_s=timing["check"], per_template_s=timing["templates"] / len(bank),
               path=result.provenance["quadrature"]["power_path_used"],
               max_error_estimate=float(np.nanmax(result.delta_chi2_error())))
    return out


def case_accuracy(args) -> dict:
    sys.path.insert(0, str(ROOT))
    from spiralbayes.axisymmetric import fit_axisymmetric
    from spiralbayes.simulate import simulate_observation
    from spiralbayes.templates import make_template
    from tests._support.quadrature_reference import reference_terms

    geometry = DiscGeometry(30.0, 60.0, 0.004, -0.003)
    templates = [make_template(1.0, 3.0, 10.0, "R"), make_template(1.0, 0.1, 0.0, "R"),
                 make_template(0.1, 3.0, 10.0, "R")]
    vis = simulate_observation("fiducial", DiscModel(tau_ref=3.0), geometry, templates[0], r_p=50 / 140,
                               phi_p=0.0, seed=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        axisym = fit_axisymmetric(vis, geometry, progress=False)
    r_p = np.array([0.1, 0.36, 0.5])
    residual = vis.V - axisym.visibilities(vis.u, vis.v, geometry)
    out = {"N_vis": vis.n, "rows": []}
    for rule in ("product", "midpoint"):
        t0 = time.perf_counter()
        result = scan(vis, axisym, templates, geometry, r_p=r_p, n_phi_p=N_PHI, progress=False, quadrature=rule)
        elapsed = time.perf_counter() - t0
        worst = {"rule": rule, "scan_s": elapsed, "max_dP_rel": 0.0, "max_dC_rel": 0.0, "max_ddchi2": 0.0,
                 "max_estimate": float(np.nanmax(result.delta_chi2_error())), "estimate_covers": True,
                 "over_tolerance": 0}
        for t, template in enumerate(templates):
            for i, r in enumerate(r_p):
                phi = result.phi_p[::10]
                c, p = reference_terms(vis, residual, geometry, axisym.brightness, template, r, phi, order_r=4,
                                       order_phi=3, support=axisym.Rmax)
                dc, dp = result.cross[t, i, ::10] - c, result.power[t, i, ::10] - p
                dd = np.abs(2 * dc - dp)
                worst["max_dP_rel"] = max(worst["max_dP_rel"], float(np.max(np.abs(dp) / p)))
                worst["max_dC_rel"] = max(worst["max_dC_rel"], float(np.max(np.abs(dc) / np.maximum(np.abs(c),
                                                                                                  np.sqrt(p)))))
                worst["max_ddchi2"] = max(worst["max_ddchi2"], float(np.max(dd)))
                worst["over_tolerance"] += int(np.sum(dd > 0.05 + 1e-4 * np.abs(2 * c - p)))
                if rule == "product":
                    worst["estimate_covers"] &= bool(np.all(dd <= result.delta_chi2_error()[t, i, ::10] + 1e-6))
        out["rows"].append(worst)
    return out


CASES = {"bank": case_bank, "as209": case_as209, "million": case_million, "accuracy": case_accuracy}


def report(name: str, r: dict, n_inst_per_template: int = R_P.size * N_PHI) -> None:
    if name == "bank":
        naive = r["naive_ms"] / 1e3
        print(f"[bank] N_vis = {r['N_vis']}; naive loop (image {NAIVE_PIXEL} arcsec + NUFFT + chi2): "
              f"{1e3 * naive:.1f} ms per instance")
        for label, key, n_t in (("paper's bank, serial (2 threads)", "serial_s", r["templates"]),
                                ("paper's bank, Dask (2 workers)", "dask_s", r["templates"]),
                                ("3 h_p x bank, serial (2 threads)", "serial_3hp_s", r["templates_3hp"]),
                                ("default bank (3 h_p x 3 morphologies), serial (2 threads)", "variants_s",
                                 r.get("templates_variants", 0))):
            if key in r:
                n_inst = n_t * n_inst_per_template
                print(f"[bank] {label}: {n_t} templates in {r[key]:.1f} s, {1e6 * r[key] / n_inst:.0f} us per "
                      f"instance, naive would take {naive * n_inst / 60:.0f} min: x{naive * n_inst / r[key]:.0f}")
        if "variants_s" in r:
            print(f"[bank] default bank: {r['templates_variants']} templates in {r['variants_s']:.1f} s (target <= 60 "
                  f"s) (grouping {r['variants_blocks_s']:.1f} s), {r['variants_s'] / r['serial_3hp_s']:.3f} x the "
                  f"{r['templates_3hp']}-template scan of the same run; largest error estimate "
                  f"{r['variants_max_error_estimate']:.2e}, over the tolerance at {r['variants_violations']} "
                  f"instances; CPU time (all threads) {r['variants_cpu_s']:.1f} s vs {r['serial_3hp_cpu_s']:.1f} s: "
                  f"{r['variants_cpu_s'] / r['serial_3hp_cpu_s']:.3f}; load average {r['load_before']:.1f} before the "
                  f"case, {r['load_after_variants']:.1f} after the variants")
        print(f"[bank] peak memory after the serial scan {r['peak_after_serial_MB']:.0f} MB; Dask workers "
              f"{', '.join(f'{m:.0f}' for m in r.get('dask_worker_MB', []))} MB; serial vs Dask max |d dchi2| / "
              f"power {r.get('serial_vs_dask_max_rel', float('nan')):.1e}; largest error estimate "
              f"{r['max_error_estimate']:.2e}; power self-check {r['power_check']:.1e}")
    elif name == "as209":
        print(f"[as209] N_vis = {r['N_vis']}: frank (N = {r['frank_N']}, {r['frank_iterations']} iterations) "
              f"{r['frank_s']:.1f} s; scan of {r['templates']} templates x 25 x 90 (r_p <= {r['r_p_max']:.3g}, "
              f"{r['path']} path) {r['scan_s']:.1f} s; peak memory {r['peak_MB']:.0f} MB "
              f"({r['peak_after_frank_MB']:.0f} MB after frank); largest error estimate {r['max_error_estimate']:.1e}")
    elif name == "million":
        print(f"[million] N_vis = {r['N_vis']}: {r['templates']} templates in {r['scan_s']:.1f} s ({r['path']} path): "
              f"set-up {r['setup_s']:.1f} s (frank's exact V_A at every baseline included), self-check "
              f"{r['check_s']:.1f} s, {r['per_template_s']:.2f} s per template (first one's one-off work included); "
              f"peak memory {r['peak_MB']:.0f} MB ({r['peak_after_data_MB']:.0f} MB with the data alone)")
    elif name == "accuracy":
        for w in r["rows"]:
            print(f"[accuracy] {w['rule']:8s} rule vs converged reference (3 templates x 3 r_p x 9 phi_p, "
                  f"N = {r['N_vis']}): max |dP|/P {w['max_dP_rel']:.1e}, max |dC|/max(|C|, sqrt P) "
                  f"{w['max_dC_rel']:.1e}, max |d dchi2| {w['max_ddchi2']:.1e}, over 0.05 + 1e-4|dchi2|: "
                  f"{w['over_tolerance']}/81; largest error estimate {w['max_estimate']:.1e}"
                  + (f", estimate covers the error: {w['estimate_covers']}" if w["rule"] == "product" else ""))


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--case", choices=["all", *CASES], default="all")
    parser.add_argument("--templates", type=int, default=64)
    parser.add_argument("--naive", type=int, default=20, help="instances timed for the naive loop")
    parser.add_argument("--no-dask", action="store_true")
    parser.add_argument("--no-variants", action="store_true", help="skip the default bank (576 templates)")
    parser.add_argument("--json", action="store_true", help=argparse.SUPPRESS)  # child process output
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    if args.case != "all":
        result = CASES[args.case](args)
        if args.json:
            print("JSON " + json.dumps(result))
        else:
            report(args.case, result)
        return
    print(f"load before: {os.getloadavg()}")
    for name in CASES:
        cmd = [sys.executable, __file__, "--case", name, "--templates", str(args.templates), "--naive",
               str(args.naive), "--json"] + (["--no-dask"] if args.no_dask else []) \
            + (["--no-variants"] if args.no_variants else [])
        proc = subprocess.run(cmd, capture_output=True, text=True)
        lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("JSON ")]
        if proc.returncode or not lines:
            print(f"[{name}] failed:\n{proc.stderr[-2000:]}")
            continue
        report(name, json.loads(lines[-1][5:]))
    print(f"load after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
