"""What the verdict names as the cause of the residual structure, and the summary's sentences for it.

* the nested test's sentence (:mod:`.nested`): the spiral's BIC gain over the alternative alone,
  the alternative named as also present when it survives the joint fit, the single-model numbers
  as information;
* calibration: a residual antenna gain error measured by
  :func:`spiralbayes.calibration.diagnose_calibration` also makes structure that the asymmetry
  models and the spiral templates fit in part. When the diagnostic warns and no spiral is claimed,
  it is repeated with the best significant alternative in the model (an unmodelled disc asymmetry
  leaves antenna-like residuals too); if it still warns, calibration is named as the explanation,
  with what to do;
* a spiral that passes tests 1-3 while the diagnostic reports antenna *phase* errors is checked
  again with the spiral in the model (:func:`rediagnose_with_spiral`): a planet's own structure
  leaves antenna-like residuals against the axisymmetric model, calibration errors remain with it.
  If they remain, no planet is claimed (``calibration["withheld"]``): spirals fitted to calibration
  structure are not planets, and those found in such data come with the wrong mass and position
  (docs/calibration.md). The amplitude part of the diagnostic does not withhold a claim: a 1 M_th
  planet in fiducial data with 5 % amplitude errors is claimed at the right mass and place.
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np

from .settings import DELTA_BIC_THRESHOLD

__all__ = ["calibration_explains", "calibration_sentence", "explain", "nested_sentence", "phase_warns", "rediagnose",
           "rediagnose_with_spiral", "withhold"]

log = logging.getLogger(__name__)


def calibration_explains(verdict) -> bool:
    """Does the verdict name calibration errors as the explanation?"""
    return bool(verdict.calibration and verdict.calibration.get("explains"))


def nested_sentence(verdict) -> str:
    """Test 3's sentence of the summary when it was the nested test."""
    fits = verdict.nested or []
    if not fits:
        return ""
    f = min(fits, key=lambda x: x["delta_bic"])
    names = " and ".join(x["label"] for x in fits)
    stat, thr = verdict.nested_delta_bic, verdict.nested_threshold
    other = verdict.nested_template
    other = f", template {other}" if other and other != verdict.template else ""
    spiral = f"the spiral ({f['hypothesis']}, {f['n_spiral_params']} parameters{other})"
    text = f" Test 3 (nested, against the {names} model{'s' if len(fits) > 1 else ''}): "
    if f["delta_bic_spiral_alone"] > f["delta_bic_joint"]:
        text += (f"the best spiral alone has a BIC lower by {stat:.1f} than the {f['label']} model alone "
                 f"(fitted jointly with it, {spiral} by {f['delta_bic_joint']:.1f})")
    else:
        text += f"fitted jointly with the {f['label']} model, {spiral} lowers its BIC by {stat:.1f}"
    text += f" (> {thr:g})." if stat > thr else f", not more than {thr:g}."
    also = next((x for x in fits if x.get("survives")), None)
    if verdict.also_present and also is not None:
        text += (f" The data hold a spiral and {verdict.also_present} (the {also['label']} model: Delta BIC = "
                 f"{also['alternative_delta_bic']:.1f} on its own, "
                 f"{also['alternative_delta_bic_given_spiral']:.1f} with the spiral in the model).")
        if also["alternative"] == "geometry":
            text += (" The scan placed the templates at the unfitted geometry, so no planet is claimed at this "
                     "position: rescan at the fitted geometry (sb.rescan_at_fitted_geometry; spiralbayes scan "
                     "does it).")
    elif (not verdict.test3_passed and f["alternative_delta_bic"] > DELTA_BIC_THRESHOLD
          and not calibration_explains(verdict)):
        what = "explains the structure" if stat < 0 else "is about as good an explanation"
        text += (f" The {f['label']} model {what} (Delta BIC = {f['alternative_delta_bic']:.1f} against the "
                 "axisymmetric disc).")
        if f["alternative"] == "geometry":
            text += " Refit the geometry and scan again (sb.rescan_at_fitted_geometry)."
            if getattr(verdict, "gains_solved", None):
                text += (" After a gain solve an offset of the disc is also what the calibration errors' mean phase "
                         "gradient leaves in the data: [calibration] keep_position leaves it to the sky model.")
    if verdict.delta_bic_vs_alternative is not None:
        peak = " + compact peak" if verdict.test3_spiral_model != "spiral" else ""
        text += (f" As single models the best spiral{peak} scores Delta BIC = "
                 f"{verdict.delta_bic_vs_alternative:+.1f} against the best competing model "
                 f"({verdict.best_alternative_label}, Delta BIC = {verdict.alternative_delta_bic:.1f}); "
                 "for information.")
    return text


