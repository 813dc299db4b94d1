"""``spiralbayes sample``: the posterior from a configuration, with its summary and figures."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from .._provenance import check_output_name, to_json
from ..config import describe_config
from ..inference.posterior.results import PosteriorResult
from ..inference.posterior.sampler import sample_posterior
from ..inference.posterior.settings import PriorSettings, SamplingSettings
from ..plotting.posterior import plot_corner, plot_hypotheses, plot_template_probabilities
from ..settings import from_config
from .calibrate import calibration_settings, reusable_gains, run_calibration
from .reuse import reusable_axisymmetric, reusable_scan
from .inputs import _geometry, load_axisymmetric, load_data, load_templates
from .outputs import _save_figure, _write_text

__all__ = ["run_sample_config"]

log = logging.getLogger(__name__)


def run_sample_config(config: dict, *, progress: bool = True) -> PosteriorResult:
    """Run :func:`~spiralbayes.inference.posterior.sampler.sample_posterior` from a merged configuration.

    The axisymmetric model is ``[frank] model``, else ``OUTPUT/axisymmetric.h5`` written by a scan
    of the same configuration, else a new frank fit; the scan (walker starts, template pruning) is
    ``[sample] scan``, else ``OUTPUT/scan.h5`` when present. Saved files are reused only when
    made from these data, geometry and frank settings (:mod:`.reuse`); otherwise the run is refused
    before any sampling, naming what differs. With ``[calibration] solve`` set the posterior is of the
    corrected data: ``OUTPUT/gains.h5`` is applied when it was solved from these data with these
    settings, else the gains are solved here (:mod:`.calibrate`; the first solve only: the second, against
    a candidate spiral, needs the scan that ``spiralbayes scan`` makes). Writes, in ``[output] dir``:
    ``chains/<run_name>.h5`` (the chains), ``<run_name>_posterior.h5`` (the result),
    ``<run_name>_summary.json`` (with the verdict: P(planet | data), the Bayes factor, and
    ``gains_solved``: the gain solution's note when the data were corrected),
    ``<run_name>_corner.png`` (r_p in au at ``[geometry] distance``), ``<run_name>_hypotheses.png``,
    ``<run_name>_templates.png`` and ``<run_name>_config.toml`` (the configuration used).
    """
    out_dir = Path(config["output"]["dir"])
    out_dir.mkdir(parents=True, exist_ok=True)
    s = config["sample"]
    run_name = check_output_name(s["run_name"], "sample.run_name")
    # the settings are built (and checked) before any data are read
    sampling = from_config(SamplingSettings, s, run_name=run_name)
    prior_settings = from_config(PriorSettings, config["priors"])
    calibration_settings(config)
    vis = load_data(config["data"], _geometry(config), config=config)
    vis, gains = reusable_gains(config, vis, out_dir)
    scanned = out_dir / "axisymmetric.h5"
    if not config["frank"]["model"] and scanned.exists():
        axisym = reusable_axisymmetric(scanned, vis, config)
    else:
        axisym = load_axisymmetric(config, vis, progress=progress)
    if gains is None:  # no saved solution: solve now (a no-op with [calibration] solve = "none")
        vis, axisym, gains = run_calibration(config, vis, axisym, out_dir, progress=progress)
    templates = load_templates(config["templates"], progress=progress)
    scan_path = s["scan"] or (out_dir / "scan.h5" if (out_dir / "scan.h5").exists() else "")
    scan_result = reusable_scan(scan_path, vis, axisym) if scan_path else None
    _write_text(out_dir / f"{run_name}_config.toml", describe_config(config))
    result = sample_posterior(vis, axisym, templates, scan_result=scan_result,
                              priors=prior_settings.priors(axisym), settings=sampling, chains_dir=out_dir / "chains",
                              progress=progress, mass_prior=prior_settings.mass_prior())
    if result is None:  # only an MPI worker rank gets none, and a configuration cannot choose MPI (pool)
        raise RuntimeError("sample_posterior returned no result, as on an MPI worker rank")
    result.save(out_dir / f"{run_name}_posterior.h5")
    summary = {**result.to_dict(), "summary": _summary_with_units(result.percentiles()),
               "gains_solved": None if gains is None else gains.note()}
    _write_text(out_dir / f"{run_name}_summary.json", to_json(summary, indent=2))
    _save_figure(plot_corner(result, distance=config["geometry"]["distance"]), out_dir / f"{run_name}_corner.png")
    _save_figure(plot_hypotheses(result), out_dir / f"{run_name}_hypotheses.png")
    _save_figure(plot_template_probabilities(result), out_dir / f"{run_name}_templates.png")
    return result


_SUMMARY_UNITS = {"r_p": ("r_p_arcsec", 1.0), "phi_p": ("phi_p_deg", 180.0 / np.pi), "A": ("A", 1.0),
                  "inc": ("inc_deg", 1.0), "PA": ("PA_deg", 1.0), "dRA": ("dRA_arcsec", 1.0),
                  "dDec": ("dDec_arcsec", 1.0)}


def _summary_with_units(stats: dict) -> dict:
    """The posterior statistics with the unit in each key and phi_p in degrees (as the text reports it)."""
    out = {}
    for name, values in stats.items():
        key, scale = _SUMMARY_UNITS.get(name, (name, 1.0))
        out[key] = {k: v * scale if isinstance(v, (int, float)) and not isinstance(v, bool) else v
                    for k, v in values.items()} if isinstance(values, dict) else values
    return out
