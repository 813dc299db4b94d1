"""The visibility scan beside the image-plane comparisons, in the style of Stevenson et al. (2024, Fig. 7).

Four panels: the CLEAN image of the data, the CLEAN residual image (in units of its noise), the
Δχ² heatmap of the best template and the CLEAN image's azimuthally averaged profile with the
deepest gap marked. Images are shown north up, east left, with the restoring beam in the lower
left corner.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Ellipse

from .scan import plot_heatmap

__all__ = ["plot_comparison"]


def _extent(clean, half: float):
    """imshow extent [arcsec] of the image crop ``|l|, |m| <= half`` and that crop's slices."""
    l, m = clean.axes()
    cols = np.flatnonzero(np.abs(l) <= half)
    rows = np.flatnonzero(np.abs(m) <= half)
    d = 0.5 * clean.cell
    extent = (l[cols[0]] + d, l[cols[-1]] - d, m[rows[0]] - d, m[rows[-1]] + d)
    return extent, (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))


def _beam(ax, clean, half: float, colour: str):
    bmaj, bmin, bpa = clean.beam
    centre = (0.8 * half, -0.8 * half)  # lower left: east is +l, drawn on the left
    # in data coordinates a rotation by angle takes north (0, 1) to (-sin, cos); PA turns it east (+l)
    ax.add_patch(Ellipse(centre, bmin, bmaj, angle=-bpa, facecolor="none", edgecolor=colour, lw=1.2))


def _image_panel(fig, ax, clean, data, half, *, title, cmap, label, norm=None, scale=1.0, beam_colour="w"):
    extent, crop = _extent(clean, half)
    im = ax.imshow(data[crop] * scale, origin="lower", extent=extent, cmap=cmap, norm=norm, interpolation="nearest")
    _beam(ax, clean, half, beam_colour)
    ax.set_xlabel(r"$\Delta$RA [arcsec]")
    ax.set_ylabel(r"$\Delta$Dec [arcsec]")
    ax.set_title(title)
    fig.colorbar(im, ax=ax, label=label, shrink=0.85)
    return ax


def plot_comparison(residuals, gap, scan_result, verdict, geometry, *, distance: float | None = None,
                    template=None, half_width: float | None = None):
    """Fig. 7-style comparison of the three methods; returns the Figure.

    Parameters
    ----------
    residuals : spiralbayes.image_plane.CleanResiduals
    gap : spiralbayes.image_plane.GapDepth
    scan_result : ScanResult
    verdict : Verdict
        Of the scan (:func:`spiralbayes.inference.detection.verdict.detect`).
    geometry : DiscGeometry
        Used to mark the scan's best planet position on the images.
    distance : float, optional
        [pc], for an au axis on the profile.
    template : int or str, optional
        Template whose heatmap is shown (default the verdict's).
    half_width : float, optional
        Half-width of the image crops [arcsec] (default ``1.3 r_out``).
    """
    from matplotlib.colors import TwoSlopeNorm

    det = residuals.detection
    half = 1.3 * det.r_out if half_width is None else float(half_width)
    fig = Figure(figsize=(19, 4.6), layout="constrained")
    axes = fig.subplots(1, 4)
    data = residuals.data
    _image_panel(fig, axes[0], data, data.image, half, title="CLEAN image", cmap="inferno", label="mJy/beam",
                 scale=1e3)
    snr = residuals.difference / det.noise
    vmax = max(5.0, float(np.ceil(det.peak_snr)))
    _image_panel(fig, axes[1], data, snr, half, cmap="RdBu_r", label=r"residual / $\sigma$",
                 norm=TwoSlopeNorm(0.0, -vmax, vmax), beam_colour="k",
                 title=f"CLEAN residuals: peak {det.peak_snr:.1f}$\\sigma$, {det.verdict}")
    l_p, m_p = geometry.disc_to_sky(verdict.r_p, np.radians(verdict.phi_p_deg))
    for ax in axes[:2]:
        ax.plot([l_p], [m_p], "+", color="c", ms=12, mew=2, label="scan's planet")
    axes[1].legend(loc="upper right", fontsize=8)
    plot_heatmap(scan_result, verdict.template if template is None else template, ax=axes[2])
    axes[2].set_title(f"{axes[2].get_title()}\n$\\Delta$BIC = {verdict.delta_bic:.1f}, "
                      f"{'detected' if verdict.detected else 'not detected'}")
    _profile_panel(axes[3], gap, verdict, distance, det.r_out)
    return fig


def _profile_panel(ax, gap, verdict, distance, r_out):
    scale = distance if distance else 1.0
    unit = "au" if distance else "arcsec"
    r = gap.r * scale
    ax.fill_between(r, (gap.profile - gap.profile_error) * 1e3, (gap.profile + gap.profile_error) * 1e3,
                    color="0.8", lw=0)
    ax.plot(r, gap.profile * 1e3, color="k", lw=1.2)
    if gap.r_gap is not None:
        ax.axvline(gap.r_gap * scale, color="tab:blue", ls=":", label="gap")
        ax.axvline(gap.r_ring * scale, color="tab:orange", ls=":", label="ring")
    ax.axvline(verdict.r_p * scale, color="c", ls="--", label="scan's planet")
    ax.set_xlabel(f"deprojected radius [{unit}]")
    ax.set_ylabel("azimuthal mean [mJy/beam]")
    ax.set_title(f"CLEAN profile\ngap depth $\\delta$ = {gap.delta:.2f}: {gap.verdict}")
    ax.set_xlim(0.0, 1.1 * r_out * scale)
    ax.set_ylim(bottom=0.0)
    ax.legend(fontsize=8)
