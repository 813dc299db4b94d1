"""Follow-up when the geometry error explains the data: refit frank there, scan again, decide again.

A phase-centre error of 10 mas on a disc with a 1 M_th planet (Δχ² ≈ 5,500 at the right geometry)
makes the scan's global peak a false, unhanded one (Δχ² ≈ 2,350) that test 2 rejects, while the
planet itself is never reported (Stevenson et al. 2024, App. A; issues 13 and 15). The geometry
alternative of test 3 measures the error; :func:`rescan_at_fitted_geometry` takes its geometry,
refits the axisymmetric profile there with the same frank hyperparameters, rescans the same
templates and grid, refits the alternatives and returns the new verdict
(``tests/inference/detection/test_scenarios.py`` checks that the planet is then detected).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ...axisymmetric import fit_axisymmetric
from ...axisymmetric.model import DEFAULT_HYPERPARAMETERS
from ...geometry import DiscGeometry
from .alternatives import AlternativesResult, fit_alternatives
from .planet_peak import detect_with_planet_peak
from .verdict import Verdict
from ..scan.run import ScanResult, scan

__all__ = ["GeometryFollowUp", "frank_settings", "rescan_at_fitted_geometry"]

log = logging.getLogger(__name__)

FRANK_KEYS = ("N", "Rmax", "alpha", "p0", "weights_smooth", "method", "nonnegative")


@dataclass
class GeometryFollowUp:
    """The geometry used, the refitted frank model, the new scan, alternatives and verdict."""

    geometry: DiscGeometry
    axisymmetric: object
    scan: ScanResult
    alternatives: AlternativesResult | None
    verdict: Verdict


def frank_settings(axisymmetric) -> dict:
    """The frank hyperparameters of a fitted model (paper defaults where it records none)."""
    hyper = dict(getattr(axisymmetric, "hyperparameters", {}) or {})
    out = {k: hyper[k] for k in FRANK_KEYS if k in hyper}
    for k, v in DEFAULT_HYPERPARAMETERS.items():
        out.setdefault(k, v)
    return out


def rescan_at_fitted_geometry(vis, axisymmetric, templates, alternatives: AlternativesResult, *,
                              r_p=None, n_phi_p: int | None = None, distance: float | None = None,
                              amplitude=None, refit_alternatives: bool = True, nthreads: int = 1,
                              progress: bool = False, frank_kwargs: dict | None = None,
                              alternative_kwargs: dict | None = None, detect_kwargs: dict | None = None,
                              previous_scan: ScanResult | None = None, refit=None, **scan_kwargs) -> GeometryFollowUp:
    """Refit the profile at the geometry alternative's geometry, rescan and decide again.

    Parameters
    ----------
    vis : Visibilities
        The data.
    axisymmetric : AxisymmetricModel
        The model the first scan used; its frank hyperparameters are reused (``frank_kwargs``
        overrides them).
    templates : sequence of SpiralTemplate
        The templates to scan (normally the first scan's).
    alternatives : AlternativesResult
        Must include the ``geometry`` alternative; its fitted geometry is used.
    r_p, n_phi_p, distance
        The scan grid; by default those of ``previous_scan`` when given.
    amplitude : None or "free"
        As in :func:`~spiralbayes.inference.detection.detect`.
    refit : callable, optional
        ``refit(geometry) -> axisymmetric model`` to use instead of a frank fit (e.g. an exact
        model in injection tests).
    refit_alternatives : bool
        Fit the alternatives again at the new geometry (test 3 of the new verdict).
    **scan_kwargs
        Passed to :func:`~spiralbayes.inference.scan.scan` (``client``, ``cell_factor``, ...).
    """
    geometry = alternatives.fitted_geometry()
    log.info("refitting at the geometry alternative's geometry: inc %.3f, PA %.3f deg, dRA %.2f, dDec %.2f mas",
             geometry.inc, geometry.PA, geometry.dRA * 1e3, geometry.dDec * 1e3)
    if refit is not None:
        new_axisym = refit(geometry)
    else:
        settings = {**frank_settings(axisymmetric), **(frank_kwargs or {})}
        new_axisym = fit_axisymmetric(vis, geometry, progress=progress, **settings)
        if settings.get("nonnegative") and getattr(axisymmetric, "hyperparameters", {}).get("profile") == "nonnegative":
            new_axisym = new_axisym.nonnegative()
    if previous_scan is not None:
        r_p = previous_scan.r_p if r_p is None else r_p
        n_phi_p = previous_scan.phi_p.size if n_phi_p is None else n_phi_p
        distance = previous_scan.distance if distance is None else distance
    new_scan = scan(vis, new_axisym, templates, geometry, r_p=None if r_p is None else np.asarray(r_p),
                    n_phi_p=n_phi_p or 90, distance=distance, progress=progress, nthreads=nthreads, **scan_kwargs)
    new_alts = None
    if refit_alternatives:
        kwargs = {"nthreads": nthreads, **(alternative_kwargs or {})}
        new_alts = fit_alternatives(vis, new_axisym, geometry, **kwargs)
    verdict = detect_with_planet_peak(new_scan, vis, new_axisym, templates, geometry, amplitude, alternatives=new_alts,
                                      **(detect_kwargs or {}))
    return GeometryFollowUp(geometry, new_axisym, new_scan, new_alts, verdict)
