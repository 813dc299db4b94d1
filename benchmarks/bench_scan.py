"""The full-bank scan against the naive loop (issue 5 benchmark).

A synthetic observation with ~1e5 visibilities (C-4 + C-7, 0.87 mm), the 64-template default
bank, the authors' grid of 25 r_p x 90 phi_p (144,000 instances). Prints the wall time of the
scan (serial and Dask LocalCluster with 2 workers), the time per instance, the naive loop's
time per instance (render image + NUFFT + chi^2 for each instance, as the authors' galario loop)
measured on a subset in the same run, their ratio, and peak memory.

    python benchmarks/bench_scan.py                 # full bank, serial and Dask
    python benchmarks/bench_scan.py --templates 8   # quicker
"""

from __future__ import annotations

import argparse
import resource
import time
import warnings

import numpy as np

from spiralbayes import AxisymmetricModel, DiscGeometry, Visibilities
from spiralbayes.fourier import ImageSampler
from spiralbayes.inference.statistics import chi2
from spiralbayes.model import render_perturbation_image
from spiralbayes.inference.scan import scan
from spiralbayes.simulate import DiscModel, observe, uv_coverage
from spiralbayes.templates import default_bank

GEOMETRY = DiscGeometry(30.0, 60.0)
R_P = np.linspace(0.02, 0.5, 25)
N_PHI = 90
NAIVE_PIXEL = 0.004  # arcsec; the converged direct evaluation needs <= 2-4 mas (DESIGN.md)


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


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--templates", type=int, default=64)
    parser.add_argument("--naive", type=int, default=20, help="instances timed for the naive loop")
    parser.add_argument("--no-serial", action="store_true")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    vis, axisym = observation()
    bank = list(default_bank())[: args.templates]
    n_inst = len(bank) * R_P.size * N_PHI
    print(f"N_vis = {vis.n}, templates = {len(bank)}, instances = {n_inst}")
    runs = {}
    if not args.no_serial:
        t0 = time.perf_counter()
        serial = scan(vis, axisym, bank, GEOMETRY, r_p=R_P, n_phi_p=N_PHI, progress=False, nthreads=2)
        runs["serial (ducc0 2 threads)"] = time.perf_counter() - t0
        serial_peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    from dask.distributed import Client, LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        t0 = time.perf_counter()
        parallel = scan(vis, axisym, bank, GEOMETRY, r_p=R_P, n_phi_p=N_PHI, progress=False, client=client)
        runs["Dask LocalCluster (2 workers)"] = time.perf_counter() - t0
        worker_rss = client.run(_current_rss_mb)  # ru_maxrss is inherited across fork, so not used
    if not args.no_serial:  # ducc0's single-precision power term depends slightly on the thread count
        diff = np.abs(serial.dchi2 - parallel.dchi2)
        print(f"serial vs Dask: max |difference| {diff.max():.2e}, "
              f"max relative to sum w|dV|^2 {np.max(diff / parallel.power):.1e}")
    naive = naive_time_per_instance(vis, axisym, bank, args.naive)
    print(f"naive loop (image {NAIVE_PIXEL} arcsec + NUFFT + chi2): {1e3 * naive:.1f} ms per instance "
          f"(=> {naive * n_inst / 60:.1f} min for all {n_inst} instances)")
    for name, seconds in runs.items():
        per = seconds / n_inst
        print(f"{name}: {seconds:.1f} s in all, {1e6 * per:.0f} us per instance, speed-up x{naive / per:.0f}")
    if not args.no_serial:
        print(f"peak memory of the serial scan (whole process): {serial_peak:.0f} MB")
    print("memory of each Dask worker after the scan (caches held): "
          + ", ".join(f"{v:.0f} MB" for v in worker_rss.values()))


if __name__ == "__main__":
    main()
