"""Price of robustness of the morphology-variant limits (docs/limits.md §4d, issue 22).

On §4's planet-free C-4 demo observation (``tests/_support/limits_setup``: 1e4 visibilities,
inclination 30°, 30 azimuths, both hands, τ0 0.3, H/r 0.07, masses 0.1–3 M_th, the default
variants), ``compute_limits(cl=0.95, resolution=0, bright_radius=inf)`` per β family: ``M_lim`` of
the compromise alone, the robust ``M_lim`` (every variant must exclude) and their ratio at
r_p = 0.25, 0.35 and 0.45″, for image sensitivities 35 and 12 µJy/beam.

With ``--learned`` the robust set is the learned bank's instead (``[templates] bank = "learned"``'s
default discs: slopes 0.5, 1, 1.5 × α 2e-4, 1e-3, 1e-2 at 200 orbits, β 0, the same masses, τ0 and
H/r; the model fitted to the repository's training runs), scanned beside the compromise's β = 0
family, whose limit the price divides by.

    PYTHONPATH=src:. python tools/price_of_robustness.py [--learned]
"""

from __future__ import annotations

import logging
import sys

import numpy as np

from spiralbayes.inference.limits import compute_limits
from spiralbayes.inference.limits.robust import combined_m_lim, variant_groups
from spiralbayes.templates.variants import DEFAULT_VARIANTS, variant_grid
from tests._support import limits_setup as L

log = logging.getLogger("price_of_robustness")
RADII = (0.25, 0.35, 0.45)


MASSES = (0.1, 0.3, 1.0, 3.0)


def learned_templates() -> list:
    """The learned bank's default discs at the set-up's masses, τ0 0.3 and H/r 0.07."""
    from spiralbayes.templates.learned import (DEFAULT_ALPHAS, DEFAULT_ORBITS, DEFAULT_SLOPES, LearnedTemplateModel,
                                               learned_bank, reference_files)

    model = LearnedTemplateModel.from_references(reference_files())
    return list(learned_bank(model, MASSES, 0.07, DEFAULT_SLOPES, DEFAULT_ALPHAS, DEFAULT_ORBITS, 0.3))


def scanned_limits(templates, sensitivity: float):
    """The set-up's limits with ``templates`` at one image sensitivity [Jy/beam], and the indices of :data:`RADII`."""
    _, _, _, result = L.scanned(sensitivity, templates=templates)
    limits = compute_limits(result, cl=0.95, resolution=0.0, bright_radius=np.inf)
    return limits, [int(np.argmin(np.abs(result.r_p - r))) for r in RADII]


def cells(limits, robust_families, single_families, idx) -> str:
    """``M_lim`` of the single and the robust sets at the radii ``idx``, and their ratio (three table cells)."""
    robust, _ = combined_m_lim(limits, robust_families)
    single, _ = combined_m_lim(limits, single_families)
    fmt = ", ".join
    return (f"{fmt(f'{single[i]:.2f}' for i in idx)} | {fmt(f'{robust[i]:.2f}' for i in idx)} | "
            f"{fmt(f'{robust[i] / single[i]:.1f}' for i in idx)}")


def learned_price() -> None:
    templates = variant_grid(("compromise",), masses=MASSES, taus=(0.3,), betas=(0.0,), **L.GRID)
    templates += learned_templates()
    log.info("| noise | M_lim compromise [M_th] | M_lim robust over the learned discs [M_th] | price |")
    log.info("|---|---|---|---|")
    for sensitivity in (35e-6, 12e-6):
        limits, idx = scanned_limits(templates, sensitivity)
        learned = [f for f in limits.families if str(f.key.get("variant", "")).startswith("learned")]
        single = [f for f in limits.families if f.key.get("variant") == "compromise"]
        log.info("| %.0f µJy/beam | %s |", sensitivity * 1e6, cells(limits, learned, single, idx))


def main(argv=None) -> None:
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    logging.getLogger("spiralbayes").setLevel(logging.ERROR)
    if "--learned" in (sys.argv[1:] if argv is None else argv):
        learned_price()
        return
    templates = variant_grid(DEFAULT_VARIANTS, masses=MASSES, taus=(0.3,), betas=(0.0, 10.0), **L.GRID)
    log.info("| family, noise | M_lim compromise [M_th] | M_lim robust [M_th] | price |")
    log.info("|---|---|---|---|")
    for sensitivity in (35e-6, 12e-6):
        limits, idx = scanned_limits(templates, sensitivity)
        for group in variant_groups(limits.families):
            members = group["members"]
            single = [f for f in members if f.key.get("variant") == "compromise"]
            log.info("| β = %g, %.0f µJy/beam | %s |", group["key"]["beta"], sensitivity * 1e6,
                     cells(limits, members, single, idx))


if __name__ == "__main__":
    main()
