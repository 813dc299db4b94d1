"""``spiralbayes compare``: the visibility scan beside the image-plane comparisons (CLEAN residuals, gap depth)."""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from .._provenance import json_default
from ..axisymmetric import AxisymmetricModel
from ..exceptions import ConfigError
from .inputs import load_data
from .outputs import _write_text, save_figure
from .scan_command import run_scan_config

if TYPE_CHECKING:  # the image-plane module is imported when a comparison runs
    from ..image_plane import CleanResiduals, GapDepth
    from ..inference.detection.verdict import Verdict
    from ..inference.scan.run import ScanResult

__all__ = ["CompareResult", "compare_table", "run_compare_config"]


@dataclass
class CompareResult:
    """Outcome of :func:`run_compare_config`: the three methods' verdicts and what they were based on."""

    verdict: Verdict
    scan: ScanResult
    residuals: CleanResiduals
    gap: GapDepth
    table: list
    files: list
    timings: dict


def compare_table(verdict, residuals, gap) -> list[dict]:
    """One row per method: the statistic, its value, the criterion and the verdict."""
    det = residuals.detection
    where = f"{verdict.template} at r_p = {verdict.r_p:.3f}\", phi_p = {verdict.phi_p_deg:.0f} deg"
    return [
        {"method": "visibility scan", "statistic": f"Delta BIC ({where})", "value": round(verdict.delta_bic, 2),
         "criterion": "Delta BIC > 10, and a compact peak with the mirror template below half of it",
         "verdict": "detected" if verdict.detected else "not detected"},
        {"method": f"CLEAN residuals ({residuals.method})",
         "statistic": f"peak |R|/sigma in the disc (p_false = {det.p_false_alarm:.2g} over {det.n_beams:.0f} beams)",
         "value": round(det.peak_snr, 2), "criterion": "p_false < 2.7e-3 detected, < 0.05 marginal",
         "verdict": det.verdict},
        {"method": "gap depth (CLEAN profile)",
         "statistic": "delta = I_ring / I_gap" + (f" (gap at {gap.r_gap:.3f}\")" if gap.r_gap is not None else ""),
         "value": round(gap.delta, 3), "criterion": "delta > 1.5 clear; 1 < delta <= 1.5 (> 3 sigma) marginal",
         "verdict": gap.verdict},
    ]


def _format_table(rows: list[dict]) -> str:
    keys = ("method", "verdict", "value", "statistic", "criterion")
    widths = {k: max(len(k), *(len(str(r[k])) for r in rows)) for k in keys}
    line = "  ".join(k.ljust(widths[k]) for k in keys)
    body = ["  ".join(str(r[k]).ljust(widths[k]) for k in keys) for r in rows]
    return "\n".join([line, "-" * len(line), *body]) + "\n"


def run_compare_config(config: dict, *, progress: bool = True) -> CompareResult:
    """The visibility scan and the image-plane comparisons on the same data (needs CASA).

    Runs :func:`.run_scan_config` (writing its usual outputs), then
    :func:`spiralbayes.image_plane.clean_residuals` and :func:`spiralbayes.image_plane.gap_depth` on
    the CLEAN image with the settings of ``[compare]``, and writes ``compare.png`` (the paper's
    Fig. 7 layout), ``compare_verdicts.txt`` and ``compare_verdicts.json`` to ``[output] dir``;
    CASA's files go to ``OUTPUT/casa``.
    """
    from .._casa import import_casa
    from ..image_plane import clean_residuals, gap_depth
    from ..plotting.compare import plot_comparison

    import_casa()  # fail before the scan if CASA is missing
    c = config["compare"]
    out_dir = Path(config["output"]["dir"])
    timings = {}
    vis = load_data(config["data"], config=config)
    if vis.wavelength is None:  # CASA needs u, v in metres: fail before the scan, with the option to set
        raise ConfigError(f"{config['data']['path']}: compare needs the observing wavelength (CASA's Measurement "
                          "Set stores u, v in metres) and the file does not state it: set [data] wavelength = "
                          "<metres> in the configuration (e.g. 1.3e-3)")
    t0 = time.perf_counter()
    verdict, result, files = run_scan_config(config, progress=progress)
    timings["scan_s"] = time.perf_counter() - t0
    axisym = AxisymmetricModel.load(out_dir / "axisymmetric.h5")
    r_out = c["r_out"] or 1.1 * axisym.R_eff(0.99)
    t1 = time.perf_counter()
    residuals = clean_residuals(vis, axisym, out_dir / "casa", method=c["residuals"], r_out=r_out,
                                imsize=c["imsize"] or None, cell=c["cell"] or None,
                                threshold_sigma=c["threshold_sigma"],
                                weighting=c["weighting"], robust=c["robust"], niter=c["niter"],
                                deconvolver=c["deconvolver"], keep_files=c["keep_casa_files"])
    timings["clean_s"] = time.perf_counter() - t1
    gap = gap_depth(residuals.data, axisym.geometry, r_out)
    table = compare_table(verdict, residuals, gap)
    distance = config["geometry"]["distance"] or None
    fig = plot_comparison(residuals, gap, result, verdict, axisym.geometry, distance=distance)
    files.append(save_figure(fig, out_dir / "compare.png", dpi=110))
    files.append(_write_text(out_dir / "compare_verdicts.txt", _format_table(table)))
    record = {"table": table, "timings": {**timings, "tclean": [residuals.data.timings, residuals.model.timings]},
              "clean": {"beam_arcsec_deg": residuals.data.beam, "cell_arcsec": residuals.data.cell,
                        "settings": residuals.data.settings, "iterations": [residuals.data.iterations,
                                                                           residuals.model.iterations]},
              "residual_detection": asdict(residuals.detection),
              "gap": {k: v for k, v in asdict(gap).items() if k not in ("r", "profile", "profile_error")}}
    files.append(_write_text(out_dir / "compare_verdicts.json", json.dumps(record, indent=2, default=json_default)))
    return CompareResult(verdict, result, residuals, gap, table, files, timings)
