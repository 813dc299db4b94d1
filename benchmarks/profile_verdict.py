"""Where the verdict's cost grows with the number of visibilities: calls and CPU per function at two sizes.

The verdict (the alternatives' fits and tests 1-3) is profiled with cProfile on the scale benchmark's data
(``bench_scale.py``: high-sensitivity preset, 1 M_th planet at 50 au, τ0 0.3, default bank) at two sizes,
each in its own process. The table compares, per function, the number of calls and the self CPU time,
with the growth exponent d ln t / d ln N: a per-visibility cost shows as the same number of calls at a
time growing with exponent ~1; an optimiser that iterates more on larger data shows as more calls.

    python benchmarks/profile_verdict.py                 # 1e6 and 3e6 (~15 min of CPU)
    python benchmarks/profile_verdict.py --sizes 1e5 1e6
"""

from __future__ import annotations

import argparse
import cProfile
import json
import math
import pstats
import subprocess
import sys
import tempfile
import time
import warnings
from dataclasses import replace
from pathlib import Path


def profile_one(n: float, out: Path) -> dict:
    import numpy as np

    import spiralbayes as sb
    from spiralbayes.inference.detection.alternatives import fit_alternatives
    from spiralbayes.inference.detection.verdict import detect_with_planet_peak

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_scale import N_BASELINES, ON_SOURCE_S

    warnings.simplefilter("ignore")
    tau0 = 0.3
    preset = replace(sb.PRESETS["high_sensitivity"], integration_time=ON_SOURCE_S * N_BASELINES / n)
    disc = sb.DiscModel(distance=140.0, r_ref=50.0, tau_ref=tau0)
    geometry = sb.DiscGeometry(30.0, 60.0)
    planet = sb.make_template(mass=1.0, tau0=tau0, beta=0.0, wavelength=preset.wavelength)
    vis = sb.simulate_observation(preset, disc, geometry, planet, r_p=50 / 140, phi_p=np.radians(40.0), seed=1)
    axisym = sb.fit_axisymmetric(vis, geometry, progress=False)
    templates = list(sb.default_bank().select(tau0=tau0))
    result = sb.scan(vis, axisym, templates, geometry, distance=140.0, progress=False)
    prof = cProfile.Profile()
    c0 = time.process_time()
    prof.enable()
    alternatives = fit_alternatives(vis, axisym, geometry, progress=False)
    detect_with_planet_peak(result, vis, axisym, templates, geometry, alternatives=alternatives)
    prof.disable()
    prof.dump_stats(str(out))
    return {"n": vis.n, "cpu_s": time.process_time() - c0}


def compare(a: Path, b: Path, n_a: int, n_b: int, most: int = 20) -> list[str]:
    sa, sb_ = pstats.Stats(str(a)).stats, pstats.Stats(str(b)).stats  # type: ignore[attr-defined]
    ratio = math.log(n_b / n_a)
    rows = []
    for key, (_, calls_a, self_a, _, _) in sa.items():
        if key in sb_:
            _, calls_b, self_b, _, _ = sb_[key]
            rows.append((self_b - self_a, key, calls_a, calls_b, self_a, self_b))
    rows.sort(reverse=True)
    total_a = sum(v[2] for v in sa.values())
    total_b = sum(v[2] for v in sb_.values())
    lines = [f"verdict self CPU {total_a:.1f} s -> {total_b:.1f} s: exponent {math.log(total_b / total_a) / ratio:.2f}",
             f"{'function':40s} {'file':24s} {'calls':>15s} {'self CPU [s]':>15s} exponent"]
    for _, key, ca, cb, ta, tb in rows[:most]:
        exponent = f"{math.log(tb / ta) / ratio:.2f}" if ta > 0.05 and tb > 0 else "-"
        lines.append(f"{key[2][:40]:40s} {Path(key[0]).name[:24]:24s} {ca:7d} {cb:7d} {ta:7.1f} {tb:7.1f} {exponent}")
    return lines


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", nargs=2, type=float, default=[1e6, 3e6])
    ap.add_argument("--one", nargs=2, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one:
        print(json.dumps(profile_one(float(args.one[0]), Path(args.one[1]))))
        return
    with tempfile.TemporaryDirectory() as tmp:
        runs = []
        for n in args.sizes:  # each size in its own process, as the scale benchmark does
            out = Path(tmp) / f"verdict_{n:g}.prof"
            text = subprocess.run([sys.executable, __file__, "--one", str(n), str(out)], check=True,
                                  capture_output=True, text=True).stdout
            runs.append((json.loads(text.strip().splitlines()[-1]), out))
        (ra, pa), (rb, pb) = runs
        print(f"verdict CPU {ra['cpu_s']:.1f} s at {ra['n']} visibilities, {rb['cpu_s']:.1f} s at {rb['n']}")
        print("\n".join(compare(pa, pb, ra["n"], rb["n"])))


if __name__ == "__main__":
    main()
