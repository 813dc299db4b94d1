"""``spiralbayes scan``: the scan, test 3 and the geometry follow-up from a configuration."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

from .._provenance import data_hash
from ..config import describe_config
from ..exceptions import InputError
from ..calibration import GainSolution
from ..inference.detection.alternatives import AlternativesResult, fit_alternatives
from ..inference.detection.settings import AlternativesSettings
from ..inference.detection.follow_up import GeometryFollowUp, rescan_at_fitted_geometry
from ..inference.detection.verdict import Verdict, detect_with_planet_peak
from ..inference.detection.verdict import DELTA_BIC_THRESHOLD
from ..inference.scan.run import ScanResult, scan
from ..inference.scan.settings import ScanSettings
from ..settings import from_config
from .calibrate import (calibration_settings, check_calibration_input, run_calibration,
                        run_candidate_calibration)
from .inputs import _geometry, load_axisymmetric, load_data, load_templates
from .outputs import _write_text, check_output_folder, write_scan_outputs

__all__ = ["ScanRun", "check_dask_address", "run_scan", "run_scan_config", "scan_settings"]

log = logging.getLogger(__name__)


@dataclass
class ScanRun:
    """What :func:`run_scan` produced: the verdict, scan, alternatives, geometry follow-up, files, and the
    antenna gain solution (None unless ``[calibration] solve`` asked for one)."""

    verdict: Verdict
    scan: ScanResult
    alternatives: AlternativesResult | None
    follow_up: GeometryFollowUp | None
    files: list
    gains: GainSolution | None = None


def run_scan_config(config: dict, *, progress: bool = True, force_resume: bool = False):
    """Run a scan described by a merged configuration (:func:`spiralbayes.config.load_config`).

    Returns ``(verdict, scan, files)`` of the scan at the configured geometry; :func:`run_scan`
    (which this calls) also returns the alternatives and the geometry follow-up.
    """
    run = run_scan(config, progress=progress, force_resume=force_resume)
    return run.verdict, run.scan, run.files


def run_scan(config: dict, *, progress: bool = True, force_resume: bool = False, overwrite: bool = False) -> ScanRun:
    """The scan of a configuration, the alternatives of test 3, the verdict and, when needed, the follow-up.

    A checkpoint left in ``[output] dir`` is checked for integrity before anything slow runs,
    and resumed only if it was written for the same inputs (``force_resume`` overrides; see
    :func:`~spiralbayes.inference.scan.run.scan`). Writes the scan's outputs to ``[output] dir``
    (:func:`write_scan_outputs`). With ``[alternatives] refit_geometry`` on, no detection and the
    geometry alternative significant (ΔBIC > 10), frank is refitted at the fitted geometry and the
    scan, alternatives and verdict are repeated there
    (:func:`~spiralbayes.inference.detection.follow_up.rescan_at_fitted_geometry`), with their outputs and
    ``axisymmetric.h5`` in ``OUTPUT/refit_geometry/``. With ``[calibration] solve`` set, antenna gains are
    solved after the frank fit (:mod:`.calibrate`; ``OUTPUT/gains.h5``) and everything after runs on the
    corrected data with frank's fit to them; the verdict says so. Unless ``[calibration] candidate_min_snr``
    is 0, the corrected data are scanned once first and the gains solved again with that scan's best
    spiral in the model (:func:`~spiralbayes.pipeline.calibrate.run_candidate_calibration`). An
    ``[output] dir`` holding a scan of other data is refused before frank and the scan run, unless ``overwrite``
    (:func:`~spiralbayes.pipeline.outputs.check_output_folder`).
    """
    out_dir = Path(config["output"]["dir"])
    settings = scan_settings(config)
    calibration_settings(config)  # checked before any data are read
    checkpoint = out_dir / "scan_checkpoint.h5" if settings.checkpoint else None
    if checkpoint is not None and checkpoint.exists():
        ScanResult.load(checkpoint)  # a truncated or foreign file fails now, not after the frank fit
    scheduler = config["scan"]["scheduler"] or None
    check_dask_address(scheduler or "")
    vis = load_data(config["data"], _geometry(config), config=config)
    check_calibration_input(config, vis)
    check_output_folder(out_dir, data_hash(vis.u, vis.v, vis.V, vis.weights), overwrite)
    axisym = load_axisymmetric(config, vis, progress=progress)
    raw = vis
    second_solve = calibration_settings(config).enabled and calibration_settings(config).candidate_min_snr > 0
    vis, axisym, gains = run_calibration(config, vis, axisym, out_dir, progress=progress, save=not second_solve)
    templates = load_templates(config["templates"], progress=progress)
    out_dir.mkdir(parents=True, exist_ok=True)
    amplitude = settings.free_amplitude
    scan_kwargs = {"settings": settings, "distance": config["geometry"]["distance"], "scheduler": scheduler,
                   "progress": progress, "force_resume": force_resume}
    if second_solve:
        first = scan(vis, axisym, templates, axisym.geometry, **scan_kwargs,
                     checkpoint=None if checkpoint is None else out_dir / "selfcal_scan_checkpoint.h5")
        vis, axisym, gains = run_candidate_calibration(config, raw, axisym, first, templates, out_dir,
                                                       amplitude=amplitude, progress=progress)
    result = scan(vis, axisym, templates, axisym.geometry, checkpoint=checkpoint, **scan_kwargs)
    a = config["alternatives"]
    alt_kwargs = {"settings": from_config(AlternativesSettings, a, nthreads=settings.nthreads), "progress": progress}
    alts = fit_alternatives(vis, axisym, axisym.geometry, **alt_kwargs) if a["fit"] else None
    detect_kwargs = {"alternative_threshold": a["threshold"], "mstar": config["limits"]["mstar"]}
    verdict = detect_with_planet_peak(result, vis, axisym, templates, axisym.geometry, amplitude, alternatives=alts,
                                      **detect_kwargs)
    if gains is not None:
        verdict.gains_solved = gains.note()
        result.provenance["uncorrected_data_hash"] = data_hash(raw.u, raw.v, raw.V, raw.weights)
    plots = config["output"]["plots"]
    files = write_scan_outputs(result, verdict, out_dir, plots, amplitude, alternatives=alts, vis=vis,
                               axisymmetric=axisym, templates=templates)
    files.append(axisym.save(out_dir / "axisymmetric.h5"))
    forced = result.provenance.get("forced_resume")
    note = "" if not forced else ("# FORCED RESUME (--force-resume): the numbers kept from the checkpoint were "
                                  "computed with other inputs: " + "; ".join(forced["differences"]) + "\n")
    files.append(_write_text(out_dir / "config_used.toml", note + describe_config(config)))
    follow = None
    if alts is not None and a["refit_geometry"] and _geometry_error_significant(alts) and not verdict.detected:
        follow = rescan_at_fitted_geometry(vis, axisym, templates, alts, settings=settings, scan_result=result,
                                           scheduler=scheduler, progress=progress, alternative_kwargs=alt_kwargs,
                                           detect_kwargs=detect_kwargs)
        if gains is not None:
            follow.verdict.gains_solved = gains.note()
        sub = out_dir / "refit_geometry"
        files += write_scan_outputs(follow.scan, follow.verdict, sub, plots, amplitude,
                                    alternatives=follow.alternatives,
                                    vis=vis, axisymmetric=follow.axisymmetric, templates=templates)
        files.append(follow.axisymmetric.save(sub / "axisymmetric.h5"))
    if gains is not None:
        files.append(out_dir / "gains.h5")
    return ScanRun(verdict, result, alts, follow, files, gains)


def scan_settings(config: dict) -> ScanSettings:
    """The :class:`~spiralbayes.inference.scan.settings.ScanSettings` of a merged configuration.

    ``[grid]`` and ``[scan]`` are its fields (0 bounds: automatic), so ``spiralbayes scan`` and
    ``sb.scan(vis, disc, templates)`` scan the same grid for the same data and model; the
    planet radii are ``scan_settings(config).planet_radii(axisymmetric)``.
    """
    return from_config(ScanSettings, {**config["grid"], **config["scan"]})


DASK_CONNECT_TIMEOUT_S = 3.0


def check_dask_address(address: str, timeout: float = DASK_CONNECT_TIMEOUT_S, *,
                       option: str = "scan.scheduler") -> None:
    """Refuse an unreachable Dask scheduler before anything slow runs (frank, the scan set-up).

    ``""`` or ``"serial"`` (serial) and ``"local"`` (a LocalCluster) need no check;
    ``tcp://host:port`` (or ``host:port``) must accept a TCP connection within ``timeout`` seconds.
    ``option`` is the name the user gave it (errors name it).
    """
    import socket
    from urllib.parse import urlsplit

    if not address or address in ("local", "serial"):
        return
    parts = urlsplit(address if "://" in address else f"tcp://{address}")
    try:
        host, port = parts.hostname, parts.port or 8786
    except ValueError:
        host = None
    if not host:
        raise InputError(f"{option} = {address!r} is not a scheduler address (tcp://host:8786, 'local', 'serial' or "
                         "empty)") from None
    try:
        with socket.create_connection((host, port), timeout=timeout):
            pass
    except OSError as exc:
        raise InputError(f"{option} = {address!r}: no Dask scheduler answers at {host}:{port} within {timeout:g} s "
                         f"({exc.__class__.__name__}); start one (dask scheduler), use 'local', or leave it empty "
                         "for a serial scan") from None


def _geometry_error_significant(alternatives) -> bool:
    return "geometry" in alternatives.fits and alternatives.delta_bic()["geometry"] > DELTA_BIC_THRESHOLD
