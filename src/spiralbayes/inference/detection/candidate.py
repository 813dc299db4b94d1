"""A compact source that the verdict cannot attribute: the *candidate* outcome.

At low optical depth most of a planet's Δχ² sits in its compact near-planet peak, which an arc or
vortex also fits. Where test 3 then cannot tell the two apart, "no spiral is claimed" would hide a
source that is plainly in the data. The verdict names it instead (``Verdict.compact_source``,
``Verdict.outcome == "candidate"``), with the models that explain it, so that the posterior odds
between them (:func:`spiralbayes.sample_posterior` with ``alternatives=``) and deeper data can decide.

Two ways a compact source is named (nothing is named when a spiral is claimed, when calibration
errors explain the residuals, or when a geometry error survives beside the spiral — the scan must
then be repeated at the fitted geometry first):

* **the spiral's peak** (``origin == "spiral"``): tests 1 and 2 pass (a significant, compact and
  handed peak) and test 3 fails, but not by much: its statistic (the nested ΔBIC) exceeds
  ``candidate_threshold``. The explanations are the spiral with its near-planet peak and every
  alternative test 3 compared it with.
* **a compact arc** (``origin == "arc"``), otherwise: the arc/vortex alternative is significant
  (ΔBIC > ``bic_threshold_value`` against the axisymmetric disc), compact (azimuthal width σ_φ ≤
  ``compact_arc_width``) and not beaten by another alternative by more than ``bic_threshold_value``.
  A planet whose spiral the bank does not hold shows this way: its near-planet peak (or the dust it
  gathers) is what the data see.

The source's flux is the positive excess of the arc model at its best fit (its brightness above the
axisymmetric disc, projected on the sky) when the arc lies at the source (within
``max(2 σ_r, 0.15 r)``); otherwise the compact peak that test 3's joint fit gave the planet.
Thresholds and their false-alarm rate: docs/verdict.md, "Candidates".
"""

from __future__ import annotations

import numpy as np

from ...units import ARCSEC

__all__ = ["OUTCOMES", "arc_excess_flux", "compact_source", "deeper_time_factor", "explanation_labels",
           "next_steps_sentence"]

OUTCOMES = ("detected", "candidate", "not detected")
"""The verdict's outcomes (:attr:`~spiralbayes.inference.detection.verdict.Verdict.outcome`)."""

SPIRAL_LABEL = "a planet's spiral with its near-planet peak"
ARC_KEYS = {"contrast", "r_c", "phi_c_deg", "sigma_r", "sigma_phi_deg"}
"""The arc fit's values a candidate needs (:meth:`~spiralbayes.alternatives.fields.ArcModel.describe`)."""
ARC_ORIGIN_LABELS = ("an arc/vortex", "a planet's near-planet peak (its spiral not among the templates)")


def arc_excess_flux(params: dict, brightness, cos_inc: float, n_phi: int = 720, n_r: int = 201) -> float:
    """Positive excess flux [Jy] of a fitted arc: ``∫ max(P, 0) dA cos i`` on the sky.

    Parameters
    ----------
    params : dict
        The arc's fitted values as :meth:`~spiralbayes.alternatives.fields.ArcModel.describe` gives
        them (``contrast``, ``r_c`` and ``sigma_r`` [arcsec], ``phi_c_deg``, ``sigma_phi_deg``).
    brightness : callable
        ``I_A(r [arcsec])`` [Jy/sr], the axisymmetric disc the contrast is relative to.
    cos_inc : float
        Projection of the disc onto the sky.
    """
    r_c, s_r = float(params["r_c"]), abs(float(params["sigma_r"]))
    s_phi = np.radians(float(params["sigma_phi_deg"]))
    r = np.linspace(max(r_c - 5 * s_r, 0.0), r_c + 5 * s_r, n_r)
    phi = np.linspace(-np.pi, np.pi, n_phi, endpoint=False)
    radial = float(params["contrast"]) * brightness(r) * np.exp(-0.5 * ((r - r_c) / s_r) ** 2)
    azim = np.exp((np.cos(phi) - 1) / s_phi ** 2)
    # the field's ring mean is removed (frank's profile holds the axisymmetric part), as in the fit
    P = radial[:, None] * (azim - azim.mean())[None, :]
    dr, dphi = r[1] - r[0], 2 * np.pi / n_phi
    return float(np.sum(np.clip(P, 0.0, None) * r[:, None]) * dr * dphi * ARCSEC ** 2 * cos_inc)


def _arc_near(params: dict, r: float, phi_deg: float) -> bool:
    d = abs(params["r_c"] * np.exp(1j * np.radians(params["phi_c_deg"])) - r * np.exp(1j * np.radians(phi_deg)))
    return bool(d <= max(2 * abs(params["sigma_r"]), 0.15 * r))


def explanation_labels(verdict, origin: str) -> list[str]:
    """The models that explain a compact source of ``origin``, in words."""
    if origin == "arc":
        return list(ARC_ORIGIN_LABELS)
    labels = [SPIRAL_LABEL]
    for fit in verdict.nested or []:
        if fit["label"] not in labels:
            labels.append(fit["label"])
    return labels


def _spiral_flux(verdict, arc, brightness, cos_inc) -> tuple[float | None, str | None]:
    if arc is not None and set(arc.get("params") or ()) >= ARC_KEYS and _arc_near(arc["params"], verdict.r_p,
                                                                                    verdict.phi_p_deg):
        return arc_excess_flux(arc["params"], brightness, cos_inc), "arc model's excess at its best fit"
    peaks = [f.get("peak_flux", 0.0) for f in verdict.nested or [] if "peak" in f.get("hypothesis", "")]
    if peaks and max(peaks) > 0:
        return float(max(peaks)), "compact peak at the planet in test 3's joint fit"
    return None, None


