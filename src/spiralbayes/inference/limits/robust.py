"""Robust exclusion: limits that hold over several template families or morphology variants.

No template is the true spiral (docs/limits.md §4c), so a planet is reported as ruled out only
when **every** member of a set of families rules it out (each member already needs both hands
and every ``phi_p``: :mod:`.limits`). Two sets are used:

* **over all families** — what :meth:`.ExclusionLimits.summary`, :meth:`~.ExclusionLimits.excluded`
  and the mass–radius plot give when no ``family=`` is chosen: the mass is excluded at ``r_p``
  only when every scanned family (every ``tau0``, ``beta``, ``h_p`` and morphology variant) that
  has that mass excludes it. In M_th, ``M_lim(robust) = max_f M_lim(f)`` (no limit if one family
  has none); in M_Jup each family uses its own ``h_p`` before the maximum is taken.
* **over morphology variants** (:func:`variant_groups`) — families equal but for their
  ``variant`` (:mod:`spiralbayes.templates.variants`) form one group, whose robust limit is the
  maximum over its variants; the *price of robustness* is ``M_lim(robust) / M_lim(single)``
  with "single" the bank's compromise variant.

**Near a planet** (:func:`near_planet_mask`): radii within one beam of a detected or candidate
planet are not excluded unless the limit was computed with that planet in the model — the
planet's own spiral, fitted by a different template, reads as "less than the template predicts"
at the neighbouring radii.
"""

from __future__ import annotations

import numpy as np

from ...exceptions import InputError

__all__ = ["SINGLE_VARIANT", "combined_m_lim", "combined_m_lim_mjup", "describe_over_families",
           "near_planet_mask", "price_of_robustness", "variant_groups"]

SINGLE_VARIANT = "compromise"
"""The variant the price of robustness is measured against (the wake generator as fitted to the reference maps)."""

_LIMITED = ("limit", "below_bank")


def _family_list(limits, families=None) -> list:
    return list(limits.families) if families is None else [limits.family(f) for f in families]


def combined_m_lim(limits, families=None) -> tuple[np.ndarray, np.ndarray]:
    """``(M_lim, status)`` [M_th] per r_p over ``families`` (default all): the largest member limit.

    Status ``"limit"`` where every member has a limit (``"below_bank"`` when every member is
    below its bank), ``"none"`` where one has none, ``"flagged"`` at flagged radii.
    """
    fams = _family_list(limits, families)
    rows = np.array([limits.m_lim[limits.families.index(f)] for f in fams])
    stat = np.array([limits.m_lim_status[limits.families.index(f)] for f in fams])
    limited = np.isin(stat, _LIMITED)
    every = np.all(limited, axis=0)
    m_lim = np.where(every, np.max(np.where(limited, rows, -np.inf), axis=0), np.nan)
    status = np.where(every, np.where(np.all(stat == "below_bank", axis=0), "below_bank", "limit"), "none")
    status = np.where(limits.flags != "", "flagged", status)
    return np.where(status == "flagged", np.nan, m_lim), status.astype(str)


def combined_m_lim_mjup(limits, families=None) -> np.ndarray:
    """Robust ``M_lim(r_p)`` [M_Jup]: each member's limit with its own ``h_p``, the largest kept."""
    fams = _family_list(limits, families)
    _, status = combined_m_lim(limits, fams)
    rows = np.array([limits.m_lim_mjup(f) for f in fams])
    return np.where(np.isin(status, _LIMITED), np.nanmax(np.where(np.isfinite(rows), rows, -np.inf), axis=0), np.nan)


