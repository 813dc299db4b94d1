"""Robust exclusion: limits that hold over several template families or morphology variants.

No template is the true spiral (docs/limits.md §4c), so a planet is reported as ruled out only
when **every** member of a set of families rules it out (each member already needs both hands
and every ``phi_p``: :mod:`~spiralbayes.inference.limits`). Two sets are used:

* **over all families** — what :meth:`.ExclusionLimits.summary`, :meth:`~.ExclusionLimits.excluded`
  and the mass–radius plot give when no ``family=`` is chosen: the mass is excluded at ``r_p``
  only when every scanned family (every ``tau0``, ``beta``, ``h_p`` and morphology variant) that
  has that mass excludes it. In M_th, ``M_lim(robust) = max_f M_lim(f)`` (no limit if one family
  has none); in M_Jup each family uses its own ``h_p`` before the maximum is taken.
* **over morphology variants** (:func:`variant_groups`) — families equal but for their
  ``variant`` (:mod:`spiralbayes.templates.variants`) form one group, whose robust limit is the
  maximum over its variants; the *price of robustness* is ``M_lim(robust) / M_lim(single)``
  with "single" the bank's compromise variant.

**Which morphologies a limit assumes** (:func:`morphologies`, :func:`morphology_note`): the
variant names of the scanned families (templates without one are the compromise when the built-in
generator made them, names ``wake_…``, else ``"unlabelled"``). Over every family the price of
robustness is ``M_lim(robust over every family) / M_lim(robust over the compromise families)``
per r_p (:func:`overall_price`; NaN, "not measured", when several morphologies are scanned and none
is the compromise, as with a learned bank's discs); every limits output names the set and this
price, or says that the limit assumes a single morphology and is not robust to the spiral's shape.

**Near a planet** (:func:`near_planet_mask`): radii within one beam of a detected or candidate
planet are not excluded unless the limit was computed with that planet in the model — the
planet's own spiral, fitted by a different template, reads as "less than the template predicts"
at the neighbouring radii.
"""

from __future__ import annotations

import numpy as np

from ...exceptions import InputError

__all__ = ["H_P_SENSITIVE_TAU0", "SINGLE_VARIANT", "UNLABELLED", "aspect_ratio_note", "combined_m_lim",
           "combined_m_lim_mjup", "describe_over_families", "family_morphology", "morphologies", "morphology_note",
           "near_planet_mask", "overall_price", "price_of_robustness", "variant_groups"]

SINGLE_VARIANT = "compromise"
"""The variant the price of robustness is measured against (the wake generator as fitted to the reference maps)."""

UNLABELLED = "unlabelled"
"""The morphology of templates that carry no variant and were not made by the built-in generator."""
GENERATOR_PREFIX = "wake_"
"""Name prefix of the built-in generator's templates (the compromise morphology)."""
H_P_SENSITIVE_TAU0 = 1.0
"""Above this τ0 the limits depend on the aspect ratio H/r: planted spirals at H/r between the
families' were wrongly excluded at τ0 3 (up to 44 % of realisations for independent wakeflow maps,
docs/limits.md §4d), not at τ0 0.3 or 1 (at most 7 %)."""
_LIMITED = ("limit", "below_bank")
_LISTED_FAMILIES = 6  # more families than this are described by their parameter values, not one label each


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


def family_morphology(limits, family) -> str:
    """The morphology a family assumes: its ``variant``, else :data:`SINGLE_VARIANT` when every member
    was made by the built-in generator (names ``wake_…``), else :data:`UNLABELLED`."""
    variant = family.key.get("variant")
    if variant is not None:
        return str(variant)
    names = [str(limits.templates[i].get("name", "")) for row in family.members.values() for i in row if i is not None]
    return SINGLE_VARIANT if names and all(n.startswith(GENERATOR_PREFIX) for n in names) else UNLABELLED


def morphologies(limits) -> list[str]:
    """The morphologies the limits assume: one name per variant among the families, sorted."""
    return sorted({family_morphology(limits, f) for f in limits.families})


def overall_price(limits, family=None, single: str = SINGLE_VARIANT) -> np.ndarray:
    """Price of robustness per r_p: ``M_lim(robust) / M_lim(single)`` over every family (``family=None``)
    or over the variants of ``family``'s group (:func:`variant_groups`). NaN where either has no limit;
    1 where it has one and the families hold a single morphology."""
    fams = list(limits.families)
    if family is not None:
        fam = limits.family(family)
        fams = next(g["members"] for g in variant_groups(fams) if fam in g["members"])
    alone = [f for f in fams if family_morphology(limits, f) == single]
    robust, _ = combined_m_lim(limits, fams)
    if len({family_morphology(limits, f) for f in fams}) < 2:
        alone = fams
    elif not alone:  # several morphologies and none is the reference one (a learned bank's discs): unmeasured
        return np.full(robust.shape, np.nan)
    base, _ = combined_m_lim(limits, alone)
    with np.errstate(invalid="ignore", divide="ignore"):
        return robust / base


