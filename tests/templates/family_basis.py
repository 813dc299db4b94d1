"""Can a few basis maps stand for a template family's mass nodes? (a measurement, not a test)

A continuous-mass posterior needs the spiral's visibilities at any mass on every likelihood call.
The family (:class:`spiralbayes.templates.TemplateFamily`) is a linear combination of its 49 node
maps, so one cheap option would be a low-rank basis of them: tables for k basis maps instead of 49.
This measures the basis taken in *image* space: the SVD of the node maps ``δ(x, φ)`` weighted by the
area element ``sqrt(x)`` (``--profile``: and by the disc profile at the planet's radius). The
measure is :mod:`.family_accuracy`'s: the χ² lost on the fiducial observation when the family's
template at 0.2, 0.5 and 2 M_th is replaced by its projection on the first k basis maps, over the
scan's tolerance, against the generator's exact template.

    PYTHONPATH=src python -m tests.templates.family_basis [--profile]
"""

from __future__ import annotations

import sys
from dataclasses import replace

import numpy as np

from tests.templates.family_accuracy import DISTANCE, R_P_AU, _dv, _observation

RANKS = (4, 6, 8, 10, 12, 16, 49)
CASES = (("compromise", 3.0), ("compromise", 0.3), ("hydro", 0.3))
BETA = 10.0


def losses(variant: str, tau0: float, profile: bool = False) -> list[dict]:
    """Per mass: the exact template's own Δχ², the tolerance and the loss/tolerance at each rank."""
    from spiralbayes.inference.scan.accuracy import TOLERANCE
    from spiralbayes.simulate import DiscModel
    from spiralbayes.templates.family import TemplateFamily
    from spiralbayes.templates.variants import variant_template

    cov, _, w = _observation()
    family = TemplateFamily.build(tau0, BETA, variant)
    nodes = [family.node(j) for j in range(family.masses.size)]
    x = nodes[0].x
    weight = np.sqrt(x)
    if profile:
        brightness = DiscModel(distance=DISTANCE, r_ref=R_P_AU, tau_ref=tau0).profile(cov.wavelength)
        weight = weight * np.asarray(brightness(x * R_P_AU / DISTANCE), float)
    weight = weight[:, None]  # rows of delta are radii x
    basis = np.linalg.svd(np.array([(np.asarray(n.delta, float) * weight).ravel() for n in nodes]),
                          full_matrices=False)[2]
    rows = []
    for mass in (0.2, 0.5, 2.0):
        exact = _dv(variant_template(mass, tau0, BETA, "R", variant, h_p=0.07), tau0)
        own = float(np.sum(w * np.abs(exact) ** 2))
        tolerance = TOLERANCE[0] + TOLERANCE[1] * own
        template = family.at(mass)
        vec = (np.asarray(template.delta, float) * weight).ravel()
        ratio = {}
        for k in RANKS:
            projected = (basis[:k].T @ (basis[:k] @ vec)).reshape(template.delta.shape) / weight
            approx = _dv(replace(template, delta=projected), tau0)
            ratio[k] = float(np.sum(w * np.abs(exact - approx) ** 2)) / tolerance
        rows.append({"variant": variant, "tau0": tau0, "mass": mass, "own": own, "tolerance": tolerance,
                     "loss_over_tolerance": ratio})
    return rows


def main(argv=None) -> None:
    args = sys.argv[1:] if argv is None else argv
    profile = "--profile" in args
    print("| variant | τ0 | M_p [M_th] | own Δχ² | " + " | ".join(f"k = {k}" for k in RANKS) + " |")
    print("|---|---|---|---|" + "---|" * len(RANKS))
    for variant, tau0 in CASES:
        for r in losses(variant, tau0, profile):
            cells = " | ".join(f"{r['loss_over_tolerance'][k]:.2f}" for k in RANKS)
            print(f"| {variant} | {tau0:g} | {r['mass']:g} | {r['own']:.0f} | {cells} |", flush=True)


if __name__ == "__main__":
    main()
