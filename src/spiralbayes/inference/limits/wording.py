"""How limits are spelled: the mass thresholds of Table 3, runs of excluded radii, the one r_p range
formatter (``"28-56 au (2.3-2.5 M_Jup)"``) and the sentences on radii left out near a detection.

Shared by :mod:`.table3` (tables, per-family sentences) and :mod:`.robust` (the sentences over
every family), so that an r_p range reads the same in every output.
"""

from __future__ import annotations

import numpy as np

from .settings import TABLE3_THRESHOLDS

__all__ = ["THRESHOLDS", "format_range", "format_ranges", "guard_sentences", "runs"]

THRESHOLDS = TABLE3_THRESHOLDS
"""Table 3's mass thresholds [M_th] (:data:`~.settings.TABLE3_THRESHOLDS`)."""


def _family_list(limits, families) -> list:
    if families is None:
        return list(limits.families)
    return list(families) if isinstance(families, (list, tuple)) else [families]


def format_range(limits, lo: float, hi: float, mass: float | None = None, families=None) -> str:
    """An r_p range [arcsec] as text: ``"a-b au"`` (or arcsec without a distance), with the M_Jup that
    ``mass`` [M_th] is at its ends; over several ``families`` (default: all) the M_Jup span covers each
    family's own aspect ratio."""
    if limits.distance:
        a, b, unit = f"{lo * limits.distance:.0f}", f"{hi * limits.distance:.0f}", "au"
    else:
        a, b, unit = f"{lo:.3f}", f"{hi:.3f}", "arcsec"
    text = f"{a} {unit}" if a == b else f"{a}-{b} {unit}"
    if mass is not None and limits.distance:
        masses = np.concatenate([limits.to_mjup(mass, np.array([lo, hi]), family=f)
                                 for f in _family_list(limits, families)])
        text += f" ({_span(np.min(masses), np.max(masses))} M_Jup)"
    return text


def format_ranges(limits, ranges, mass: float | None = None, families=None, *, empty: str = "none") -> str:
    """:func:`format_range` of each ``(lo, hi)`` in ``ranges``, joined by ``"; "`` (``empty`` when none)."""
    return "; ".join(format_range(limits, lo, hi, mass, families) for lo, hi in ranges) or empty


def runs(r_p, mask) -> list[tuple[float, float]]:
    """``(first, last)`` r_p of each run of True in ``mask``."""
    out, start = [], None
    for i, flag in enumerate(mask):
        if flag and start is None:
            start = i
        if start is not None and (not flag or i == len(mask) - 1):
            end = i if flag else i - 1
            out.append((float(r_p[start]), float(r_p[end])))
            start = None
    return out


def _span(lo: float, hi: float) -> str:
    """``"a-b"`` to 2 significant digits (``"a"`` when they agree)."""
    a, b = f"{lo:.2g}", f"{hi:.2g}"
    return a if a == b else f"{a}-{b}"


def guard_sentences(limits) -> list[str]:
    """Why radii near a detected planet or a significant non-spiral asymmetry are not reported
    (``compute_limits(planets=...)``; empty without them)."""
    out = []
    prov = limits.provenance or {}
    if prov.get("near_planets"):
        out.append("Radii within one beam of the planet(s) at " + ", ".join(f"{r:.3g}" for r in prov["near_planets"])
                   + " arcsec are not reported as excluded (the planet is not in the model).")
    if prov.get("near_asymmetries"):
        out.append("Radii within one beam of significant non-spiral asymmetries ("
                   + "; ".join(f"{b['model']} at {b['r_min']:.3g}-{b['r_max']:.3g} arcsec, Delta BIC "
                               f"{b['delta_bic']:.0f}"
                               for b in prov["near_asymmetries"])
                   + ") are not reported as excluded (no template stands for them).")
    return out
