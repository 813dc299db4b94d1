"""The spiral against its best competitor, as residual dirty images on one colour scale (test 3).

Top row: the data's residual from the axisymmetric model, and what the best spiral instance and
the best alternative model predict for it (their model minus the axisymmetric model); bottom
row: what each leaves behind (data minus model). All are naturally weighted dirty images of the
visibility differences [Jy/beam], north up and east left (:func:`spiralbayes.fourier.dirty_image`),
so a model that explains the residual reproduces the top-left panel and leaves noise below.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from ..exceptions import InputError
from ..fourier import dirty_image, image_axes
from ..model import perturbation_visibilities
from ..units import ARCSEC

__all__ = ["plot_residual_comparison", "spiral_visibilities"]


def _find_template(templates, name: str):
    for template in templates:
        if getattr(template, "name", None) == name:
            return template
    raise InputError(f"template {name!r} (the scan's best) is not among the templates given: pass the scanned ones")


def spiral_visibilities(vis, axisymmetric, scan_result, templates, amplitude=None) -> tuple[np.ndarray, str]:
    """``V_S − V_A`` [Jy] of the scan's best instance at ``vis``, and a label for it.

    With ``amplitude="free"`` the template is scaled by its best amplitude there.
    """
    best = scan_result.peak(amplitude=amplitude)
    template = _find_template(templates, best.template)
    scale = 1.0
    if amplitude == "free":
        t, i, j = best.template_index, best.i_rp, best.i_phi
        power = scan_result.power[t, i, j]
        scale = max(scan_result.cross[t, i, j] / power, 0.0) if power > 0 else 0.0
    dV = perturbation_visibilities(vis.u, vis.v, scan_result.geometry, axisymmetric.brightness, template,
                                   best.r_p, best.phi_p)
    label = f"{best.template} at r_p = {best.r_p:.3f}\", phi_p = {np.degrees(best.phi_p):.0f} deg"
    return scale * dV, label


def plot_residual_comparison(vis, axisymmetric, scan_result, alternatives, templates, *, amplitude=None,
                             fov: float | None = None, pixel_size: float | None = None, cmap: str = "RdBu_r"):
    """Residual dirty images of the data, the best spiral and the best alternative (one colour scale).

    Parameters
    ----------
    vis : Visibilities
        The data the scan and the alternatives used.
    axisymmetric : AxisymmetricModel
        The scan's axisymmetric model.
    scan_result : ScanResult
    alternatives : AlternativesResult
    templates : sequence of SpiralTemplate
        The scanned templates (the best one is looked up by name).
    amplitude : None or "free"
        The scan's amplitude convention.
    fov : float, optional
        Image width [arcsec]; default twice the alternatives' grid radius.
    pixel_size : float, optional
        [arcsec]; default a third of the finest fringe spacing.

    Returns
    -------
    Figure
    """
    vis = vis.standardised()
    geometry = scan_result.geometry
    V_A = axisymmetric.visibilities(vis.u, vis.v, geometry)
    residual = vis.V - V_A
    dV_spiral, spiral_label = spiral_visibilities(vis, axisymmetric, scan_result, templates, amplitude)
    alt = alternatives.best
    dV_alt = alternatives.model_visibilities(alt.name, vis, axisymmetric)
    uv_max = float(np.max(np.hypot(vis.u, vis.v)))
    pixel = pixel_size or 1.0 / (3.0 * uv_max) / ARCSEC
    width = fov or 2.0 * alternatives.grid.r_max
    n = int(np.ceil(width / pixel))
    n += n % 2
    panels = {
        "data - axisymmetric": residual,
        f"best spiral - axisymmetric\n{spiral_label}": dV_spiral,
        f"best alternative - axisymmetric\n{alt.label} (Delta BIC {alt.delta_bic(alternatives.n_data):.0f})": dV_alt,
        "data - best spiral": residual - dV_spiral,
        "data - best alternative": residual - dV_alt,
    }
    images = {k: dirty_image(vis.u, vis.v, V, vis.weights, (n, n), pixel) for k, V in panels.items()}
    vmax = float(np.max(np.abs(images["data - axisymmetric"]))) or 1.0
    l, m = image_axes((n, n), pixel)
    extent = (l[0] + pixel / 2, l[-1] - pixel / 2, m[0] - pixel / 2, m[-1] + pixel / 2)
    fig = Figure(figsize=(13, 8.4), layout="constrained")
    axes = fig.subplots(2, 3)
    axes[1, 0].axis("off")
    axes[1, 0].text(0.02, 0.5, _score_text(scan_result, alternatives, amplitude), va="center", family="monospace",
                    fontsize=8, transform=axes[1, 0].transAxes)
    slots = [axes[0, 0], axes[0, 1], axes[0, 2], axes[1, 1], axes[1, 2]]
    for ax, (title, image) in zip(slots, images.items()):
        mesh = ax.imshow(image, origin="lower", extent=extent, cmap=cmap, vmin=-vmax, vmax=vmax)
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("RA offset [arcsec] (east left)")
        ax.set_ylabel("Dec offset [arcsec]")
    fig.colorbar(mesh, ax=axes, shrink=0.7, label="dirty image [Jy/beam]")
    return fig


def _score_text(scan_result, alternatives, amplitude) -> str:
    best = scan_result.peak(amplitude=amplitude)
    lines = [f"{'model':<16}{'dBIC':>9}", f"{'spiral':<16}{best.delta_bic:>9.1f}"]
    for name, value in sorted(alternatives.delta_bic().items(), key=lambda kv: -kv[1]):
        lines.append(f"{name:<16}{value:>9.1f}")
    return "Delta BIC against the\naxisymmetric model\n\n" + "\n".join(lines)
