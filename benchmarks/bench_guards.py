"""What the hardening costs and how well the weight guard measures: load-time checks and resume keys.

Run: ``python benchmarks/bench_guards.py`` (about a minute on 2 cores).

1. Weight estimators against the truth, per preset of Stevenson et al. (2024, Table 1) with a
   planet-free power-law disc: the factor by which correct weights "should" be multiplied
   (ideal: 1) from uv neighbour planes (``neighbour_weight_factor``, used by the load-time check
   and by ``[data] estimate_weights``), from uv cells (``estimate_weight_factor`` without a
   geometry) and from deprojected annuli (with the true geometry); and the neighbour estimate for
   CASA simobserve-like weights (all 2: ideal ``1 / (2 sigma^2)``).
2. Load time of the high-sensitivity set (4.4e5 visibilities, spiralbayes HDF5) with and without
   the load-time checks (units and weights), as a ratio.
3. Resume key: hashing the compromise bank (192 templates) and the data, against loading the bank.
"""

from __future__ import annotations

import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from spiralbayes.geometry import DiscGeometry
from spiralbayes.io import load_visibilities, save_visibilities
from spiralbayes.simulate import PRESETS, DiscModel, simulate_observation
from spiralbayes.visibilities import estimate_weight_factor, neighbour_weight_factor

GEOMETRY = DiscGeometry(30.0, 60.0)


def _median_time(fn, repeat=3):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times))


def estimators() -> None:
    print("1. weight factor that correct weights 'need' (ideal 1.000); simobserve-like weights (ideal in brackets)")
    print(f"{'preset':<18}{'N':>8}{'neighbours':>12}{'uv cells':>10}{'annuli':>9}{'simobserve':>13}{'(ideal)':>11}")
    for name in PRESETS:
        vis = simulate_observation(name, DiscModel(distance=140.0, tau_ref=3.0), GEOMETRY, seed=1)
        ideal = 1.0 / (2.0 * float(np.median(vis.sigma)) ** 2)
        simobserve = vis.with_weights(np.full(vis.n, 2.0), "WEIGHT = SIGMA = 1")
        print(f"{name:<18}{vis.n:>8}{neighbour_weight_factor(vis).factor:>12.3f}"
              f"{estimate_weight_factor(vis).factor:>10.3f}{estimate_weight_factor(vis, GEOMETRY).factor:>9.3f}"
              f"{neighbour_weight_factor(simobserve).factor:>13.4g}{ideal:>11.4g}")


def load_overhead() -> None:
    vis = simulate_observation("high_sensitivity", DiscModel(distance=140.0, tau_ref=3.0), GEOMETRY, seed=1)
    with tempfile.TemporaryDirectory() as folder:
        path = save_visibilities(vis, Path(folder) / "obs.h5")
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # correct weights and units: no warning may fire
            plain = _median_time(lambda: load_visibilities(path, check_weights_on_load=False))
            checked = _median_time(lambda: load_visibilities(path))
    print(f"\n2. loading {vis.n} visibilities: {plain:.3f} s without the weight check, {checked:.3f} s with it "
          f"(ratio {checked / plain:.2f}; the units check runs in both)")


def resume_key_cost() -> None:
    from spiralbayes._provenance import content_hash, data_hash
    from spiralbayes.templates import compromise_bank
    from spiralbayes.templates.template import template_metadata

    compromise_bank()  # build and cache once
    load = _median_time(compromise_bank, repeat=3)
    bank = compromise_bank()
    keys = _median_time(lambda: [content_hash(t.x, t.phi, t.delta, template_metadata(t)) for t in bank], repeat=3)
    vis = simulate_observation("high_sensitivity", DiscModel(distance=140.0, tau_ref=3.0), GEOMETRY, seed=1)
    data = _median_time(lambda: data_hash(vis.u, vis.v, vis.V, vis.weights), repeat=3)
    print(f"\n3. resume key: {len(bank)} template hashes ({bank.nbytes() / 1e6:.0f} MB) {keys:.3f} s, data hash of "
          f"{vis.n} visibilities {data:.3f} s; loading the cached bank {load:.3f} s (ratio {(keys + data) / load:.2f})")


if __name__ == "__main__":
    estimators()
    load_overhead()
    resume_key_cost()
