"""Test 3 with the planet's own compact peak: "spiral + compact peak at the planet" is the spiral hypothesis.

Both kinds of reference spiral (FARGO3D hydrodynamics and wakeflow, ``tests/data/references``)
hold a compact density peak at the planet, within about one pressure scale height, that the
wake templates do not carry. In the data it is a compact source at the planet, which
the arc/vortex alternative of test 3 (:mod:`~spiralbayes.inference.detection.alternatives`) fits
well (σ_φ of a few degrees) —
so a real planet could lose test 3 to "an arc at the planet". A planet is spiral *plus* that
peak, so for test 3 the spiral hypothesis is scored as the best spiral instance (template at
``A = 1``, as in the scan) plus a circular Gaussian source at the planet's sky position with a
free flux (one more parameter): ``ΔBIC = Δχ² − 7 ln N``. Its width is the planet's scale height
``h_p r_p`` (at least ``min_width``), far below the beam of the data this package targets, so the
peak is nearly a point source and adds nothing for extended impostors (arcs, lopsided or m = 2
patterns, eccentric rings, geometry errors); it is only compared with the **arc** alternative
(the only compact one); every other alternative still faces the bare spiral's ΔBIC. Tests 1 and 2
are unchanged. The verdict says which spiral score test 3 used (``Verdict.test3_spiral_model``).
:func:`~.verdict.detect` applies it when given the scanned data (``vis``, ``axisymmetric``,
``templates``), as the pipeline runs it.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ...exceptions import InputError
from ...units import ARCSEC
from ..scan.statistics import bic_threshold, chi2

__all__ = ["COMPACT_ALTERNATIVES", "apply_planet_peak", "rescore_with_planet_peak", "spiral_with_planet_peak"]

COMPACT_ALTERNATIVES = ("arc",)
"""Alternatives that a compact source at the planet can mimic (scored against spiral + peak)."""
SPIRAL_PEAK_LABEL = "spiral + compact peak at the planet"


def _peak_visibilities(u, v, geometry, r_p: float, phi_p: float, width: float) -> np.ndarray:
    """Unit-flux circular Gaussian [Jy] of FWHM-free width ``width`` [arcsec] (σ) at disc ``(r_p, phi_p)``."""
    l, m = geometry.disc_to_sky(r_p, phi_p)
    q2 = (np.asarray(u) ** 2 + np.asarray(v) ** 2) * ARCSEC**2
    return np.exp(-2 * np.pi**2 * width**2 * q2) * np.exp(2j * np.pi * (np.asarray(u) * l + np.asarray(v) * m) * ARCSEC)


def spiral_with_planet_peak(result, vis, axisymmetric, templates, geometry, *, template=None,
                            min_width: float = 0.005, d_rp: int = 1, d_phi: int = 3) -> dict:
    """Δχ² and ΔBIC of "spiral + free-flux compact peak at its planet", best over the instances of
    the best template within ``d_rp`` radius and ``d_phi`` azimuth steps of its best one.

    The planet's position is the spiral's (no new position parameters): 7 parameters in all.

    Parameters
    ----------
    result : ScanResult
    vis : Visibilities
        The scanned data.
    axisymmetric : AxisymmetricModel
        The scan's axisymmetric model.
    templates : sequence of SpiralTemplate
        The scanned templates, in the scan's order.
    geometry : DiscGeometry
    template : int or str, optional
        Which template (default: the overall best).
    min_width : float
        Smallest Gaussian σ of the peak [arcsec].
    d_rp, d_phi : int
        Neighbourhood searched [grid steps].

    Returns
    -------
    dict
        ``delta_chi2``, ``delta_bic`` (7 parameters), ``spiral_delta_chi2`` (the bare spiral's at
        that instance, recomputed from the visibilities), ``peak_flux`` [Jy], ``width`` [arcsec],
        ``template``, ``r_p`` [arcsec], ``phi_p`` [rad].
    """
    from ...model import perturbation_visibilities
    from ..scan.engine import ScanContext

    best = result.peak(template)
    k = best.template_index
    t = templates[k]
    v_a = axisymmetric.visibilities(vis.u, vis.v, geometry)
    resid = vis.V - v_a
    chi2_ao = chi2(v_a, vis.V, vis.weights)
    h_p = t.h_p if np.isfinite(t.h_p) else 0.07
    n_phi = len(result.phi_p)
    out = None
    for i in range(max(0, best.i_rp - d_rp), min(len(result.r_p), best.i_rp + d_rp + 1)):
        r_p = float(result.r_p[i])
        ctx = ScanContext.build(vis, axisymmetric, geometry, [r_p], 8, x_max=float(np.max(t.x)))
        quad = ctx.quadrature(t, r_p)
        width = max(float(h_p) * r_p, min_width)
        for dj in range(-d_phi, d_phi + 1):
            phi_p = float(result.phi_p[(best.i_phi + dj) % n_phi])
            dv = perturbation_visibilities(vis.u, vis.v, geometry, ctx.profile, t, r_p, phi_p, quad=quad)
            rest = resid - dv
            spiral = chi2_ao - float(np.sum(vis.weights * np.abs(rest) ** 2))
            peak = _peak_visibilities(vis.u, vis.v, geometry, r_p, phi_p, width)
            pp = float(np.sum(vis.weights * np.abs(peak) ** 2))
            rp = float(np.sum(vis.weights * np.real(np.conj(peak) * rest)))
            total = spiral + (rp * rp / pp if pp > 0 else 0.0)
            if out is None or total > out["delta_chi2"]:
                out = {"delta_chi2": float(total), "delta_bic": float(total - bic_threshold(result.n_data, 7)),
                       "spiral_delta_chi2": float(spiral), "peak_flux": float(rp / pp if pp > 0 else 0.0),
                       "width": width, "template": best.template, "r_p": r_p, "phi_p": phi_p}
    if out is None:  # only a negative d_rp or d_phi leaves the neighbourhood empty
        raise InputError(f"spiral_with_planet_peak: d_rp = {d_rp} and d_phi = {d_phi} must be >= 0")
    return out


def apply_planet_peak(verdict, alternatives, peak: dict):
    """The verdict with test 3 rescored: against each compact alternative the spiral's score is
    ``max(bare spiral, spiral + peak)`` ΔBIC, against the others the bare spiral's (module docstring)."""
    if verdict.test3_passed is None or alternatives is None:
        return verdict
    n = alternatives.n_data
    margins = {}
    for fit in alternatives.fits.values() if isinstance(alternatives.fits, dict) else alternatives.fits:
        alt_bic = float(fit.delta_bic(n))
        score = max(verdict.delta_bic, peak["delta_bic"]) if fit.name in COMPACT_ALTERNATIVES else verdict.delta_bic
        margins[fit.name] = (score - alt_bic, alt_bic, fit, score > verdict.delta_bic)
    name = min(margins, key=lambda k: margins[k][0])
    margin, alt_bic, fit, with_peak = margins[name]
    passed = bool(margin > verdict.alternative_threshold)
    detected = verdict.test1_passed and verdict.test2_passed and passed
    return dataclasses.replace(verdict, test3_passed=passed, best_alternative=fit.name,
                               best_alternative_label=fit.label,
                               alternative_delta_bic=alt_bic, delta_bic_vs_alternative=float(margin),
                               detected=bool(detected),
                               test3_spiral_model=SPIRAL_PEAK_LABEL if with_peak else "spiral",
                               planet_peak=peak)


def rescore_with_planet_peak(verdict, result, vis, axisymmetric, templates, geometry=None, *, alternatives):
    """``verdict`` with test 3 rescored with the planet's compact peak (:func:`apply_planet_peak`); the
    peak is fitted only when there are alternatives and test 1 passes (otherwise test 3 cannot change
    the verdict). ``geometry`` defaults to the axisymmetric model's."""
    if alternatives is None or not verdict.test1_passed:
        return verdict
    geometry = geometry if geometry is not None else axisymmetric.geometry
    peak = spiral_with_planet_peak(result, vis, axisymmetric, list(templates), geometry)
    return apply_planet_peak(verdict, alternatives, peak)
