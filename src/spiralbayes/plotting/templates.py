"""Plots of spiral templates: a template's brightness and residual maps, and a bank overview.

Maps are shown face on in the disc plane, in units of ``r_p``, with the azimuth convention of
:mod:`spiralbayes.templates.template`: φ = 0 (the planet, marked ★) to the right, φ increasing
anticlockwise, as in the usual sky display (north up, east left) rotated so the minor axis is
horizontal (Stevenson et al. 2024, Fig. 2). Residuals use a diverging colour map centred on 0.
Functions return a :class:`matplotlib.figure.Figure` built without pyplot (Agg-safe).
"""

from __future__ import annotations

import numpy as np
from matplotlib.colors import TwoSlopeNorm
from matplotlib.figure import Figure

from ..exceptions import InputError
from ..templates.bank import TemplateBank
from ..templates.template import SpiralTemplate

__all__ = ["plot_template", "plot_bank_overview"]


def _edges_log(x: np.ndarray) -> np.ndarray:
    lx = np.log(x)
    mid = 0.5 * (lx[1:] + lx[:-1])
    return np.exp(np.concatenate([[2 * lx[0] - mid[0]], mid, [2 * lx[-1] - mid[-1]]]))


def _polar_mesh(t: SpiralTemplate, rmax: float | None):
    keep = np.ones(t.x.size, bool) if rmax is None else t.x <= rmax  # a prefix: x increases
    xe = _edges_log(t.x)[: keep.sum() + 1]
    dphi = 2 * np.pi / t.phi.size
    pe = np.concatenate([t.phi - 0.5 * dphi, [t.phi[-1] + 0.5 * dphi]])
    R, P = np.meshgrid(xe, pe, indexing="ij")
    return R * np.cos(P), R * np.sin(P), keep


def _draw_map(ax, t: SpiralTemplate, values, keep, X, Y, *, cmap, norm, label, colorbar=True, fig=None):
    mesh = ax.pcolormesh(X, Y, values[keep], cmap=cmap, norm=norm, shading="flat", rasterized=True)
    ax.plot([1.0], [0.0], marker="*", color="gold", mec="k", ms=10, lw=0)
    ax.set_aspect("equal")
    if colorbar and fig is not None:
        fig.colorbar(mesh, ax=ax, label=label, shrink=0.85)
    return mesh