def compact_source(verdict, axisymmetric=None, settings=None) -> dict | None:
    """The compact source a verdict should name, or None (see the module docs).

    Parameters
    ----------
    verdict : Verdict
        After tests 1-3 and the calibration explanation.
    axisymmetric : AxisymmetricModel, optional
        For the source's flux (None: the flux is not given).
    settings : DetectionSettings, optional
        ``candidate_threshold``, ``compact_arc_width`` and ``bic_threshold_value`` (default ones).

    Returns
    -------
    dict or None
        ``origin`` ("spiral" or "arc"), ``r`` [arcsec], ``r_au`` (with a distance), ``phi_deg``,
        ``flux_mJy`` and ``flux_from``, ``explained_by`` (labels), ``delta_bic`` (the spiral's or the arc's
        against the axisymmetric disc), ``nested_delta_bic`` (test 3's statistic, spiral origin) and
        ``next_steps`` (what to do with it).
    """
    from .explanation import calibration_explains
    from .settings import DetectionSettings

    s = settings or DetectionSettings()
    if verdict.detected or calibration_explains(verdict) or (verdict.calibration or {}).get("withheld"):
        return None
    alts = verdict.alternatives or {}
    if any(f["alternative"] == "geometry" and f.get("survives") for f in verdict.nested or []):
        return None
    brightness = None if axisymmetric is None else axisymmetric.brightness
    cos_inc = None if axisymmetric is None else axisymmetric.geometry.cos_inc
    arc = alts.get("arc")
    out: dict | None = None
    if (verdict.test1_passed and verdict.test2_passed and verdict.test3_method == "nested"
            and verdict.nested_delta_bic is not None and verdict.nested_delta_bic > s.candidate_threshold):
        flux, source = (None, None) if brightness is None else _spiral_flux(verdict, arc, brightness, cos_inc)
        out = {"origin": "spiral", "r": float(verdict.r_p), "phi_deg": float(verdict.phi_p_deg),
               "delta_bic": float(verdict.delta_bic), "nested_delta_bic": float(verdict.nested_delta_bic),
               "template": verdict.template, "flux_mJy": None if flux is None else 1e3 * flux, "flux_from": source}
    elif arc is not None and set(arc.get("params") or ()) >= ARC_KEYS:
        best = max((a["delta_bic"] for a in alts.values()), default=-np.inf)
        p = arc["params"]
        if (arc["delta_bic"] > s.bic_threshold_value and p["sigma_phi_deg"] <= s.compact_arc_width
                and arc["delta_bic"] >= best - s.bic_threshold_value):
            flux = None if brightness is None or cos_inc is None else arc_excess_flux(p, brightness, cos_inc)
            out = {"origin": "arc", "r": float(p["r_c"]), "phi_deg": float(p["phi_c_deg"]) % 360.0,
                   "delta_bic": float(arc["delta_bic"]), "nested_delta_bic": None, "template": None,
                   "flux_mJy": None if flux is None else 1e3 * flux,
                   "flux_from": None if flux is None else "arc model's excess at its best fit"}
    if out is None:
        return None
    out["r_au"] = None if verdict.distance is None else out["r"] * verdict.distance
    out["explained_by"] = explanation_labels(verdict, out["origin"])
    out["deeper_time_factor"] = deeper_time_factor(verdict, s.nested_threshold) if out["origin"] == "spiral" else None
    out["next_steps"] = next_steps_sentence(out)
    return out


def deeper_time_factor(verdict, threshold: float) -> float | None:
    """Factor ``f`` of the time on source after which test 3's statistic would pass ``threshold`` if the
    spiral is real: its Δχ² gain over the binding alternative grows as ``f`` (weights ∝ time at fixed uv
    coverage, as :func:`~spiralbayes.inference.limits.forecasting.forecast` assumes) and its penalty
    as ``k ln (f N)``. None when the gain is not positive (more data of the same kind would not help)."""
    from scipy.optimize import brentq

    fits = verdict.nested or []
    if not fits:
        return None
    f = min(fits, key=lambda x: x["delta_bic"])
    n = np.exp(verdict.threshold_6lnN / 6.0)  # N from 6 ln N
    k = f["n_spiral_params"]
    gain = verdict.nested_delta_bic + k * np.log(n)
    if not gain > 0:
        return None
    score = lambda t: t * gain - k * np.log(t * n) - threshold  # noqa: E731
    if score(1.0) > 0:
        return 1.0
    hi = 2.0
    while score(hi) <= 0 and hi < 1e6:
        hi *= 2
    return float(brentq(score, 1.0, hi)) if score(hi) > 0 else None


def next_steps_sentence(source: dict) -> str:
    """What a user can do with a candidate: the posterior odds, then deeper data."""
    text = ("Next: weigh the explanations with the posterior odds (sb.sample_posterior(vis, disc, templates, "
            "alternatives=('arc', 'eccentric_ring')), or [sample] alternatives for spiralbayes sample), which "
            "report P(planet), P(arc) and P(ring)")
    f = source.get("deeper_time_factor")
    if f is not None:
        text += (f"; if it is a planet, data {f:.1f} times as deep (time on source at the same uv coverage, "
                 "sb.forecast's linear scaling) would pass test 3")
    return text + ("; a vortex's dust trap and a planet's spiral also differ between wavelengths (dust trapping "
                   "concentrates larger grains).")
