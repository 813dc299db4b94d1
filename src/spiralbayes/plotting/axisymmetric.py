"""Plots of an axisymmetric (frank) fit: the brightness profile and the binned visibilities.

Both functions return a :class:`matplotlib.figure.Figure` built without pyplot's global
state (safe under the Agg backend, in scripts and in tests).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from matplotlib.figure import Figure

from ..axisymmetric import AxisymmetricModel
from ..exceptions import InputError
from ..visibilities import Visibilities

__all__ = ["plot_profile", "plot_binned_visibilities"]

_BRIGHTNESS_UNIT = 1e10  # profiles are shown in 1e10 Jy/sr, as frank does
_UV_UNITS = {"klambda": (1e3, r"k$\lambda$"), "Mlambda": (1e6, r"M$\lambda$")}


def _truth_curve(truth, r_fine):
    """``(r, I)`` of a reference profile given as a callable or as a pair of arrays."""
    if callable(truth):
        return r_fine, np.asarray(truth(r_fine), dtype=float)
    r_t, I_t = truth
    return np.asarray(r_t, dtype=float), np.asarray(I_t, dtype=float)


def plot_profile(model: AxisymmetricModel, truth: Callable | tuple | None = None, *,
                 distance: float | None = None, show_nonnegative: bool = True,
                 figsize=(6.4, 4.2)) -> Figure:
    """Brightness profile ``I(r)`` of a frank fit [1e10 Jy/sr] against radius [arcsec].

    Parameters
    ----------
    model : AxisymmetricModel
        The fit; its 1-sigma band is drawn when ``model.I_err`` is known, and the non-negative
        profile when present and ``show_nonnegative``.
    truth : callable or (r, I), optional
        A reference profile: ``I(r [arcsec]) -> Jy/sr`` or arrays of r [arcsec] and I [Jy/sr].
    distance : float, optional
        Source distance [pc]; adds a top axis in au.
    """
    fig = Figure(figsize=figsize, layout="constrained")
    ax = fig.add_subplot()
    r_fine = np.linspace(0.0, model.Rmax, max(4 * model.N, 800))
    scale = _BRIGHTNESS_UNIT
    ax.plot(r_fine, model.brightness(r_fine) / scale, color="C0", lw=1.2, label="frank fit")
    if model.I_err is not None:
        ax.fill_between(model.r, (model.I - model.I_err) / scale, (model.I + model.I_err) / scale,
                        color="C0", alpha=0.3, lw=0, label=r"$\pm 1\sigma$")
    if show_nonnegative and model.I_nonneg is not None:
        ax.plot(model.r, model.I_nonneg / scale, color="C2", lw=1, ls="--", label=r"frank fit, $I \geq 0$")
    if truth is not None:
        r_t, I_t = _truth_curve(truth, r_fine)
        ax.plot(r_t, I_t / scale, color="k", lw=1, ls=":", label="truth")
    ax.axhline(0.0, color="0.6", lw=0.6)
    ax.set_xlim(0.0, model.Rmax)
    ax.set_xlabel("r [arcsec]")
    ax.set_ylabel(r"I [$10^{10}$ Jy sr$^{-1}$]")
    g = model.geometry
    sky_mjy = model.total_flux * g.cos_inc * 1e3  # the flux on the sky (x cos i), as the CLI prints
    ax.set_title(f"inc = {g.inc:.2f}°, PA = {g.PA:.2f}°, sky (projected) flux = {sky_mjy:.2f} mJy, "
                 f"R$_{{95}}$ = {model.R_eff(0.95):.3f}\"", fontsize=9)
    if distance is not None:
        if not (np.isfinite(distance) and distance > 0):
            raise InputError(f"distance = {distance!r} pc must be positive")
        d = float(distance)
        top = ax.secondary_xaxis("top", functions=(lambda r: np.asarray(r) * d, lambda a: np.asarray(a) / d))
        top.set_xlabel("r [au]")
    ax.legend(fontsize=8)
    return fig


def _bin(vis: Visibilities, geometry, bin_width: float):
    """Binned deprojected visibilities: ``(q, re, re_err, im, im_err)``."""
    from ..visibilities import bin_deprojected

    b = bin_deprojected(vis, geometry, bin_width=bin_width)
    return b.q, b.re, b.re_err, b.im, b.im_err


def plot_binned_visibilities(vis: Visibilities, model: AxisymmetricModel, *, bin_width: float = 20e3,
                             logx: bool = False, units: str = "klambda", figsize=(6.4, 5.6)) -> Figure:
    """Binned Re V and Im V [mJy] against deprojected baseline, with the model's curve.

    The data are re-centred and deprojected with the model's geometry
    (:func:`spiralbayes.visibilities.bin_deprojected`, no ``cos i`` rescaling), so the model
    curve is ``cos i`` times the Hankel transform of the profile
    (:meth:`.AxisymmetricModel.visibilities_deprojected`).

    Parameters
    ----------
    vis : Visibilities
        The data.
    model : AxisymmetricModel
        The fit.
    bin_width : float
        Bin width [lambda].
    logx : bool
        Logarithmic baseline axis.
    units : {"klambda", "Mlambda"}
        Unit of the baseline axis.
    """
    if units not in _UV_UNITS:
        raise InputError(f"units = {units!r} must be one of {sorted(_UV_UNITS)}")
    if not (np.isfinite(bin_width) and bin_width > 0):
        raise InputError(f"bin_width = {bin_width!r} lambda must be positive")
    div, label = _UV_UNITS[units]
    q, re, re_err, im, im_err = _bin(vis, model.geometry, bin_width)
    q_lo = max(q.min() * 0.5, 1.0) if logx else 0.0
    q_model = np.geomspace(q_lo, q.max() * 1.05, 1000) if logx else np.linspace(0.0, q.max() * 1.05, 1000)
    V_model = model.visibilities_deprojected(q_model)

    fig = Figure(figsize=figsize, layout="constrained")
    ax_re, ax_im = fig.subplots(2, 1, sharex=True, height_ratios=[3, 1])
    ax_re.errorbar(q / div, re * 1e3, yerr=re_err * 1e3, fmt=".", ms=3, color="k", elinewidth=0.6,
                   label=f"data, {bin_width / div:g} {label} bins")
    ax_re.plot(q_model / div, V_model * 1e3, color="C3", lw=1.2, label="frank fit")
    ax_im.errorbar(q / div, im * 1e3, yerr=im_err * 1e3, fmt=".", ms=3, color="k", elinewidth=0.6)
    ax_im.axhline(0.0, color="C3", lw=1.2)
    for ax in (ax_re, ax_im):
        ax.axhline(0.0, color="0.6", lw=0.5, zorder=0)
        if logx:
            ax.set_xscale("log")
    ax_re.set_ylabel("Re V [mJy]")
    ax_im.set_ylabel("Im V [mJy]")
    ax_im.set_xlabel(f"deprojected baseline [{label}]")
    ax_re.legend(fontsize=8)
    return fig
