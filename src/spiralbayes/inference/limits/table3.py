"""The paper's Table 3 from computed limits: r_p ranges where planets ≥ 3 and ≥ 1 M_th are ruled out.

Stevenson et al. (2024, Table 3) list, per Taurus disc, the orbital radii at which planets of at
least 3 M_th and at least 1 M_th would have been detected had they been there, with the
corresponding Jupiter masses. :func:`limits_table` gives the same from an
:class:`~spiralbayes.inference.limits.ExclusionLimits` (and, optionally, the minimum detectable
mass from a :class:`~spiralbayes.inference.completeness.CompletenessResult`), one row per template
family — the limit is only as good as the family it assumes, so every row names it.
"""

from __future__ import annotations

import csv
import io

import numpy as np

from .settings import TABLE3_THRESHOLDS

__all__ = ["describe_family_limits", "limits_table", "runs", "table_csv", "table_markdown"]

THRESHOLDS = TABLE3_THRESHOLDS


def _range_text(limits, lo: float, hi: float, mass: float | None, family=None) -> str:
    if limits.distance:
        a, b, unit = f"{lo * limits.distance:.0f}", f"{hi * limits.distance:.0f}", "au"
    else:
        a, b, unit = f"{lo:.3f}", f"{hi:.3f}", "arcsec"
    text = f"{a} {unit}" if a == b else f"{a}-{b} {unit}"
    if mass is not None and limits.distance:
        m_lo, m_hi = (f"{m:.2g}" for m in limits.to_mjup(mass, np.array([lo, hi]), family=family))
        text += f" ({m_lo} M_Jup)" if m_lo == m_hi else f" ({m_lo}-{m_hi} M_Jup)"
    return text


def limits_table(limits, completeness=None, *, name: str = "disc", thresholds=THRESHOLDS) -> list[dict]:
    """One dict per (family, mass threshold, r_p range): the long form of Table 3 (also the CSV rows).

    Keys: disc, family, hands, cl, method, mass_mth, r_min_arcsec, r_max_arcsec, r_min_au, r_max_au,
    m_min_mjup, m_max_mjup (the M_Jup of ``mass_mth`` at the range's ends). A threshold without any
    excluded range gives one row with empty radii. With ``completeness`` for that family, rows with
    ``mass_mth = "M_det(50%)"`` give the minimum detectable mass at each injection radius.
    """
    rows = []
    for fam in limits.families:
        base = {"disc": name, "family": fam.label, "hands": "both" if limits.hand == "both" else limits.hand,
                "cl": limits.cl, "method": limits.method}
        for mass in thresholds:
            ranges = limits.excluded_ranges(fam, mass)
            for lo, hi in ranges or [(np.nan, np.nan)]:
                row = {**base, "mass_mth": mass, "r_min_arcsec": lo, "r_max_arcsec": hi}
                row.update(_physical(limits, mass, lo, hi, fam))
                rows.append(row)
        if completeness is not None and completeness.family.label == fam.label:
            for level in (0.5, 0.9):
                m_det = completeness.m_det(level)
                for r, m in zip(completeness.r_p, m_det):
                    row = {**base, "mass_mth": f"M_det({level:.0%})", "r_min_arcsec": r, "r_max_arcsec": r,
                           "m_det_mth": m}
                    row.update(_physical(limits, m, r, r, fam))
                    rows.append(row)
    return rows


def _physical(limits, mass, lo, hi, family=None) -> dict:
    out = {"r_min_au": np.nan, "r_max_au": np.nan, "m_min_mjup": np.nan, "m_max_mjup": np.nan}
    if limits.distance and np.isfinite(lo):
        out.update(r_min_au=lo * limits.distance, r_max_au=hi * limits.distance)
        if np.isfinite(mass):
            m_lo, m_hi = limits.to_mjup(mass, np.array([lo, hi]), family=family)
            out.update(m_min_mjup=float(m_lo), m_max_mjup=float(m_hi))
    return out


