"""``[calibration]`` in the pipeline: solve antenna gains after the frank fit, or reuse the solution a scan saved.

With ``[calibration] solve`` other than ``"none"``, ``spiralbayes scan`` self-calibrates after the frank
fit (:func:`spiralbayes.calibration.selfcal`: gain solves alternated with frank fits) and scans, judges,
bounds and samples the corrected data with the frank fit to them. The solution is saved as
``OUTPUT/gains.h5`` (with ``gains.png``); ``sample`` and ``limits`` apply it to the data they read, and
reuse it only when it was solved from these data with these settings (otherwise
:class:`~spiralbayes.exceptions.ResumeMismatchError` names what differs). The corrected data's hash is
what the scan's checkpoint and the reused frank model and scan are keyed on, so a change of the
calibration settings never resumes or reuses work done on differently corrected data.
"""

from __future__ import annotations

import logging
from pathlib import Path

from dataclasses import replace

import numpy as np

from .._provenance import data_hash
from ..axisymmetric import FrankSettings
from ..calibration import CalibrationSettings, GainSolution, selfcal
from ..exceptions import InputError, ResumeMismatchError
from ..settings import from_config
from .outputs import save_figure

__all__ = ["GAINS_FILE", "calibration_settings", "candidate_spiral", "check_calibration_input", "reusable_gains",
           "run_calibration", "run_candidate_calibration"]

log = logging.getLogger(__name__)

GAINS_FILE = "gains.h5"
"""The gain solution's file name in ``[output] dir``."""


def calibration_settings(config: dict) -> CalibrationSettings:
    """The :class:`~spiralbayes.calibration.CalibrationSettings` of a merged configuration."""
    return from_config(CalibrationSettings, config.get("calibration", {}))


def check_calibration_input(config: dict, vis) -> None:
    """Refuse a gain solve on data that record no antennas, before any fit runs."""
    s = calibration_settings(config)
    if s.enabled and not vis.has_antennas:
        raise InputError(f"[calibration] solve = {s.solve!r} needs visibilities that record their antennas and times "
                         f"(a Measurement Set or a spiralbayes .h5 file); {config['data']['path']} does not: set "
                         "[calibration] solve = 'none' (and self-calibrate with CASA first), or give a Measurement Set")


def _solution_key(vis, s: CalibrationSettings) -> dict:
    return {"data": data_hash(vis.u, vis.v, vis.V, vis.weights), "settings": {
        k: getattr(s, k) for k in ("solve", "interval_s", "min_snr", "n_iterations", "refant", "keep_position",
                                   "candidate_min_snr", "amp_iterations")}}


def run_calibration(config: dict, vis, axisymmetric, out_dir, *, progress: bool = True, save: bool = True):
    """Self-calibrate ``vis`` starting from ``axisymmetric`` and (with ``save``) save the solution in ``out_dir``.

    Returns ``(corrected visibilities, frank fit to them, GainSolution)``; with ``solve = "none"``
    ``(vis, axisymmetric, None)``. ``save=False`` when a second solve
    (:func:`run_candidate_calibration`) will replace it: an interrupted scan then leaves no first
    solution that ``limits`` or ``sample`` would take for the final one.
    """
    s = calibration_settings(config)
    if not s.enabled:
        return vis, axisymmetric, None
    check_calibration_input(config, vis)
    frank = from_config(FrankSettings, config["frank"])
    result = selfcal(vis, axisymmetric.geometry, settings=s, model=axisymmetric, frank=frank, progress=progress)
    return _save(config, vis, result, out_dir, write=save)


def candidate_spiral(scan_result, vis, axisymmetric, templates, amplitude=None) -> tuple[np.ndarray, dict]:
    """The visibilities [Jy] of a scan's best spiral and what it is.

    The best instance of ``scan_result`` for ``amplitude`` (None: the paper's fixed amplitude 1;
    ``"free"``: the fitted ``max(cross / power, 0)``), transformed exactly
    (:func:`spiralbayes.model.perturbation_visibilities`) at the baselines of ``vis`` with
    ``axisymmetric``'s profile and geometry. Returns ``(ΔV, description)``, the description holding the
    template, ``r_p_arcsec``, ``phi_p_deg``, ``amplitude`` and the peak's ``delta_bic``.
    """
    from ..inference.scan.statistics import fitted_amplitude
    from ..model import perturbation_visibilities

    peak = scan_result.peak(amplitude=amplitude)
    t, i, j = peak.template_index, peak.i_rp, peak.i_phi
    a = float(fitted_amplitude(scan_result.cross[t, i, j], scan_result.power[t, i, j], amplitude))
    vis = vis.standardised()
    dv = perturbation_visibilities(vis.u, vis.v, axisymmetric.geometry, axisymmetric.brightness, list(templates)[t],
                                   peak.r_p, peak.phi_p)
    about = {"template": peak.template, "r_p_arcsec": peak.r_p, "phi_p_deg": float(np.degrees(peak.phi_p)),
             "amplitude": a, "delta_bic": peak.delta_bic}
    return a * dv, about


