"""Exclusion limits, completeness and the mass–radius plane (Stevenson et al. 2024, Fig. 14).

Every function returns a Matplotlib ``Figure``. Radii are in au when the result carries a
distance, else in arcsec; flagged radii (unresolved, beyond the disc's bright extent) are greyed.
The mass–radius plot names the spiral morphologies its limit assumes and the price of robustness
(:meth:`~spiralbayes.inference.limits.ExclusionLimits.morphology_note`).
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from ..exceptions import InputError

__all__ = ["plot_completeness", "plot_excluded_fraction", "plot_mass_radius"]


def _scale(obj, unit: str):
    if unit not in ("au", "arcsec"):
        raise InputError(f"unit must be 'au' or 'arcsec', got {unit!r}")
    if unit == "au" and obj.distance:
        return float(obj.distance), "au"
    return 1.0, "arcsec"


def _edges(c: np.ndarray) -> np.ndarray:
    c = np.asarray(c, dtype=float)
    if c.size == 1:
        return np.array([0.5 * c[0], 1.5 * c[0]])
    mid = 0.5 * (c[1:] + c[:-1])
    return np.concatenate([[c[0] - (mid[0] - c[0])], mid, [c[-1] + (c[-1] - mid[-1])]])


def _log_edges(m: np.ndarray) -> np.ndarray:
    return np.exp(_edges(np.log(np.asarray(m, dtype=float)))) if len(m) > 1 else np.array([m[0] / 2, m[0] * 2])


def _grey_flags(ax, limits, scale):
    edges = _edges(limits.r_p) * scale
    for i, flag in enumerate(limits.flags):
        if flag:
            ax.axvspan(edges[i], edges[i + 1], color="0.85", zorder=0, lw=0)


def plot_excluded_fraction(limits, family=None, *, unit: str = "au"):
    """Fraction of planet azimuths excluded, mass × r_p, one panel per hand of a family."""
    fam = limits.family(family)
    scale, label = _scale(limits, unit)
    hands = fam.hands
    fig = Figure(figsize=(5.0 * len(hands) + 1.0, 3.8), layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, len(hands), sharey=True))
    r_edges = _edges(limits.r_p) * scale
    m_edges = _log_edges(fam.masses)
    for ax, hand in zip(axes, hands):
        values = np.full((len(fam.masses), limits.r_p.size), np.nan)
        for k, index in enumerate(fam.members[hand]):
            if index is not None:
                values[k] = limits.excluded_fraction[index]
        values[:, limits.flags != ""] = np.nan
        mesh = ax.pcolormesh(r_edges, m_edges, values, vmin=0, vmax=1, cmap="viridis", shading="flat")
        _grey_flags(ax, limits, scale)
        ax.set_yscale("log")
        ax.set_yticks(fam.masses, [f"{m:g}" for m in fam.masses])
        ax.set_xlabel(f"r_p [{label}]")
        ax.set_title(f"{hand}-handed, {fam.label}", fontsize=9)
    axes[0].set_ylabel(r"$M_p$ [$M_{\rm th}$]")
    fig.colorbar(mesh, ax=axes, label=f"fraction of $\\phi_p$ excluded ({limits.cl:.0%})")
    return fig


def _limit_curve(limits, fi):
    status = limits.m_lim_status[fi]
    ok = (status == "limit") | (status == "below_bank")
    return np.where(ok, limits.m_lim[fi], np.nan), status == "below_bank"


def plot_mass_radius(limits, family=None, completeness=None, *, unit: str = "au"):
    """The mass–radius plane: M_lim(r_p) with the excluded region shaded, and M_det(r_p).

    Left panel in thermal masses, right panel in Jupiter masses (``M_th ∝ r_p^{3/4}``; needs a
    distance). ``completeness`` (same family) adds M_det at 50 % and 90 % completeness. Without
    ``family`` on a scan of several families: the limit that holds for every family
    (:mod:`spiralbayes.inference.limits.robust`; M_Jup from each family's own ``h_p``).
    """
    if family is None and len(limits.families) > 1:
        return _plot_over_families(limits, unit)
    fam = limits.family(family)
    fi = limits.families.index(fam)
    scale, label = _scale(limits, unit)
    r = limits.r_p * scale
    m_lim, below = _limit_curve(limits, fi)
    m_top = max(fam.masses)
    panels = [("th", r"$M_p$ [$M_{\rm th}$]")]
    if limits.distance:
        panels.append(("jup", r"$M_p$ [$M_{\rm Jup}$]"))
    fig = Figure(figsize=(5.2 * len(panels), 4.0), layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, len(panels)))
    for ax, (kind, ylabel) in zip(axes, panels):
        conv = (lambda m, rr=limits.r_p: np.asarray(m, float)) if kind == "th" else \
            (lambda m, rr=limits.r_p: limits.to_mjup(m, rr, family=fam))
        lim = conv(m_lim)
        top = conv(np.full(r.size, m_top))
        ax.fill_between(r, lim, top, where=np.isfinite(lim), color="tab:red", alpha=0.25, lw=0,
                        label=f"excluded ({limits.cl:.0%}), bank masses")
        ax.plot(r, lim, color="tab:red", lw=2, label=r"$M_{\rm lim}(r_p)$")
        if below.any():
            ax.plot(r[below], lim[below], "v", color="tab:red", ms=5, label="limit at the lightest bank mass")
        if completeness is not None:
            rc = completeness.r_p * scale
            for level, style in ((0.5, "-"), (0.9, "--")):
                m_det = completeness.m_det(level)
                values = m_det if kind == "th" else limits.to_mjup(m_det, completeness.r_p, family=fam)
                ax.plot(rc, values, style, color="tab:blue", lw=1.8,
                        label=rf"$M_{{\rm det}}$ ({level:.0%} completeness)")
        for m in fam.masses:
            ax.plot(r, conv(np.full(r.size, m)), color="0.6", lw=0.6, ls=":")
        _grey_flags(ax, limits, scale)
        ax.set_yscale("log")
        ax.set_xlabel(f"r_p [{label}]")
        ax.set_ylabel(ylabel)
    axes[0].legend(fontsize=7, loc="upper right")
    fig.suptitle(f"Template family {fam.label}; grey: flagged radii\n{limits.morphology_note(fam)}", fontsize=9)
    return fig


def _plot_over_families(limits, unit: str):
    """Robust M_lim over every family (thick) and each family's own (thin), M_th and M_Jup."""
    from ..inference.limits.robust import combined_m_lim, combined_m_lim_mjup

    scale, label = _scale(limits, unit)
    r = limits.r_p * scale
    panels = [("th", r"$M_p$ [$M_{\rm th}$]")] + ([("jup", r"$M_p$ [$M_{\rm Jup}$]")] if limits.distance else [])
    fig = Figure(figsize=(5.2 * len(panels), 4.0), layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, len(panels)))
    for ax, (kind, ylabel) in zip(axes, panels):
        for fi, fam in enumerate(limits.families):
            curve, _ = _limit_curve(limits, fi)
            ax.plot(r, curve if kind == "th" else limits.to_mjup(curve, family=fam), color="0.6", lw=0.7)
        robust = combined_m_lim(limits)[0] if kind == "th" else combined_m_lim_mjup(limits)
        ax.plot(r, robust, color="tab:red", lw=2,
                label=rf"$M_{{\rm lim}}$ holding for every family (morphologies {', '.join(limits.morphologies)})")
        _grey_flags(ax, limits, scale)
        ax.set_yscale("log")
        ax.set_xlabel(f"r_p [{label}]")
        ax.set_ylabel(ylabel)
    axes[0].legend(fontsize=7, loc="upper right")
    fig.suptitle(f"All {len(limits.families)} template families (grey: each family; grey bands: flagged radii)\n"
                 f"{limits.morphology_note()}", fontsize=9)
    return fig


def plot_completeness(completeness, *, unit: str = "au"):
    """P(recovered | M_p, r_p) with the 50 % and 90 % minimum detectable masses."""
    scale, label = _scale(completeness, unit)
    fig = Figure(figsize=(6.0, 3.8), layout="constrained")
    ax = fig.subplots()
    mesh = ax.pcolormesh(_edges(completeness.r_p) * scale, _log_edges(completeness.masses),
                         completeness.probability, vmin=0, vmax=1, cmap="magma", shading="flat")
    for level, style in ((0.5, "-"), (0.9, "--")):
        ax.plot(completeness.r_p * scale, completeness.m_det(level), style, color="tab:cyan", lw=2,
                label=rf"$M_{{\rm det}}$ ({level:.0%})")
    ax.set_yscale("log")
    ax.set_yticks(completeness.masses, [f"{m:g}" for m in completeness.masses])
    ax.set_xlabel(f"r_p [{label}]")
    ax.set_ylabel(r"$M_p$ [$M_{\rm th}$]")
    ax.set_title(f"completeness, {completeness.family.label}, {completeness.n_trials} injections per cell",
                 fontsize=9)
    ax.legend(fontsize=7)
    fig.colorbar(mesh, ax=ax, label="P(recovered)")
    return fig