def table_markdown(limits, completeness=None, *, name: str = "disc", thresholds=THRESHOLDS) -> str:
    """Table 3 as Markdown: one line per family, the excluded r_p ranges (and M_Jup) per threshold."""
    hands = "both hands" if limits.hand == "both" else f"{limits.hand}-handed"
    head = [f"Exclusion limits for {name}: CL = {limits.cl:.0%} one-sided, "
            f"{'excluded at every phi_p' if limits.method == 'all_phi' else 'phi_p marginalised'}, {hands}. "
            "Each row assumes the template family named in it; masses above the bank's largest are not tested.",
            ""]
    cols = ["disc", "template family"] + [f"ruled out for M >= {m:g} M_th" for m in thresholds]
    with_det = completeness is not None
    if with_det:
        cols.append("M_det (50 % / 90 % completeness)")
    head += ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for fam in limits.families:
        cells = [name, fam.label]
        for mass in thresholds:
            ranges = limits.excluded_ranges(fam, mass)
            cells.append("; ".join(_range_text(limits, lo, hi, mass, fam) for lo, hi in ranges) or "none")
        if with_det:
            cells.append(_m_det_text(limits, completeness, fam) if completeness.family.label == fam.label else "-")
        head.append("| " + " | ".join(cells) + " |")
    flagged = [(f, r) for f, r in zip(limits.flags, limits.r_p) if f]
    if flagged:
        kinds = sorted({f for f, _ in flagged})
        head += ["", "Flagged (not excluded): " + "; ".join(
            f"{k}: " + ", ".join(_range_text(limits, lo, hi, None) for lo, hi in _flag_runs(limits, k))
            for k in kinds) + f" (resolution {limits.resolution:.3f} arcsec, bright extent "
            f"{limits.bright_radius:.3f} arcsec)."]
    return "\n".join(head) + "\n"


def _flag_runs(limits, kind):
    return runs(limits.r_p, limits.flags == kind)


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


def _m_det_text(limits, completeness, family=None) -> str:
    parts = []
    for level in (0.5, 0.9):
        m = completeness.m_det(level)
        ok = np.isfinite(m)
        if not ok.any():
            parts.append("none")
            continue
        text = _span(np.nanmin(m), np.nanmax(m)) + " M_th"
        if limits.distance:
            mj = limits.to_mjup(m[ok], completeness.r_p[ok], family=family)
            text += f" ({_span(np.min(mj), np.max(mj))} M_Jup)"
        parts.append(text)
    return " / ".join(parts)


def _span(lo: float, hi: float) -> str:
    a, b = f"{lo:.2g}", f"{hi:.2g}"
    return a if a == b else f"{a}-{b}"


def table_csv(limits, completeness=None, *, name: str = "disc", thresholds=THRESHOLDS) -> str:
    """The rows of :func:`limits_table` as CSV text."""
    rows = limits_table(limits, completeness, name=name, thresholds=thresholds)
    keys = []
    for row in rows:
        keys += [k for k in row if k not in keys]
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=keys, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: ("" if isinstance(v, float) and not np.isfinite(v) else v) for k, v in row.items()})
    return buffer.getvalue()


def describe_family_limits(limits, family=None) -> str:
    """Sentences: the r_p ranges where planets of at least 3 and 1 M_th are ruled out, and the radii
    not reported because of a detection (:func:`guard_sentences`)."""
    fam = limits.family(family)
    out = []
    for mass in THRESHOLDS:
        ranges = limits.excluded_ranges(fam, mass)
        where = "; ".join(_range_text(limits, lo, hi, mass, fam) for lo, hi in ranges) or "no radius"
        out.append(f"Planets of >= {mass:g} M_th (template family {fam.label}) are ruled out at "
                   f"{limits.cl:.0%} confidence at {where}.")
    return " ".join(out + guard_sentences(limits))


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
                   + "; ".join(f"{b['model']} at {b['r_min']:.3g}-{b['r_max']:.3g} arcsec, Delta BIC {b['delta_bic']:.0f}"
                               for b in prov["near_asymmetries"])
                   + ") are not reported as excluded (no template stands for them).")
    return out