def morphology_note(limits, family=None) -> str:
    """One sentence: the morphologies the limits (of ``family``, or over every family) assume and,
    when several, the price of robustness (median and range over the radii with a limit)."""
    every = morphologies(limits)
    names = [family_morphology(limits, limits.family(family))] if family is not None else every
    if len(names) == 1 and len(every) > 1:
        return (f"This family assumes the {names[0]} morphology only; the limits robust to the spiral's shape are "
                f"those over every morphology ({', '.join(every)}).")
    if len(names) == 1:
        shape = "one unlabelled template morphology" if names[0] == UNLABELLED else f"the {names[0]} morphology"
        return f"These limits assume {shape} only; not robust to the spiral's shape."
    price = overall_price(limits)
    ok = np.isfinite(price)
    if SINGLE_VARIANT not in names:
        return (f"These limits hold for every morphology ({_short_list(names)}): a mass counts as ruled out only "
                f"where every morphology rules it out; no {SINGLE_VARIANT} family was scanned, so the price of "
                "robustness is not measured.")
    text = (f"median {np.median(price[ok]):.2g} (range {np.min(price[ok]):.2g}-{np.max(price[ok]):.2g})"
            if ok.any() else "undefined (no radius where both have a limit)")
    return (f"These limits hold for every morphology ({', '.join(names)}): a mass counts as ruled out only where "
            f"every morphology rules it out; price of robustness M_lim(robust)/M_lim({SINGLE_VARIANT}) {text}.")


def _short_list(names, at_most: int = 4) -> str:
    if len(names) <= at_most:
        return ", ".join(names)
    return f"{', '.join(names[:at_most])} and {len(names) - at_most} more"


def near_planet_mask(r_p, planets, beam: float) -> np.ndarray:
    """True at radii within one ``beam`` [arcsec] (FWHM) of any planet radius in ``planets`` [arcsec]."""
    r_p = np.asarray(r_p, dtype=float)
    planets = np.atleast_1d(np.asarray(planets if planets is not None else [], dtype=float))
    if planets.size == 0:
        return np.zeros(r_p.size, dtype=bool)
    if not np.isfinite(beam) or beam <= 0:
        raise InputError(f"planet_beam must be a positive beam FWHM [arcsec], got {beam!r}: give resolution= or vis=")
    return np.any(np.abs(r_p[:, None] - planets[None, :]) <= beam * (1 + 1e-9), axis=1)


def aspect_ratio_note(limits) -> str:
    """A sentence when a family's τ0 exceeds :data:`H_P_SENSITIVE_TAU0`: the limits then hold at the
    families' aspect ratios only (empty otherwise)."""
    fams = [f for f in limits.families if f.key.get("tau0") is not None and f.key["tau0"] > H_P_SENSITIVE_TAU0]
    h_ps = sorted({float(f.key["h_p"]) for f in fams if f.key.get("h_p") is not None})
    if not h_ps:
        return ""
    return (f"At tau0 > {H_P_SENSITIVE_TAU0:g} these limits hold for the templates' aspect ratios "
            f"(H/r = {', '.join(f'{h:g}' for h in h_ps)}) only: a planet between them can be wrongly excluded "
            "(docs/limits.md 4d).")


def describe_over_families(limits) -> str:
    """Sentences for :meth:`.ExclusionLimits.summary` without ``family=``: the robust limit over every
    family, the set named, and the price of robustness where variants exist."""
    from .wording import THRESHOLDS, format_ranges, guard_sentences, runs

    fams = list(limits.families)
    m_lim, status = combined_m_lim(limits, fams)
    out = [f"Over all {len(fams)} template families ({_family_set(limits)}), a planet counts as ruled out only "
           "where every family rules it out.", morphology_note(limits)]
    if note := aspect_ratio_note(limits):
        out.append(note)
    for mass in THRESHOLDS:
        ok = np.isin(status, _LIMITED) & (np.nan_to_num(m_lim, nan=np.inf) <= mass * (1 + 1e-9))
        where = format_ranges(limits, runs(limits.r_p, ok), mass, empty="no radius")
        out.append(f"Planets of >= {mass:g} M_th are ruled out at {limits.cl:.0%} confidence at {where}.")
    groups = [g for g in variant_groups(fams) if len(g["members"]) > 1]
    for group in groups if len(fams) <= _LISTED_FAMILIES else []:  # else the overall price above says it
        price = price_of_robustness(limits, group)
        ok = np.isfinite(price)
        variants = ", ".join(str(f.key.get("variant")) for f in group["members"])
        text = (f"{np.nanmin(price[ok]):.2g}-{np.nanmax(price[ok]):.2g}" if ok.any() else "undefined (no limit)")
        out.append(f"Family {group['label']}: morphology variants {{{variants}}}; price of robustness "
                   f"M_lim(robust)/M_lim({SINGLE_VARIANT}) = {text}.")
    out.extend(guard_sentences(limits))
    return " ".join(out)


def _family_set(limits) -> str:
    """The families' labels, or for many families the values each parameter takes."""
    fams = list(limits.families)
    if len(fams) <= _LISTED_FAMILIES:
        return "; ".join(f.label for f in fams)
    parts = []
    for key in ("tau0", "beta", "h_p"):
        values = sorted({f.key[key] for f in fams if f.key.get(key) is not None})
        if values:
            parts.append(f"{key} {', '.join(f'{v:g}' for v in values)}")
    parts.append(f"morphologies {', '.join(morphologies(limits))}")
    return "; ".join(parts)