def run_candidate_calibration(config: dict, vis, axisymmetric, scan_result, templates, out_dir, *,
                              amplitude=None, progress: bool = True):
    """Solve the gains of the original data ``vis`` again, against ``axisymmetric`` plus the best spiral of
    ``scan_result`` (a scan of the data corrected by :func:`run_calibration`), down to
    ``[calibration] candidate_min_snr``, and save the solution in ``out_dir``.

    With the candidate in the model the solve does not take it for a gain error, so it can use the
    faint visibilities (long baselines), where a spiral is bright against the disc and where, at
    ``min_snr``, antennas are left unsolved (docs/calibration.md). Returns ``(corrected visibilities,
    frank fit to them, GainSolution)``.
    """
    s = calibration_settings(config)
    spiral, about = candidate_spiral(scan_result, vis, axisymmetric, templates, amplitude)
    log.info("second gain solve (model S/N >= %g) with the scan's best spiral in the model: %s at r_p = %.3g arcsec, "
             "phi_p = %.0f deg, amplitude %.3g", s.candidate_min_snr, about["template"], about["r_p_arcsec"],
             about["phi_p_deg"], about["amplitude"])
    frank = from_config(FrankSettings, config["frank"])
    result = selfcal(vis, axisymmetric.geometry, settings=replace(s, min_snr=s.candidate_min_snr),
                     model=axisymmetric, spiral=spiral, frank=frank, progress=progress)
    return _save(config, vis, result, out_dir, candidate=about)


def _save(config: dict, vis, result, out_dir, candidate: dict | None = None, write: bool = True):
    s = calibration_settings(config)
    model = result.model.nonnegative() if config["frank"]["nonnegative"] else result.model
    solution = result.solution
    solution.provenance = {"solved_from": _solution_key(vis, s), "phase_rms_deg_by_round": result.phase_rms_deg}
    if candidate is not None:
        solution.provenance["candidate"] = candidate
    log.info("%s", result.summary())
    if not write:
        return result.corrected, model, solution
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    solution.save(out_dir / GAINS_FILE)
    if config["output"].get("plots", True):
        from ..plotting.calibration import plot_gain_phases

        save_figure(plot_gain_phases(solution), out_dir / "gains.png")
    return result.corrected, model, solution


def reusable_gains(config: dict, vis, out_dir, *, required: bool = False):
    """``(corrected vis, GainSolution)`` from ``OUTPUT/gains.h5`` when it was solved from ``vis`` with this
    configuration's ``[calibration]`` settings; ``(vis, None)`` when calibration is off, or when the file is
    absent and not ``required``. A file for other data or settings raises ResumeMismatchError."""
    s = calibration_settings(config)
    path = Path(out_dir) / GAINS_FILE
    if not s.enabled:
        return vis, None
    check_calibration_input(config, vis)
    if not path.exists():
        if required:
            raise ResumeMismatchError(f"[calibration] solve = {s.solve!r} but {path} is missing: run 'spiralbayes "
                                      "scan' with this configuration first (it solves and saves the gains)")
        return vis, None
    solution = GainSolution.load(path)
    have, want = (solution.provenance or {}).get("solved_from", {}), _solution_key(vis, s)
    diffs = []
    if have.get("data") != want["data"]:
        diffs.append("the data (u, v, V or weights)")
    changed = [f"{k}: {have.get('settings', {}).get(k)!r} -> {v!r}" for k, v in want["settings"].items()
               if have.get("settings", {}).get(k) != v]
    if changed:
        diffs.append(f"[calibration] settings ({', '.join(changed)})")
    if diffs:
        raise ResumeMismatchError(f"{path} was solved for other inputs — {'; '.join(diffs)}: run 'spiralbayes scan' "
                                  "with this configuration first (it solves the gains again), or use another "
                                  "[output] dir")
    return solution.apply(vis), solution
