"""Δχ² heatmaps of a scan, as in Stevenson et al. (2024, Figs 3-6), and χ² against r_p.

The heatmaps show the deprojected disc with the minor axis horizontal: ``phi_p = 0`` (the
right-hand arm of the minor axis) points right and ``phi_p`` increases anticlockwise, the
convention of :mod:`spiralbayes.geometry`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.figure import Figure

from ..exceptions import InputError
from ..inference.scan.statistics import bic_threshold

__all__ = ["plot_chi2_vs_rp", "plot_heatmap", "plot_heatmap_pair", "plot_template_grid_heatmaps"]


def _norm(values, vmin=None, vmax=None):
    from matplotlib.colors import TwoSlopeNorm

    finite = values[np.isfinite(values)]
    vmax = float(np.max(finite)) if vmax is None else vmax
    vmin = float(np.min(finite)) if vmin is None else vmin
    vmax = max(vmax, 1e-12)
    vmin = min(vmin, -1e-12)
    return TwoSlopeNorm(vcenter=0.0, vmin=vmin, vmax=vmax)


def _edges(centres: np.ndarray, periodic: bool = False) -> np.ndarray:
    c = np.asarray(centres, dtype=float)
    if c.size == 1:
        return np.array([c[0] * 0.5, c[0] * 1.5])
    mid = 0.5 * (c[1:] + c[:-1])
    first = c[0] - (mid[0] - c[0])
    last = c[-1] + (c[-1] - mid[-1])
    return np.concatenate([[max(first, 0.0) if not periodic else first], mid, [last]])


def _draw(ax, result, values, norm, unit: str, cmap: str):
    scale = result.distance if (unit == "au" and result.distance) else 1.0
    r_edges = _edges(result.r_p) * scale
    phi_edges = _edges(result.phi_p, periodic=True)
    R, P = np.meshgrid(r_edges, phi_edges, indexing="ij")
    mesh = ax.pcolormesh(R * np.cos(P), R * np.sin(P), values, norm=norm, cmap=cmap, shading="flat")
    ax.set_aspect("equal")
    label = "au" if scale != 1.0 else "arcsec"
    ax.set_xlabel(f"minor axis [{label}]")
    ax.set_ylabel(f"major axis [{label}]")
    return mesh


def _mark_best(ax, result, t_index, amplitude, unit):
    best = result.peak(t_index, amplitude)
    scale = result.distance if (unit == "au" and result.distance) else 1.0
    r = best.r_p * scale
    ax.plot(r * np.cos(best.phi_p), r * np.sin(best.phi_p), "x", color="k", ms=8, mew=2)


def plot_heatmap(result, template=0, *, amplitude=None, unit: str = "au", vmin=None, vmax=None,
                 cmap: str = "RdBu_r", ax=None, mark_best: bool = True):
    """Polar Δχ² heatmap of one template over (r_p, phi_p); returns the Figure."""
    t = result.template_index(template)
    values = result.delta_chi2(amplitude)[t]
    fig = ax.figure if ax is not None else Figure(figsize=(5.5, 4.8))
    ax = ax or fig.add_subplot(111)
    mesh = _draw(ax, result, values, _norm(values, vmin, vmax), unit, cmap)
    if mark_best:
        _mark_best(ax, result, t, amplitude, unit)
    ax.set_title(result.templates[t]["name"])
    fig.colorbar(mesh, ax=ax, label=r"$\Delta\chi^2$")
    return fig


def plot_heatmap_pair(result, right, left, *, amplitude=None, unit: str = "au", vmin=None, vmax=None,
                      cmap: str = "RdBu_r"):
    """R and L templates side by side with a shared colour bar (the paper's handedness view)."""
    idx = [result.template_index(right), result.template_index(left)]
    dchi2 = result.delta_chi2(amplitude)
    values = dchi2[idx]
    norm = _norm(values, vmin, vmax)
    fig = Figure(figsize=(10.5, 4.8), layout="constrained")
    axes = fig.subplots(1, 2)
    for ax, t in zip(axes, idx):
        mesh = _draw(ax, result, dchi2[t], norm, unit, cmap)
        _mark_best(ax, result, t, amplitude, unit)
        peak = float(np.max(dchi2[t]))
        ax.set_title(f"{result.templates[t]['name']}\npeak $\\Delta\\chi^2$ = {peak:.1f}")
    fig.colorbar(mesh, ax=axes, label=r"$\Delta\chi^2$", shrink=0.85)
    return fig


def plot_template_grid_heatmaps(result, *, hand: str = "R", beta=None, amplitude=None, unit: str = "au"):
    """Heatmaps of every scanned template of one hand (and beta), mass × tau0, shared colours."""
    chosen = [i for i, m in enumerate(result.templates)
              if m.get("hand") == hand and (beta is None or m.get("beta") == beta)]
    if not chosen:
        raise InputError(f"no scanned template with hand={hand!r} and beta={beta!r}")
    masses = sorted({result.templates[i].get("mass") for i in chosen})
    taus = sorted({result.templates[i].get("tau0") for i in chosen})
    dchi2 = result.delta_chi2(amplitude)
    norm = _norm(dchi2[chosen])
    fig = Figure(figsize=(3 * len(taus), 3 * len(masses)), layout="constrained")
    axes = fig.subplots(len(masses), len(taus), squeeze=False)
    for i in chosen:
        m = result.templates[i]
        ax = axes[masses.index(m.get("mass")), taus.index(m.get("tau0"))]
        mesh = _draw(ax, result, dchi2[i], norm, unit, "RdBu_r")
        ax.set_title(f"M={m.get('mass')} Mth, tau0={m.get('tau0')}", fontsize=8)
    fig.colorbar(mesh, ax=axes, label=r"$\Delta\chi^2$", shrink=0.6)
    return fig


def plot_chi2_vs_rp(result, templates=None, *, quantity: str = "chi2_SA", amplitude=None, unit: str = "au"):
    """χ² against planet radius for each template (Stevenson et al. 2024, App. B).

    ``quantity="chi2_SA"`` (default): ``chi2_SA = sum w |V_S - V_A|^2``, the χ² between the spiral
    and axisymmetric models — the Δχ² a real planet with that template would give without noise —
    averaged over phi_p (band: min to max over phi_p), on a log axis, with the ``6 ln N`` line
    above which such a planet would pass ΔBIC > 0. ``quantity="delta_chi2"``: the best Δχ² over
    phi_p of the data.
    """
    if quantity not in ("chi2_SA", "delta_chi2"):
        raise InputError(f"quantity must be 'chi2_SA' or 'delta_chi2', got {quantity!r}")
    idx = range(len(result.templates)) if templates is None else [result.template_index(t) for t in templates]
    idx = list(idx)
    scale = result.distance if (unit == "au" and result.distance) else 1.0
    r = result.r_p * scale
    fig = Figure(figsize=(6.5, 4.2), layout="constrained")
    ax = fig.subplots()
    for t in idx:
        name = result.templates[t]["name"]
        # a template and its mirror have nearly the same chi2_SA: L dashed over a wider R stays visible
        style: dict[str, Any] = ({"ls": "--", "lw": 1.2} if result.templates[t].get("hand") == "L"
                                 else {"ls": "-", "lw": 2.2})
        if quantity == "chi2_SA":
            power = result.power[t]
            (line,) = ax.plot(r, power.mean(axis=1), label=name, **style)
            ax.fill_between(r, power.min(axis=1), power.max(axis=1), color=line.get_color(), alpha=0.15)
        else:
            ax.plot(r, np.max(result.delta_chi2(amplitude)[t], axis=1), label=name, **style)
    if quantity == "chi2_SA":
        ax.set_yscale("log")
        ax.axhline(bic_threshold(result.n_data), color="k", ls="--", lw=0.8, label="6 ln N")
        ax.set_ylabel(r"$\chi^2_{SA} = \sum w\,|V_S - V_A|^2$ (spiral vs axisymmetric model;" "\n"
                      r"the noise-free $\Delta\chi^2$ of such a planet)", fontsize=8)
    else:
        ax.axhline(0, color="0.5", lw=0.8)
        ax.set_ylabel(r"max over $\phi_p$ of $\Delta\chi^2$")
    ax.set_xlabel(f"r_p [{'au' if scale != 1.0 else 'arcsec'}]")
    if len(idx) <= 12:
        ax.legend(fontsize=7)
    return fig
