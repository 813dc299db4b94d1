"""CASA as a partner: write_ms, tclean and simobserve timings, and the two simulation backends compared.

Run: ``python benchmarks/bench_casa.py [--per-row-times]`` after ``pip install -e ".[casa]"``
(a few minutes on 2 cores). Prints:

1. ``write_ms`` of the fiducial observation (36 120 visibilities), with its antenna layout and
   with the generic layout (no antennas known).
2. tclean on both sets (dirty image, natural weighting; Briggs 0.5 Högbom CLEAN to 2 sigma of the
   natural noise), wall and CPU seconds of this process, and the largest difference between the
   two dirty images (they must be the same image). With ``--per-row-times`` also the baseline
   the writer replaced: the same 1806-row subset written with one time stamp per row, against
   one per integration (CASA's visibility iterator makes one chunk per time stamp).
3. ``simulate_observation(backend="casa")`` against the package's backend on the fiducial set-up
   (a 1 M_th, tau0 = 3, beta = 10 planet at 50 au): simobserve time per configuration, row-by-row
   uv mismatch, relative RMS difference of the noise-free visibilities (and by baseline length),
   and the noise per visibility and image noise of each backend.
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
from pathlib import Path

import numpy as np

from spiralbayes._casa import import_casa
from spiralbayes.image_plane import _cpu_seconds, clean_image, default_clean_grid
from spiralbayes.geometry import DiscGeometry
from spiralbayes.io import write_ms
from spiralbayes.simulate import DiscModel, disc_visibilities, simulate_observation
from spiralbayes.templates import make_template

GEOMETRY = DiscGeometry(30.0, 60.0)
DISC = DiscModel(distance=140.0, r_ref=50.0, tau_ref=3.0)


def _timed(fn):
    c0, t0 = _cpu_seconds(), time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0, _cpu_seconds() - c0


def _dirty(vis, folder: Path, name: str, n: int, cell: float):
    return clean_image(vis, folder, name, imsize=n, cell=cell, weighting="natural", niter=0)


def writer_and_tclean(vis, folder: Path, per_row: bool) -> None:
    print("1. write_ms (36 120 visibilities)")
    for label, v in (("antenna layout", vis), ("generic layout", dataclasses.replace(vis, layout=None))):
        _, wall, _ = _timed(lambda v=v: write_ms(v, folder / "w.ms"))
        print(f"   {label:16s} {wall:6.2f} s")
    n, cell = default_clean_grid(vis, DISC.r_max)
    print(f"2. tclean, {n} x {n} pixels of {cell} arcsec (wall / CPU s)")
    known = _dirty(vis, folder, "known", n, cell)
    generic = _dirty(dataclasses.replace(vis, layout=None), folder, "generic", n, cell)
    for label, c in (("dirty, antenna layout", known), ("dirty, generic layout", generic)):
        print(f"   {label:34s} {c.timings['tclean_wall_s']:6.1f} / {c.timings['tclean_cpu_s']:5.1f}")
    print(f"   max |dirty(antennas) - dirty(generic)| / peak = "
          f"{np.max(np.abs(known.image - generic.image)) / known.image.max():.1e}")
    threshold = 2.0 / np.sqrt(vis.weights.sum())
    briggs = clean_image(vis, folder, "briggs", imsize=n, cell=cell, threshold=threshold, niter=20000)
    print(f"   {'Briggs 0.5 Hogbom to 2 sigma_nat':34s} {briggs.timings['tclean_wall_s']:6.1f} / "
          f"{briggs.timings['tclean_cpu_s']:5.1f}  ({briggs.iterations} iterations, beam "
          f"{briggs.beam[0]:.3f}\" x {briggs.beam[1]:.3f}\")")
    if per_row:
        _per_row_baseline(vis, folder, n, cell)


def _per_row_baseline(vis, folder: Path, n: int, cell: float) -> None:
    import casacore.tables as tables

    sub = vis.subset(np.arange(2 * 903))
    grouped = _dirty(sub, folder, "grouped", n, cell)
    write_ms(dataclasses.replace(sub, layout=None), folder / "perrow.ms", rows_per_time=1)  # one TIME per row
    casatools, casatasks = import_casa()
    with tables.table(str(folder / "perrow.ms"), readonly=False, ack=False) as t:
        times = 4.8e9 + np.arange(t.nrows(), dtype=float)
        t.putcol("TIME", times)
        t.putcol("TIME_CENTROID", times)
    c0, t0 = _cpu_seconds(), time.perf_counter()
    casatasks.tclean(vis=str(folder / "perrow.ms"), imagename=str(folder / "perrow"), imsize=n, cell=f"{cell}arcsec",
                     specmode="mfs", gridder="standard", weighting="natural", niter=0, stokes="I")
    wall, cpu = time.perf_counter() - t0, _cpu_seconds() - c0
    print(f"   1806 rows, one TIME per integration: {grouped.timings['tclean_wall_s']:6.1f} / "
          f"{grouped.timings['tclean_cpu_s']:5.1f};  one TIME per row: {wall:6.1f} / {cpu:5.1f}  "
          f"(CPU ratio {cpu / grouped.timings['tclean_cpu_s']:.0f})")


def backends() -> None:
    planet = make_template(1.0, 3.0, 10.0, "R")
    kw = dict(r_p=50.0 / 140.0, phi_p=0.0, seed=1)
    package = simulate_observation("fiducial", DISC, GEOMETRY, planet, **kw)
    (casa_clean, wall, _) = _timed(lambda: simulate_observation("fiducial", DISC, GEOMETRY, planet, add_noise=False,
                                                              backend="casa", **kw))
    t = casa_clean.provenance["timings"]
    print(f"3. simulate_observation(backend='casa'): {wall:.1f} s in all; sky model {t['sky_model_s']:.1f} s, "
          + ", ".join(f"simobserve {k.split('_')[1]} {v:.1f} s" for k, v in t.items() if k.startswith("simobserve")))
    print(f"   hour-angle offset of simobserve corrected: {casa_clean.provenance['hour_angle_offset_s']}")
    q = np.hypot(package.u, package.v)
    print(f"   rows {casa_clean.n} vs {package.n}; max |uv_casa + uv_package| / |uv| = "
          f"{np.max(np.hypot(casa_clean.u + package.u, casa_clean.v + package.v) / q):.1e}")
    model = disc_visibilities(casa_clean.u, casa_clean.v, DISC.profile(casa_clean.wavelength), GEOMETRY, DISC.r_max,
                              r_min=DISC.r_min, perturbation=planet, r_p=kw["r_p"], phi_p=kw["phi_p"])
    diff = casa_clean.V - model
    print(f"   noise-free: RMS |V_casa - V_package| / RMS |V| = "
          f"{np.sqrt(np.mean(np.abs(diff) ** 2) / np.mean(np.abs(model) ** 2)):.2e}")
    qc = np.hypot(casa_clean.u, casa_clean.v)
    for lo, hi in ((0, 5e5), (5e5, 1e6), (1e6, 2e6), (2e6, 5e6)):
        s = (qc >= lo) & (qc < hi)
        print(f"     {lo / 1e6:3.1f}-{hi / 1e6:3.1f} Mlambda: RMS diff "
              f"{np.sqrt(np.mean(np.abs(diff[s]) ** 2)) * 1e3:.3f} mJy, "
              f"RMS |V| {np.sqrt(np.mean(np.abs(model[s]) ** 2)) * 1e3:8.2f} mJy, median Re(V_casa / V_package) "
              f"{np.median((casa_clean.V[s] / model[s]).real):.4f}")
    s_casa, s_pkg = 1 / np.sqrt(casa_clean.weights.mean()), 1 / np.sqrt(package.weights.mean())
    print(f"   noise per visibility (Re, Im of Stokes I): CASA {s_casa * 1e3:.3f} mJy, package {s_pkg * 1e3:.3f} mJy "
          f"(ratio {s_casa / s_pkg:.3f}); image noise {1e6 / np.sqrt(casa_clean.weights.sum()):.1f} vs "
          f"{1e6 / np.sqrt(package.weights.sum()):.1f} uJy/beam")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--per-row-times", action="store_true", help="also time the one-TIME-per-row layout")
    args = parser.parse_args()
    import_casa()
    vis = simulate_observation("fiducial", DISC, GEOMETRY, seed=1)
    with tempfile.TemporaryDirectory(prefix="bench-casa-") as tmp:
        writer_and_tclean(vis, Path(tmp), args.per_row_times)
    backends()


if __name__ == "__main__":
    main()
