"""Price of robustness of the morphology-variant limits (docs/limits.md §4d, issue 22).

On §4's planet-free C-4 demo observation (``tests/_support/limits_setup``: 1e4 visibilities,
inclination 30°, 30 azimuths, both hands, τ0 0.3, H/r 0.07, masses 0.1–3 M_th, the default
variants), ``compute_limits(cl=0.95, resolution=0, bright_radius=inf)`` per β family: ``M_lim`` of
the compromise alone, the robust ``M_lim`` (every variant must exclude) and their ratio at
r_p = 0.25, 0.35 and 0.45″, for image sensitivities 35 and 12 µJy/beam.

    PYTHONPATH=src:. python tools/price_of_robustness.py
"""

from __future__ import annotations

import logging

import numpy as np

from spiralbayes.inference.limits import compute_limits
from spiralbayes.inference.limits.robust import combined_m_lim, variant_groups
from spiralbayes.templates.variants import DEFAULT_VARIANTS, variant_grid
from tests._support import limits_setup as L

log = logging.getLogger("price_of_robustness")
RADII = (0.25, 0.35, 0.45)


def main() -> None:
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    logging.getLogger("spiralbayes").setLevel(logging.ERROR)
    templates = variant_grid(DEFAULT_VARIANTS, masses=(0.1, 0.3, 1.0, 3.0), taus=(0.3,), betas=(0.0, 10.0), **L.GRID)
    log.info("| family, noise | M_lim compromise [M_th] | M_lim robust [M_th] | price |")
    log.info("|---|---|---|---|")
    for sensitivity in (35e-6, 12e-6):
        _, _, _, result = L.scanned(sensitivity, templates=templates)
        limits = compute_limits(result, cl=0.95, resolution=0.0, bright_radius=np.inf)
        idx = [int(np.argmin(np.abs(result.r_p - r))) for r in RADII]
        for group in variant_groups(limits.families):
            members = group["members"]
            robust, _ = combined_m_lim(limits, members)
            single, _ = combined_m_lim(limits, [f for f in members if f.key.get("variant") == "compromise"])
            fmt = ", ".join
            log.info("| β = %g, %.0f µJy/beam | %s | %s | %s |", group["key"]["beta"], sensitivity * 1e6,
                     fmt(f"{single[i]:.2f}" for i in idx), fmt(f"{robust[i]:.2f}" for i in idx),
                     fmt(f"{robust[i] / single[i]:.1f}" for i in idx))


if __name__ == "__main__":
    main()
