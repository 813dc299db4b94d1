"""The paper's Table 3 from computed limits: r_p ranges where planets ≥ 3 and ≥ 1 M_th are ruled out.

Stevenson et al. (2024, Table 3) list, per Taurus disc, the orbital radii at which planets of at
least 3 M_th and at least 1 M_th would have been detected had they been there, with the
corresponding Jupiter masses. :func:`build_table3` gives the same from an
:class:`~spiralbayes.inference.limits.ExclusionLimits` as an astropy Table (and, optionally, the
minimum detectable mass from a :class:`~spiralbayes.inference.limits.recovery.CompletenessResult`):
on a scan of several families first the row that holds for every family (:mod:`.robust`), then
one row per family. The limit is only as good as the templates it assumes, so every row names
its family, the morphologies (template variants) it covers and, over several morphologies, the
price of robustness. :func:`write_table` writes any such table as ECSV and Markdown — the one
writer of ``spiralbayes limits``' ``table3`` and of the survey's table — and :func:`format_range`
is the one spelling of an r_p range (``"28-56 au (2.3-2.5 M_Jup)"``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["build_table3", "describe_family_limits", "families_text", "limits_table", "markdown_table", "price_text",
           "table_markdown", "write_table"]

from .robust import SINGLE_VARIANT, family_morphology, morphologies, overall_price
from .wording import THRESHOLDS, _span, format_range, format_ranges, guard_sentences, runs


def families_text(limits) -> str:
    """The template families a limit over all of them assumes, in a few words: the one family's label, or
    ``"all 24 families (each must rule it out): tau0 0.3, 3; beta 0, 10; h_p 0.05, 0.07, 0.1"``."""
    fams = list(limits.families)
    if len(fams) == 1:
        return fams[0].label
    values: dict[str, list] = {}
    for fam in fams:
        for key in ("tau0", "beta", "h_p"):
            if fam.key.get(key) is not None and fam.key[key] not in values.setdefault(key, []):
                values[key].append(fam.key[key])
    spelled = "; ".join(f"{k} " + ", ".join(f"{v:g}" for v in sorted(vs)) for k, vs in values.items() if vs)
    return f"all {len(fams)} families (each must rule it out): {spelled}"


def price_text(limits) -> str:
    """The price of robustness, ``M_lim(robust) / M_lim(compromise)``, over the radii with both limits:
    ``"1.2-3.4"``; ``"1"`` for a single morphology; ``"undefined"`` where they never both have one;
    ``"not measured"`` when no compromise family was scanned (a learned bank's discs)."""
    names = morphologies(limits)
    if len(names) < 2:
        return "1"
    if SINGLE_VARIANT not in names:
        return "not measured"
    price = overall_price(limits)
    ok = np.isfinite(price)
    return _span(np.min(price[ok]), np.max(price[ok])) if ok.any() else "undefined"



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


def build_table3(limits, completeness=None, *, name: str = "disc", thresholds=THRESHOLDS):
    """Table 3 as an astropy Table: the limit over every family first (when there are several), then each family.

    Columns: ``disc``, ``families`` (what the row assumes), ``morphologies`` (the template variants
    it covers), ``price_of_robustness`` (M_lim over the morphologies / M_lim of the compromise wake;
    the robust row only), ``excluded_ge{M}Mth`` per threshold M (the r_p ranges, :func:`format_range`)
    and, with ``completeness``, ``m_det`` (50 % / 90 % completeness, on its family's row).
    ``meta["caption"]`` states the confidence level, the method and the hands; ``meta["notes"]``
    the morphologies assumed with their price of robustness, and the radii flagged rather than excluded.
    """
    from astropy.table import Table

    fams = list(limits.families)
    sets = ([(families_text(limits), None)] if len(fams) > 1 else []) + [(fam.label, fam) for fam in fams]
    rows = []
    for label, fam in sets:
        row = {"disc": name, "families": label, "morphologies": ", ".join(
                   morphologies(limits) if fam is None else [family_morphology(limits, fam)]),
               "price_of_robustness": price_text(limits) if fam is None or len(fams) == 1 else ""}
        for mass in thresholds:
            row[f"excluded_ge{mass:g}Mth"] = format_ranges(limits, limits.excluded_ranges(fam, mass), mass, fam)
        if completeness is not None:
            same = fam is not None and completeness.family.label == fam.label
            row["m_det"] = _m_det_text(limits, completeness, fam) if same else "-"
        rows.append(row)
    hands = "both hands" if limits.hand == "both" else f"{limits.hand}-handed"
    caption = (f"Exclusion limits for {name}: CL = {limits.cl:.0%} one-sided, "
               f"{'excluded at every phi_p' if limits.method == 'all_phi' else 'phi_p marginalised'}, {hands}. "
               "Each row assumes the template families and morphologies named in it; masses above the bank's "
               "largest are not tested.")
    return Table(rows=rows, names=list(rows[0]), meta={"caption": caption,
                                                       "notes": [limits.morphology_note(), *_flag_notes(limits)]})


def _flag_notes(limits) -> list[str]:
    flagged = sorted({f for f in limits.flags if f})
    source = limits.provenance.get("candidate_source")
    notes = []
    if source:
        where = f"{source['r']:.3g} arcsec" + (f" ({source['r_au']:.0f} au)" if source.get("r_au") else "")
        notes.append(f"Candidate compact source at {where}, phi = {source['phi_deg']:.0f} deg, explained by "
                     f"{' or '.join(source['explained_by'])}: radii within one beam of it are flagged, not excluded.")
    if not flagged:
        return notes
    return notes + ["Flagged (not excluded): " + "; ".join(
        f"{k}: " + ", ".join(format_range(limits, lo, hi) for lo, hi in _flag_runs(limits, k)) for k in flagged)
        + f" (resolution {limits.resolution:.3f} arcsec, bright extent {limits.bright_radius:.3f} arcsec)."]


def _cell(value) -> str:
    if isinstance(value, (float, np.floating)):
        return "" if not np.isfinite(value) else f"{value:.4g}"
    return str(value)


def markdown_table(table) -> str:
    """An astropy Table as Markdown: ``meta["caption"]`` above, ``meta["notes"]`` below, numbers to 4 digits."""
    lines = [table.meta["caption"], ""] if table.meta.get("caption") else []
    lines += ["| " + " | ".join(table.colnames) + " |", "|" + "---|" * len(table.colnames)]
    lines += ["| " + " | ".join(_cell(row[c]) for c in table.colnames) + " |" for row in table]
    notes = list(table.meta.get("notes") or [])
    return "\n".join(lines + ([""] + notes if notes else [])) + "\n"


def table_markdown(limits, completeness=None, *, name: str = "disc", thresholds=THRESHOLDS) -> str:
    """:func:`build_table3` as Markdown (:func:`markdown_table`)."""
    return markdown_table(build_table3(limits, completeness, name=name, thresholds=thresholds))


def write_table(table, stem) -> list[Path]:
    """``<stem>.ecsv`` and ``<stem>.md`` of an astropy Table (:func:`markdown_table`), each written atomically."""
    from ..._provenance import atomic_path

    stem = Path(stem)
    ecsv, md = stem.with_name(stem.name + ".ecsv"), stem.with_name(stem.name + ".md")
    with atomic_path(ecsv) as tmp:
        table.write(tmp, format="ascii.ecsv", overwrite=True)
    with atomic_path(md) as tmp:
        tmp.write_text(markdown_table(table))
    return [ecsv, md]


def _flag_runs(limits, kind):
    return runs(limits.r_p, limits.flags == kind)


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


def describe_family_limits(limits, family=None) -> str:
    """Sentences: the r_p ranges where planets of at least 3 and 1 M_th are ruled out, and the radii
    not reported because of a detection (:func:`guard_sentences`)."""
    fam = limits.family(family)
    out = []
    for mass in THRESHOLDS:
        ranges = limits.excluded_ranges(fam, mass)
        where = format_ranges(limits, ranges, mass, fam, empty="no radius")
        out.append(f"Planets of >= {mass:g} M_th (template family {fam.label}) are ruled out at "
                   f"{limits.cl:.0%} confidence at {where}.")
    return " ".join(out + guard_sentences(limits))
