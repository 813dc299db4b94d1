"""How well the continuous template family reproduces the generator's exact template.

Shared by ``test_family.py`` and ``python -m tests.templates.family_accuracy`` (prints the
docs/templates.md table).

Reference: the generator's own template at the intermediate point
(:func:`spiralbayes.templates.variants.variant_template`), not the family. Measure: the χ² that
using the interpolated template instead of the exact one costs on the fiducial observation
(36,120 visibilities, C-4 + C-7, 0.87 mm, 140 pc, inc 30°, PA 60°, planet at 50 au):
``loss = Σ w |ΔV_exact − ΔV_family|²`` — the expected χ² increase at the true planet when the data
hold the exact spiral — beside the planet's own ``Δχ² = Σ w |ΔV_exact|²``, and the scan's
accuracy tolerance at that Δχ² (:data:`spiralbayes.inference.scan.accuracy.TOLERANCE`).
"""

from __future__ import annotations

import sys
from functools import lru_cache

import numpy as np

DISTANCE = 140.0
R_P_AU = 50.0
PHI_P = 0.3
MASSES = (0.2, 0.5, 2.0)  # between the bank's 0.1, 0.3, 1, 3 M_th
H_TARGETS = (0.06, 0.07, 0.08)  # between the family's H/r nodes (0.05, 0.0625, 0.075, 0.0875, 0.1)
VARIANTS = ("compromise", "hydro", "wakeflow")
TAUS = (0.1, 0.3, 1.0, 3.0)
BETAS = (0.0, 10.0)


@lru_cache(maxsize=1)
def _observation():
    from spiralbayes import DiscGeometry
    from spiralbayes.simulate import DiscModel, simulate_observation
    from spiralbayes.simulate.presets import get_preset

    cov = get_preset("fiducial").coverage()
    geometry = DiscGeometry(30.0, 60.0)
    vis = simulate_observation("fiducial", DiscModel(distance=DISTANCE, r_ref=R_P_AU), geometry, coverage=cov,
                               add_noise=False)
    return cov, geometry, vis.weights


def _dv(template, tau0: float) -> np.ndarray:
    from spiralbayes.model import perturbation_visibilities
    from spiralbayes.simulate import DiscModel

    cov, geometry, _ = _observation()
    profile = DiscModel(distance=DISTANCE, r_ref=R_P_AU, tau_ref=tau0).profile(cov.wavelength)
    return perturbation_visibilities(cov.u, cov.v, geometry, profile, template, R_P_AU / DISTANCE, PHI_P)


def loss(family, mass: float, h_p: float | None = None) -> dict:
    """``own`` Δχ² of the exact template, the ``loss`` of the family's, and the scan's ``tolerance``."""
    from spiralbayes.inference.scan.accuracy import TOLERANCE
    from spiralbayes.templates.variants import variant_template

    h = float(family.h_ps[0]) if h_p is None else float(h_p)
    exact = variant_template(mass, family.tau0, family.beta, family.hand, family.variant, h_p=h)
    w = _observation()[2]
    e, f = _dv(exact, family.tau0), _dv(family.at(mass, h_p), family.tau0)
    own = float(np.sum(w * np.abs(e) ** 2))
    return {"variant": family.variant, "tau0": family.tau0, "beta": family.beta, "mass": mass, "h_p": h,
            "own": own, "loss": float(np.sum(w * np.abs(e - f) ** 2)),
            "tolerance": TOLERANCE[0] + TOLERANCE[1] * own}


def table(variants=VARIANTS, taus=TAUS, betas=BETAS) -> list[dict]:
    """Every family of the bank's grid: the masses at a fixed H/r 0.07 (:data:`MASSES`), and each
    (mass, H/r) of :data:`MASSES` x :data:`H_TARGETS` in the family spanning the bank's H/r."""
    from spiralbayes.templates.family import H_NODES, TemplateFamily

    rows = []
    for v in variants:
        for tau in taus:
            for beta in betas:
                fixed = TemplateFamily.build(tau, beta, v)
                rows += [loss(fixed, m) for m in MASSES]
                spanning = TemplateFamily.build(tau, beta, v, h_p=H_NODES)
                rows += [loss(spanning, m, h) for m in MASSES for h in H_TARGETS]
    return rows


def main(argv=None) -> None:
    args = sys.argv[1:] if argv is None else argv
    quick = "--quick" in args
    rows = table(taus=(0.3, 3.0), betas=(0.0,)) if quick else table()
    print("| variant | τ0 | β | M_p [M_th] | H/r | own Δχ² | loss | scan tolerance |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['variant']} | {r['tau0']:g} | {r['beta']:g} | {r['mass']:g} | {r['h_p']:g} | {r['own']:.4g} | "
              f"{r['loss']:.2g} | {r['tolerance']:.2g} |")
    worst = max(rows, key=lambda r: r["loss"] / r["tolerance"])
    print(f"\n{len(rows)} points; worst loss/tolerance {worst['loss'] / worst['tolerance']:.2f} "
          f"({worst['variant']} tau0 {worst['tau0']:g} beta {worst['beta']:g} M {worst['mass']:g} h {worst['h_p']:g}); "
          f"largest loss {max(r['loss'] for r in rows):.2g}")


if __name__ == "__main__":
    main()