def plot_template(template: SpiralTemplate, *, rmax: float | None = None, vmax: float | None = None,
                  cmap: str = "RdBu_r", figsize=(11.0, 4.8)) -> Figure:
    """Brightness and residual maps of one template in the disc plane (cf. the paper's Fig. 2).

    Parameters
    ----------
    template : SpiralTemplate
        The template. The left panel shows ``template.brightness`` (``I / <I>_φ(r_p)``) when it
        is stored, else ``1 + δ = I/<I>_φ``.
    rmax : float, optional
        Outer radius shown [r_p] (default: the whole grid).
    vmax : float, optional
        Colour limit of the residual panel (default: the 99.5th percentile of ``|δ|``).
    cmap : str
        Diverging colour map of the residual panel.

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig = Figure(figsize=figsize, constrained_layout=True)
    ax1, ax2 = fig.subplots(1, 2)
    X, Y, keep = _polar_mesh(template, rmax)
    delta = np.asarray(template.delta, dtype=float)
    if template.brightness is not None:
        bright, blabel = template.brightness, r"$I\,/\,\langle I\rangle_\phi(r_p)$"
        norm_b = None
        from matplotlib.colors import LogNorm

        pos = bright[keep][bright[keep] > 0]
        if pos.size:
            norm_b = LogNorm(vmin=np.percentile(pos, 1), vmax=pos.max())
    else:
        bright, blabel, norm_b = 1.0 + delta, r"$I\,/\,\langle I\rangle_\phi$", None
    _draw_map(ax1, template, bright, keep, X, Y, cmap="inferno", norm=norm_b, label=blabel, fig=fig)
    ax1.set_title("brightness")
    v = vmax if vmax is not None else float(np.percentile(np.abs(delta[keep]), 99.5)) or 1.0
    _draw_map(ax2, template, delta, keep, X, Y, cmap=cmap, norm=TwoSlopeNorm(0.0, -v, v),
              label=r"$\delta = I/\langle I\rangle_\phi - 1$", fig=fig)
    ax2.set_title("residual")
    for ax in (ax1, ax2):
        ax.set_xlabel(r"$x\ [r_p]$ (φ = 0 to the right)")
        ax.set_ylabel(r"$y\ [r_p]$")
    fig.suptitle(
        f"{template.name}: $M_p$ = {template.mass:g} $M_{{th}}$, $\\tau_0$ = {template.tau0:g}, "
        f"$\\beta$ = {template.beta:g}, hand {template.hand}"
    )
    return fig


def plot_bank_overview(bank: TemplateBank, *, beta: float = 0.0, hand: str = "R", h_p: float | None = None,
                       rmax: float | None = None, vmax: float | None = None, cmap: str = "RdBu_r",
                       panel_size: float = 2.6) -> Figure:
    """Residual maps of a bank's templates on a mass × τ0 grid for one β, hand and H/r.

    Parameters
    ----------
    bank : TemplateBank
        The bank (e.g. :func:`~spiralbayes.templates.default_bank`).
    beta : float
        Cooling time shown.
    hand : {'R', 'L'}
        Handedness shown.
    h_p : float, optional
        Disc aspect ratio shown (default: 0.07 if the bank has it, else its first).
    rmax : float, optional
        Outer radius [r_p].
    vmax : float, optional
        Common colour limit (default: the 99th percentile of ``|δ|`` over the panels).

    Returns
    -------
    matplotlib.figure.Figure
        Rows: masses (increasing downwards); columns: τ0 (increasing to the right).
    """
    if h_p is None:
        have = sorted({float(t.h_p) for t in bank})
        h_p = 0.07 if any(np.isclose(h, 0.07) for h in have) else (have[0] if have else None)
    sub = bank.select(beta=beta, hand=hand, h_p=h_p)
    if len(sub) == 0:
        raise InputError(f"the bank has no templates with beta={beta}, hand={hand!r}, h_p={h_p}")
    params = sub.parameters
    masses = np.unique(params["mass"])
    taus = np.unique(params["tau0"])
    fig = Figure(figsize=(panel_size * len(taus) + 1.2, panel_size * len(masses)), constrained_layout=True)
    axes = np.atleast_2d(fig.subplots(len(masses), len(taus), squeeze=False))
    if vmax is None:
        vmax = max(float(np.percentile(np.abs(t.delta), 99)) for t in sub) or 1.0
    norm = TwoSlopeNorm(0.0, -vmax, vmax)
    mesh = None
    for i, m in enumerate(masses):
        for j, tau in enumerate(taus):
            ax = axes[i, j]
            found = sub.select(mass=m, tau0=tau)
            if len(found) == 0:
                ax.set_axis_off()
                continue
            t = found[0]
            X, Y, keep = _polar_mesh(t, rmax)
            mesh = _draw_map(ax, t, np.asarray(t.delta, dtype=float), keep, X, Y, cmap=cmap, norm=norm,
                             label="", colorbar=False)
            ax.set_xticks([])
            ax.set_yticks([])
            if i == 0:
                ax.set_title(rf"$\tau_0$ = {tau:g}")
            if j == 0:
                ax.set_ylabel(rf"$M_p$ = {m:g} $M_{{th}}$")
    if mesh is not None:
        fig.colorbar(mesh, ax=axes, label=r"$\delta$", shrink=0.6)
    fig.suptitle(rf"templates, $\beta$ = {beta:g}, hand {hand}, $H/r$ = {h_p:g}")
    return fig
