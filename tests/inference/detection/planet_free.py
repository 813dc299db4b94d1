"""False detections on planet-free data with the morphology-variant bank (issue 22, Done-when 4).

Shared by ``test_planet_free.py`` (slow) and ``python -m tests.inference.detection.planet_free``.

Each dataset is a *reduced fiducial* observation: the fiducial preset's coverage and per-visibility
noise (C-4 + C-7, 0.87 mm, 140 pc, inc 30°, PA 60°, τ_ref 3, no planet) keeping every
:data:`STRIDE`-th visibility (about 9,000 of 36,120: a quarter of the integrations, half the
sensitivity), each with its own noise seed. The axisymmetric model is the true disc
(:class:`~spiralbayes.simulate.asymmetric.ExactAxisymmetric`) or, with ``frank=True``, frank fitted at
the true geometry (about a minute of CPU per dataset on the shared machine), the scan covers
the variant bank restricted to τ0 3, β 0, H/r 0.07 (every variant and mass, both hands) over
:data:`R_GRID` × 90 azimuths, and the verdict is :func:`~spiralbayes.inference.detection.detect_with_planet_peak`
with the competing models — fitted only when tests 1 and 2 pass, since test 3 can only turn a
detection down.
"""

from __future__ import annotations

import json
import logging
import sys
import warnings
from functools import lru_cache

import numpy as np
from spiralbayes._provenance import atomic_path

log = logging.getLogger(__name__)

DISTANCE = 140.0
STRIDE = 4
R_GRID = np.linspace(0.04, 0.52, 13)  # arcsec: 6-73 au, the fiducial disc's planets
SEEDS = tuple(range(1000, 1050))
BANK = {"taus": (3.0,), "betas": (0.0,), "h_ps": (0.07,)}


@lru_cache(maxsize=1)
def bank_templates() -> tuple:
    from spiralbayes.templates.variants import DEFAULT_VARIANTS, variant_grid

    return tuple(variant_grid(DEFAULT_VARIANTS, **BANK))


@lru_cache(maxsize=1)
def _coverage():
    from spiralbayes.simulate.presets import get_preset

    return get_preset("fiducial").coverage()


def dataset(seed: int):
    """A reduced fiducial observation of the planet-free disc (module docstring)."""
    from spiralbayes import DiscGeometry
    from spiralbayes.simulate import DiscModel, simulate_observation

    geometry = DiscGeometry(30.0, 60.0)
    vis = simulate_observation("fiducial", DiscModel(distance=DISTANCE, tau_ref=3.0), geometry, seed=seed,
                               coverage=_coverage())
    return vis.subset(np.arange(0, vis.V.size, STRIDE)), geometry


def evaluate(seed: int, frank: bool = False) -> dict:
    """The verdict's numbers for one dataset."""
    from spiralbayes.axisymmetric import fit_axisymmetric
    from spiralbayes.inference.detection import detect, detect_with_planet_peak, fit_alternatives
    from spiralbayes.inference.scan.run import scan

    vis, geometry = dataset(seed)
    if frank:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            axisym = fit_axisymmetric(vis, geometry, progress=False)
    else:
        from spiralbayes.simulate import DiscModel
        from spiralbayes.simulate.asymmetric import ExactAxisymmetric

        axisym = ExactAxisymmetric(DiscModel(distance=DISTANCE, tau_ref=3.0), _coverage().wavelength, geometry)
    templates = bank_templates()
    result = scan(vis, axisym, list(templates), geometry, r_p=R_GRID, distance=DISTANCE, progress=False)
    first = detect(result)
    alts = None
    if first.test1_passed and first.test2_passed:
        alts = fit_alternatives(vis, axisym, geometry, progress=False)
    verdict = detect_with_planet_peak(result, vis, axisym, templates, geometry, alternatives=alts)
    return {"seed": seed, "frank": frank, "n_vis": int(vis.V.size), "delta_bic": verdict.delta_bic,
            "template": verdict.template,
            "test1": verdict.test1_passed, "test2": verdict.test2_passed, "test3": verdict.test3_passed,
            "candidate": verdict.candidate is not None, "detected": verdict.detected}


def main(out: str = "planet_free.json", frank: str = "") -> None:
    logging.basicConfig(level=logging.INFO)
    rows = []
    for seed in SEEDS:
        rows.append(evaluate(seed, frank=bool(frank)))
        log.info("%s", rows[-1])
        with atomic_path(out) as tmp:  # a run stopped mid-write keeps the rows it had
            tmp.write_text(json.dumps(rows, indent=1, default=float))
    largest = max(rows, key=lambda r: r["delta_bic"])
    print(f"{sum(r['detected'] for r in rows)} detections in {len(rows)} planet-free datasets; test 1 passed in "
          f"{sum(r['test1'] for r in rows)}, tests 1 and 2 in {sum(r['test1'] and r['test2'] for r in rows)}; "
          f"largest Delta BIC {largest['delta_bic']:.1f} (seed {largest['seed']}, {largest['template']})")


if __name__ == "__main__":
    main(*sys.argv[1:])