def calibration_sentence(verdict) -> str:
    """The calibration sentence of the summary: calibration as the explanation when no spiral is
    claimed, a caution when one is and the diagnostic warns; empty otherwise."""
    c = verdict.calibration
    if not c or not c.get("warning"):
        return ""
    measured = ("" if c.get("phase_rms_deg") is None else
                f"residual antenna phase rms {c['phase_rms_deg']:.3g} deg and amplitude rms "
                f"{100 * c['amp_rms']:.3g} %, ")
    if c.get("withheld"):
        again = c.get("with_alternative") or {}
        return (f" Calibration: the residuals show {measured}reduced chi2 {c['reduced_chi2']:.3g}, and antenna "
                f"phase errors of {again.get('phase_rms_deg', float('nan')):.3g} deg rms remain with the spiral in "
                "the model, so the spiral is not claimed: antenna gain errors make structure that spiral templates "
                f"fit. {_fix(c).capitalize()}, and scan again.")
    if verdict.detected:
        return (f" Calibration: the residuals also show {measured}reduced chi2 {c['reduced_chi2']:.3g}: "
                f"{_fix(c)}, and confirm the spiral in the calibrated data.")
    if not calibration_explains(verdict):
        return ""
    return (f" Calibration: the residuals show {measured}reduced chi2 {c['reduced_chi2']:.3g}, so antenna gain "
            "errors rather than a disc asymmetry are the likely explanation of the residual structure: "
            f"{_fix(c)}, and scan again.")


def _fix(c: dict) -> str:
    """What to do about the errors the diagnostic ``c`` found: the amplitudes need their own solve."""
    from ...calibration.diagnostics import AMP_WARN, PHASE_WARN_DEG, exceeds_warning

    if exceeds_warning(c.get("amp_rms"), c.get("amp_significance"), AMP_WARN) and not exceeds_warning(
            c.get("phase_rms_deg"), c.get("phase_significance"), PHASE_WARN_DEG):
        return 'self-calibrate the amplitudes too, or set [calibration] solve = "amplitude+phase"'
    return "self-calibrate, or set [calibration] solve"


def rediagnose(calibration, vis, axisymmetric, geometry, alternatives):
    """The diagnostic repeated with the best significant alternative in the model: a real disc
    asymmetry, unmodelled, also leaves antenna-like residuals, so calibration is named only when they
    remain once the asymmetry is modelled (``calibration.warning`` None otherwise)."""
    from ...calibration import diagnose_calibration

    best = alternatives.best
    if best.delta_bic(alternatives.n_data) <= DELTA_BIC_THRESHOLD:
        return calibration
    vis = vis.standardised()
    geometry = geometry if geometry is not None else alternatives.geometry
    model = (np.asarray(axisymmetric.visibilities(vis.u, vis.v, geometry))
             + alternatives.model_visibilities(best.name, vis, axisymmetric))
    again = diagnose_calibration(vis, model)
    log.info("calibration diagnostic with the %s model: %s", best.name, again.summary())
    return again


def phase_warns(calibration) -> bool:
    """Does a diagnostic measure antenna phase errors above its warning level, significantly?"""
    from ...calibration.diagnostics import PHASE_WARN_DEG, exceeds_warning

    return exceeds_warning(getattr(calibration, "phase_rms_deg", None),
                           getattr(calibration, "phase_significance", None), PHASE_WARN_DEG)


def rediagnose_with_spiral(vis, axisymmetric, template, r_p: float, phi_p: float, geometry, amplitude: float = 1.0):
    """The diagnostic with the spiral (``template`` at ``r_p`` [arcsec], ``phi_p`` [rad], times
    ``amplitude``) added to the axisymmetric model (exact transform,
    :func:`spiralbayes.model.perturbation_visibilities`)."""
    from ...calibration import diagnose_calibration
    from ...model import perturbation_visibilities

    vis = vis.standardised()
    geometry = geometry if geometry is not None else axisymmetric.geometry
    spiral = perturbation_visibilities(vis.u, vis.v, geometry, axisymmetric.brightness, template, r_p, phi_p)
    model = np.asarray(axisymmetric.visibilities(vis.u, vis.v, geometry)) + amplitude * spiral
    again = diagnose_calibration(vis, model)
    log.info("calibration diagnostic with the spiral in the model: %s", again.summary())
    return again


def withhold(verdict):
    """``verdict`` with its claim withdrawn (tests kept as they are): calibration errors remain."""
    return dataclasses.replace(verdict, detected=False)


def explain(verdict, calibration, again=None, alternative: str | None = None, withheld: bool = False):
    """Record the calibration diagnostic and what the verdict names as the residual structure's cause.

    ``again`` is the diagnostic repeated with the ``alternative`` in the model (:func:`rediagnose`);
    calibration is the explanation when the diagnostic (repeated, if it was) still warns and there is
    structure to explain (test 1 passes or an alternative is significant against the disc).
    """
    keys = ("phase_rms_deg", "amp_rms", "phase_significance", "amp_significance", "reduced_chi2", "warning")
    cal = None
    if calibration is not None:
        cal = {k: getattr(calibration, k) for k in keys}
        # only structure needs explaining: a spiral or an alternative significant against the disc
        structure = bool(verdict.test1_passed or (verdict.alternative_delta_bic is not None
                                                   and verdict.alternative_delta_bic > DELTA_BIC_THRESHOLD))
        cal["explains"] = bool((again if again is not None else calibration).warning) and structure
        if again is not None and again is not calibration:
            cal["with_alternative"] = {"model": alternative, **{k: getattr(again, k) for k in keys}}
        if withheld:
            cal["withheld"] = True
    if verdict.detected:
        why = "spiral"
    elif cal is not None and cal["explains"]:
        why = "calibration"
    elif verdict.alternative_delta_bic is not None and verdict.alternative_delta_bic > DELTA_BIC_THRESHOLD:
        why = verdict.best_alternative
    else:
        why = None
    return dataclasses.replace(verdict, calibration=cal, explanation=why)
