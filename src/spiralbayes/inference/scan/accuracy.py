"""The scan's accuracy: its self-check against exact sums and the tolerance rule.

Every template's ``cross`` and ``power`` carry error estimates (:mod:`~spiralbayes.inference.scan.engine`): the
quadrature's bound, plus the power path's own error, which :func:`check_terms` measures once per
scan by comparing the fast terms with exact sums (ΔV at every baseline by a double-precision
NUFFT at ``EXACT_EPSILON``) at the largest radius of each uv level. :func:`warn_if_inaccurate`
raises an :class:`~spiralbayes.exceptions.AccuracyWarning` where the Δχ² estimate exceeds
``TOLERANCE[0] + TOLERANCE[1] |Δχ²|``.

Why that tolerance: the absolute part matters near the detection threshold, where ``2 cross`` and
``power`` nearly cancel: with ``power`` up to ~1e3 there, each term must be good to ~1e-5
relative; the rule aims at 1e-6, a factor 10 to spare, and the relative part covers the largest
powers (a bright planet's own peak).
"""

from __future__ import annotations

import logging
import warnings

import numpy as np

from ..._threads import blas_threads
from ...exceptions import AccuracyWarning
from .engine import CHECK_SAFETY, ScanContext, _terms_at

__all__ = ["CHECK_AZIMUTHS", "EXACT_EPSILON", "TOLERANCE", "check_terms", "exact_terms", "warn_if_inaccurate"]

log = logging.getLogger(__name__)

TOLERANCE = (0.05, 1e-4)
"""A Δχ² error estimate above ``TOLERANCE[0] + TOLERANCE[1] |Δχ²|`` raises an AccuracyWarning."""
CHECK_AZIMUTHS = 4
EXACT_EPSILON = 1e-10
"""NUFFT accuracy of the exact sums that check the power path (100x below what they check)."""


def exact_terms(context: ScanContext, flux: np.ndarray, quad, phi_index) -> tuple[np.ndarray, np.ndarray]:
    """``cross`` and ``power`` from ΔV at every baseline (double precision, ``EXACT_EPSILON``)
    for the planet azimuths ``phi_index`` (the reference of :func:`check_terms`)."""
    import ducc0

    cross, power = [], []
    for j in np.atleast_1d(phi_index):
        dV = ducc0.nufft.experimental.nu2nu(
            points_in=flux.ravel().astype(complex), coord_in=2 * np.pi * quad.positions(),
            coord_out=context.rotated_baselines(j), forward=False, epsilon=EXACT_EPSILON, nthreads=context.nthreads)
        cross.append(context.geometry.cos_inc * np.sum(context.weights * (np.conj(context.residual) * dV).real))
        power.append(context.geometry.cos_inc ** 2 * np.sum(context.weights * (dV.real ** 2 + dV.imag ** 2)))
    return np.array(cross), np.array(power)


def check_terms(context: ScanContext, template) -> dict:
    """The power path's own error: the scan's terms against exact sums (ΔV at every baseline,
    double precision) at the largest radius of each uv level (or the largest radius, direct
    path) and ``CHECK_AZIMUTHS`` azimuths.

    Returns the worst relative discrepancies ``power`` (of the power) and ``cross`` (of
    ``sqrt(chi2_AO power)``, the Cauchy-Schwarz scale of ``cross``) and what was checked; the scan
    stores it in ``context.algorithm_error`` so that every template's error estimate includes it.
    """
    groups: dict = {}
    for i, r_p in enumerate(context.r_p):
        quad = context.quadrature(template, r_p)
        groups[context.level(quad).r_out if context.power_path == "polar" else 0.0] = i  # keeps the largest
    phi_index = np.linspace(0, context.n_phi_p, CHECK_AZIMUTHS, endpoint=False).astype(int)
    worst_p = worst_c = 0.0
    for i in sorted(groups.values()):
        with blas_threads(1):
            cross, power, quad, flux = _terms_at(context, template, context.r_p[i])
        c, p = exact_terms(context, flux, quad, phi_index)
        scale = np.maximum(np.abs(p), 1e-300)
        worst_p = max(worst_p, float(np.max(np.abs(power[phi_index] - p) / scale)))
        worst_c = max(worst_c, float(np.max(np.abs(cross[phi_index] - c) / np.sqrt(context.chi2_AO * scale))))
    out = {"power": worst_p, "cross": worst_c, "r_p": [float(context.r_p[i]) for i in sorted(groups.values())],
           "phi_index": phi_index.tolist(), "template": getattr(template, "name", ""), "path": context.power_path}
    log.info("power path checked against exact sums: |d power| / power <= %.2g, |d cross| / sqrt(chi2 power) "
             "<= %.2g", worst_p, worst_c)
    return out


def _power_path_share(result, where) -> float:
    """The part of the Δχ² error estimate at the instance ``where`` (an index into ``result.cross``)
    that the power path's measured discrepancy (``provenance["power_check"]``, times
    ``CHECK_SAFETY``) makes; the rest is the quadrature's bound."""
    check = (result.provenance or {}).get("power_check") or {}
    power = max(float(result.power[where]), 0.0)
    part = CHECK_SAFETY * (2 * check.get("cross", 0.0) * np.sqrt(result.chi2_AO * power)
                           + check.get("power", 0.0) * power)
    total = float(result.delta_chi2_error()[where])
    return part / total if total > 0 else 0.0


def warn_if_inaccurate(result, tolerance=TOLERANCE, stacklevel: int = 3) -> None:
    """Log and warn (:class:`AccuracyWarning`) where ``result``'s Δχ² error estimate exceeds the
    tolerance, naming what dominates the largest estimate: the quadrature's bound (which kinks and
    jumps of the profile inside the disc inflate) or the power path's measured discrepancy."""
    bad = result.accuracy_violations(tolerance)
    if not bad.any():
        return
    t = np.flatnonzero(bad.any(axis=(1, 2)))
    names = ", ".join(result.templates[i]["name"] for i in t[:3]) + (" ..." if t.size > 3 else "")
    err = np.where(bad, np.nan_to_num(result.delta_chi2_error(), nan=0.0), -np.inf)
    where = np.unravel_index(int(np.argmax(err)), err.shape)
    if _power_path_share(result, where) >= 0.5:
        why = "mostly the power path's measured discrepancy: power_path='direct' can help"
    else:
        why = ("mostly the quadrature's bound, which kinks and jumps of the axisymmetric profile inside the disc "
               "(edges, a tabulated gap) inflate; it bounds the error from above, so compare with "
               "quadrature='midpoint' or pass a smoother profile")
    msg = (f"the Δχ² error estimate exceeds {tolerance[0]} + {tolerance[1]} |Δχ²| at {int(bad.sum())} of "
           f"{bad.size} instances (largest {np.nanmax(result.delta_chi2_error()):.3g}; templates {names}): see "
           f"result.delta_chi2_error(); the estimate is {why}")
    log.warning(msg)
    warnings.warn(msg, AccuracyWarning, stacklevel=stacklevel)
