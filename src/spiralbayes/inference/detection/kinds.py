"""Where each kind of template puts the planet, in a bank that mixes the generator and simulated maps.

A simulated map holds its run's aspect ratio, and the winding of its arms moves the peak of its
Δχ² map when the disc's differs: every H/r 0.07 map of a 1 M_th planet places a planted H/r 0.10
planet two radius steps out and 8–12° off, while the generator's templates, which span H/r, place
it right (docs/verdict.md, "What the six still lost would need"). When the best template of each
kind peaks in a different place, the verdict reports both instead of the winner's alone.
"""

from __future__ import annotations

import numpy as np

from ...templates.template import template_kind
from ..scan.statistics import bic_threshold
from .settings import DELTA_BIC_THRESHOLD

__all__ = ["best_by_kind", "kind_position_sentence"]

COMPARABLE_FRACTION = 0.5
"""The other kind's best must reach this fraction of the verdict's ΔBIC to be named: measured on the
library plantings of docs/verdict.md with the maps, it reached 0.65–0.91 where both kinds stood for
the planet at different places, and 0.09–0.32 where the other kind's templates simply did not fit."""
KIND_NOUNS = {"generator": "generator template", "simulation": "simulated map"}
KIND_H_P = {"generator": "its bank spans H/r", "simulation": "one H/r, its run's"}


def best_by_kind(result, amplitude=None, threshold: float = DELTA_BIC_THRESHOLD) -> dict | None:
    """The best template of each kind (:func:`~spiralbayes.templates.template.template_kind`) in the
    scan, ``kind -> {template, r_p [arcsec], phi_p_deg, delta_bic, test1, steps_from_best}``:
    ``test1`` whether its ΔBIC exceeds ``threshold``, ``steps_from_best`` the radius and (cyclic)
    azimuth grid steps from the scan's best instance. None when the scan holds one kind only."""
    kinds = np.array([template_kind(meta) for meta in result.templates])
    if len(set(kinds)) < 2:
        return None
    # ΔBIC at every instance: Δχ² less the scan's k ln N; templates not scanned never win
    bic = np.nan_to_num(result.delta_chi2(amplitude) - bic_threshold(result.n_data, result.n_params(amplitude)),
                        nan=-np.inf)
    best = np.unravel_index(int(np.argmax(bic)), bic.shape)
    n_phi = bic.shape[2]
    out = {}
    for kind in sorted(set(kinds)):
        masked = np.where((kinds == kind)[:, None, None], bic, -np.inf)
        if not np.isfinite(masked.max()):
            continue
        t, i, j = np.unravel_index(int(np.argmax(masked)), masked.shape)
        d_phi = abs(int(j) - int(best[2])) % n_phi
        out[str(kind)] = {"template": result.templates[t]["name"], "r_p": float(result.r_p[i]),
                          "phi_p_deg": float(np.degrees(result.phi_p[j])), "delta_bic": float(masked[t, i, j]),
                          "test1": bool(masked[t, i, j] > threshold),
                          "steps_from_best": [abs(int(i) - int(best[1])), min(d_phi, n_phi - d_phi)]}
    return out if len(out) > 1 else None


def kind_position_sentence(verdict) -> str:
    """A sentence when the best template of the other kind than the verdict's passes test 1, reaches
    :data:`COMPARABLE_FRACTION` of the verdict's ΔBIC and peaks more than one grid step from the
    verdict's position; else ``""``."""
    kinds = verdict.best_by_kind
    if not kinds or not verdict.test1_passed:
        return ""
    mine = next((k for k, v in kinds.items() if v["template"] == verdict.template), None)
    for kind, other in kinds.items():
        if (mine is None or kind == mine or not other["test1"] or max(other["steps_from_best"]) <= 1
                or other["delta_bic"] < COMPARABLE_FRACTION * kinds[mine]["delta_bic"]):
            continue
        d_rp, d_phi = other["steps_from_best"]
        where = verdict._where(other["r_p"], other["phi_p_deg"])
        return (f" The best {KIND_NOUNS[kind]} ({KIND_H_P[kind]}), {other['template']}, peaks elsewhere: at {where} "
                f"(Delta BIC = {other['delta_bic']:.1f}), {d_rp} radius and {d_phi} azimuth steps from the best "
                f"{KIND_NOUNS[mine]}. A map's fixed aspect ratio moves its peak when the disc's "
                "differs, so the planet's position is uncertain between the two.")
    return ""
