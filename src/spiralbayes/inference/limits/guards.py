"""Radii the limits do not report: near a detected planet and near a significant non-spiral asymmetry.

The limits assume that the scan's residual holds noise and at most the spiral being tested. Two
things in the detection verdict break that near them, and radii within one beam there are flagged
instead of excluded (:func:`~.exclusion.compute_limits`'s ``planets``):

* **a detected or candidate planet** (``"near_planet"``; a candidate compact source of the verdict,
  :mod:`~spiralbayes.inference.detection.candidate`, counts): its own spiral, fitted by a different
  template, reads as "less than the template predicts" at the neighbouring radii
  (:func:`~.robust.near_planet_mask`);
* **a significant competing asymmetry** (``"near_asymmetry"``): each of test 3's alternatives with an
  annulus (arc, lopsided ring, m = 2, eccentric ring, eccentric bright ring) whose ΔBIC against the
  axisymmetric disc exceeds :data:`ASYMMETRY_THRESHOLD`, over ``r_c ± (2 σ_r + e r_c)``. A
  vortex-dominated gap edge is such a disc, and no spiral template stands for it (docs/limits.md §4d).
"""

from __future__ import annotations

import numpy as np

from ..detection.settings import DELTA_BIC_THRESHOLD
from .robust import near_planet_mask

__all__ = ["ASYMMETRY_THRESHOLD", "asymmetry_bands", "candidate_source", "planet_radii"]

FLAG_NEAR_PLANET = "near_planet"
FLAG_NEAR_ASYMMETRY = "near_asymmetry"
ASYMMETRY_THRESHOLD = DELTA_BIC_THRESHOLD
"""ΔBIC against the axisymmetric disc above which a competing asymmetry model flags its radii."""


def _verdict_dict(planets) -> dict | None:
    """A detection verdict as a dict (a Verdict or its ``to_dict()``), or None."""
    if hasattr(planets, "test1_passed"):
        return {"test1_passed": planets.test1_passed, "r_p": planets.r_p,
                "candidate": getattr(planets, "candidate", None),
                "compact_source": getattr(planets, "compact_source", None),
                "alternatives": getattr(planets, "alternatives", None)}
    if isinstance(planets, dict) and "test1_passed" in planets:
        return planets
    return None


def planet_radii(planets) -> list[float]:
    """Radii [arcsec] of the detected or candidate planets in ``planets`` (a Verdict, its dict or radii)."""
    if planets is None:
        return []
    verdict = _verdict_dict(planets)
    if verdict is not None:
        out = [float(verdict["r_p"])] if verdict["test1_passed"] else []
        if verdict.get("candidate"):
            out.append(float(verdict["candidate"]["r_p"]))
        if verdict.get("compact_source"):
            out.append(float(verdict["compact_source"]["r"]))
        return out
    return [float(r) for r in np.atleast_1d(np.asarray(planets, dtype=float))]


def candidate_source(planets) -> dict | None:
    """The verdict's candidate compact source (``Verdict.compact_source``): place and explanations, or None."""
    source = ((_verdict_dict(planets) or {}).get("compact_source")) or None
    if source is None:
        return None
    return {k: source.get(k) for k in ("r", "r_au", "phi_deg", "flux_mJy", "origin", "explained_by")}


def asymmetry_bands(planets, threshold: float = ASYMMETRY_THRESHOLD) -> list[dict]:
    """The annuli ``r_c ± (2 σ_r + e r_c)`` [arcsec] of the verdict's competing asymmetry models with ΔBIC
    above ``threshold`` against the axisymmetric disc (``planets``: a Verdict or its dict; none otherwise);
    ``σ_r`` is a ring's ``width`` where it has one, ``e`` an eccentric model's eccentricity (else 0)."""
    verdict = _verdict_dict(planets)
    out = []
    for name, alt in ((verdict or {}).get("alternatives") or {}).items():
        params = alt.get("params") or {}
        sigma = params.get("sigma_r", params.get("width"))
        if alt.get("delta_bic", -np.inf) > threshold and "r_c" in params and sigma is not None:
            r_c = float(params["r_c"])
            half = 2 * abs(float(sigma)) + abs(float(params.get("e", 0.0))) * r_c  # an ellipse reaches e r_c out
            out.append({"model": name, "r_min": r_c - half, "r_max": r_c + half, "delta_bic": float(alt["delta_bic"])})
    return out


def guard_flags(r_p, flags, planets, beam: float):
    """``(flags, planet radii, asymmetry bands)``: ``flags`` with the radii still unflagged within
    ``beam`` [arcsec] of a planet set to ``"near_planet"`` and then of an asymmetry band to
    ``"near_asymmetry"``."""
    r_p = np.asarray(r_p, dtype=float)
    near, bands = planet_radii(planets), asymmetry_bands(planets)
    if near:
        flags = np.where(near_planet_mask(r_p, near, beam) & (flags == ""), FLAG_NEAR_PLANET, flags)
    if bands:
        inside = np.zeros(r_p.size, dtype=bool)
        for b in bands:
            inside |= (r_p >= b["r_min"] - beam) & (r_p <= b["r_max"] + beam)
        flags = np.where(inside & (flags == ""), FLAG_NEAR_ASYMMETRY, flags)
    return flags, near, bands