def combined_excluded(limits, mass: float | None = None, families=None) -> np.ndarray:
    """Excluded in every member family that has ``mass`` (default: every mass of the union)."""
    fams = _family_list(limits, families)
    masses = sorted({m for f in fams for m in f.masses}) if mass is None else [float(mass)]
    rows = []
    for m in masses:
        having = [f for f in fams if any(np.isclose(m, fm, rtol=1e-6) for fm in f.masses)]
        if not having:
            raise InputError(f"mass {m} is in none of the families ({'; '.join(f.label for f in fams)})")
        rows.append(np.all([limits.excluded(f, m) for f in having], axis=0))
    out = np.array(rows)
    return out[0] if mass is not None else out


def variant_groups(families) -> list[dict]:
    """Families equal but for their morphology ``variant``: ``{"key", "label", "members"}`` per group
    (``members``: the Family objects, one per variant), in the order of first appearance."""
    groups: dict = {}
    for fam in families:
        key = tuple((k, fam.key.get(k)) for k in ("tau0", "beta", "h_p"))
        groups.setdefault(key, []).append(fam)
    out = []
    for key, members in groups.items():
        label = ", ".join(f"{k}={v:g}" for k, v in key if v is not None)
        out.append({"key": dict(key), "label": label, "members": members})
    return out


def price_of_robustness(limits, group: dict, single: str = SINGLE_VARIANT) -> np.ndarray:
    """``M_lim(robust) / M_lim(single variant)`` per r_p of a :func:`variant_groups` group (NaN
    where either has no limit; 1 when the group has one variant)."""
    members = group["members"]
    chosen = [f for f in members if f.key.get("variant") == single] or members[:1]
    robust, _ = combined_m_lim(limits, members)
    alone, _ = combined_m_lim(limits, chosen)
    with np.errstate(invalid="ignore", divide="ignore"):
        return robust / alone


def near_planet_mask(r_p, planets, beam: float) -> np.ndarray:
    """True at radii within one ``beam`` [arcsec] (FWHM) of any planet radius in ``planets`` [arcsec]."""
    r_p = np.asarray(r_p, dtype=float)
    planets = np.atleast_1d(np.asarray(planets if planets is not None else [], dtype=float))
    if planets.size == 0:
        return np.zeros(r_p.size, dtype=bool)
    if not np.isfinite(beam) or beam <= 0:
        raise InputError(f"planet_beam must be a positive beam FWHM [arcsec], got {beam!r}: give resolution= or vis=")
    return np.any(np.abs(r_p[:, None] - planets[None, :]) <= beam * (1 + 1e-9), axis=1)


def describe_over_families(limits) -> str:
    """Sentences for :meth:`.ExclusionLimits.summary` without ``family=``: the robust limit over every
    family, the set named, and the price of robustness where variants exist."""
    from .wording import THRESHOLDS, format_ranges, guard_sentences, runs

    fams = list(limits.families)
    m_lim, status = combined_m_lim(limits, fams)
    labels = "; ".join(f.label for f in fams)
    out = [f"Over all {len(fams)} template families ({labels}), a planet counts as ruled out only where "
           "every family rules it out."]
    for mass in THRESHOLDS:
        ok = np.isin(status, _LIMITED) & (np.nan_to_num(m_lim, nan=np.inf) <= mass * (1 + 1e-9))
        where = format_ranges(limits, runs(limits.r_p, ok), mass, empty="no radius")
        out.append(f"Planets of >= {mass:g} M_th are ruled out at {limits.cl:.0%} confidence at {where}.")
    for group in variant_groups(fams):
        if len(group["members"]) < 2:
            continue
        price = price_of_robustness(limits, group)
        ok = np.isfinite(price)
        variants = ", ".join(str(f.key.get("variant")) for f in group["members"])
        text = (f"{np.nanmin(price[ok]):.2g}-{np.nanmax(price[ok]):.2g}" if ok.any() else "undefined (no limit)")
        out.append(f"Family {group['label']}: morphology variants {{{variants}}}; price of robustness "
                   f"M_lim(robust)/M_lim({SINGLE_VARIANT}) = {text}.")
    out.extend(guard_sentences(limits))
    return " ".join(out)
