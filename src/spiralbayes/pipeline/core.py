"""The main runs: the demo, the frank fit with plots, and scan and sample from a configuration.

The command line (:mod:`spiralbayes.cli`) only parses arguments and calls these; notebooks can call
them too. Outputs are written atomically (temporary file, then rename, with the user's umask), JSON
outputs are strict (NaN written as ``null``), and a scan's configuration record is written only
once the scan it describes has finished.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._provenance import atomic_path, check_output_name, to_json
from ..axisymmetric import AxisymmetricModel, fit_axisymmetric
from ..axisymmetric.provenance import check_fitted_to
from ..config import describe_config, geometry_given
from ..exceptions import ConfigError, InputError
from ..geometry import DiscGeometry
from ..inference.detection.alternatives import fit_alternatives
from ..inference.detection.planet_peak import detect_with_planet_peak
from ..inference.detection.refit import GeometryFollowUp, rescan_at_fitted_geometry
from ..inference.detection.verdict import DELTA_BIC_THRESHOLD, mirror_index
from ..inference.posterior.priors import DEFAULT_WIDTHS, Priors
from ..inference.posterior.results import PosteriorResult
from ..inference.posterior.sampler import sample_posterior
from ..inference.scan.run import ScanResult, scan
from ..io import load_visibilities
from ..plotting.alternatives import plot_residual_comparison
from ..plotting.axisymmetric import plot_binned_visibilities, plot_profile
from ..plotting.posterior import plot_corner, plot_hypotheses, plot_template_probabilities
from ..plotting.scan import plot_chi2_vs_rp, plot_heatmap_pair
from ..simulate import DiscModel, simulate_observation
from ..templates import TemplateBank, default_bank, make_template
from ..visibilities import Visibilities, estimate_weights
from .reuse import reusable_axisymmetric, reusable_scan

__all__ = [
    "DemoResult",
    "ScanRun",
    "load_axisymmetric",
    "load_data",
    "load_templates",
    "run_axisym",
    "run_demo",
    "run_sample_config",
    "run_scan",
    "run_scan_config",
    "save_figure",
    "select_templates",
    "write_scan_outputs",
]

log = logging.getLogger(__name__)

DEMO_DISTANCE = 140.0  # pc
DEMO_PLANET_AU = 50.0


@dataclass
class DemoResult:
    verdict: object
    scan: object
    files: list
    timings: dict
    alternatives: object = None


@dataclass
class ScanRun:
    """What :func:`run_scan` produced: the verdict, scan, alternatives, geometry follow-up, files."""

    verdict: object
    scan: object
    alternatives: object
    follow_up: GeometryFollowUp | None
    files: list


def select_templates(bank, mass=(), tau0=(), beta=(), hand=(), h_p=()):
    """The templates of ``bank`` matching every non-empty criterion (lists of allowed values)."""
    chosen = bank.select(mass=list(mass) or None, tau0=list(tau0) or None, beta=list(beta) or None,
                         hand=list(hand) or None, h_p=list(h_p) or None)
    if not len(chosen):
        raise InputError(f"no template matches mass={list(mass)}, tau0={list(tau0)}, beta={list(beta)}, "
                         f"hand={list(hand)}, h_p={list(h_p)}; the bank ({len(bank)} templates) has "
                         f"{_bank_values(bank)}")
    return list(chosen)


def _bank_values(bank) -> str:
    """The values each template parameter takes in ``bank``, e.g. ``mass 0.3, 1, 3; hand L, R``."""
    parts = []
    for key in ("mass", "tau0", "beta", "hand", "h_p"):
        values = sorted({getattr(t, key) for t in bank if getattr(t, key, None) is not None}, key=str)
        values = [v for v in values if not (isinstance(v, float) and v != v)]
        parts.append(f"{key} {', '.join(f'{v:g}' if isinstance(v, float) else str(v) for v in values) or '-'}")
    return "; ".join(parts)


def save_figure(fig, path, dpi: int = 120, **kwargs) -> Path:
    """Write a Figure through a temporary file (format from the suffix, default PNG; no pyplot state)."""
    path = Path(path)
    fmt = path.suffix.lstrip(".").lower() or "png"
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=fmt, dpi=dpi, **kwargs)
    return path


_save_figure = save_figure


def _write_text(path: Path, text: str) -> Path:
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return path


def write_scan_outputs(result, verdict, out_dir: Path, plots: bool = True, amplitude=None, *, alternatives=None,
                       vis=None, axisymmetric=None, templates=None) -> list[Path]:
    """Save the scan, the verdict (JSON and text) and the heatmap PNGs; return the paths.

    With ``alternatives`` also ``alternatives.h5`` and ``alternatives.txt`` (the fits of test 3)
    and, when ``vis``, ``axisymmetric`` and ``templates`` are given and ``plots`` is on,
    ``residual_comparison.png`` (:func:`~spiralbayes.plotting.alternatives.plot_residual_comparison`).
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    files = [result.save(out_dir / "scan.h5")]
    files.append(_write_text(out_dir / "verdict.json", to_json(verdict.to_dict(), indent=2)))
    files.append(_write_text(out_dir / "verdict.txt", verdict.summary() + "\n"))
    if alternatives is not None:
        files.append(alternatives.save(out_dir / "alternatives.h5"))
        files.append(_write_text(out_dir / "alternatives.txt", alternatives.table() + "\n"))
    if not plots:
        return files
    done = set()
    for t, meta in enumerate(result.templates):
        j = mirror_index(result, t)
        if meta.get("hand") != "R" or j is None or t in done:
            continue
        done.update({t, j})
        fig = plot_heatmap_pair(result, t, j, amplitude=amplitude)
        files.append(_save_figure(fig, out_dir / f"heatmap_{meta['name']}.png"))
    files.append(_save_figure(plot_chi2_vs_rp(result, amplitude=amplitude), out_dir / "chi2_vs_rp.png"))
    if alternatives is not None and None not in (vis, axisymmetric, templates):
        fig = plot_residual_comparison(vis, axisymmetric, result, alternatives, templates, amplitude=amplitude)
        files.append(_save_figure(fig, out_dir / "residual_comparison.png"))
    return files


def run_demo(out_dir="spiralbayes-demo", *, seed: int = 1, masses=(0.3, 1.0, 3.0), progress: bool = True,
             dask=None, alternatives: bool = True) -> DemoResult:
    """Simulate a fiducial-set observation with a planet, fit frank, scan, and decide.

    The planet: 1 M_th, tau0 = 3, beta = 10, right-handed, at 50 au (140 pc), phi_p = 0, in a
    power-law disc (10-110 au) whose optical depth at 50 au is the template's tau0 = 3, of
    inclination 30 deg and PA 60 deg. The scan uses the masses given, tau0 = 3 and
    beta = 10, both hands, on the paper's grid (25 radii from 0.02 to 0.5 arcsec, 90 azimuths).
    With ``alternatives`` the competing asymmetry models are fitted too (test 3).

    The templates are the default bank's at H/r = 0.07 (``wake_m{M}_tau3_b10_h0.07_{R,L}``); the
    full default bank also spans H/r = 0.05 and 0.10 (192 templates). The wake generator is
    calibrated against wakeflow and FARGO3D reference maps (docs/templates.md).
    """
    out_dir = Path(out_dir)
    if isinstance(dask, str):
        check_dask_address(dask)
    timings = {}
    t0 = time.perf_counter()
    geometry = DiscGeometry(30.0, 60.0)
    truth = make_template(1.0, 3.0, 10.0, "R")
    r_p_true = DEMO_PLANET_AU / DEMO_DISTANCE
    log.info("simulating the fiducial set-up with a %s planet at %.0f au, phi_p = 0", truth.name, DEMO_PLANET_AU)
    disc = DiscModel(distance=DEMO_DISTANCE, r_ref=DEMO_PLANET_AU, tau_ref=truth.tau0)
    vis = simulate_observation("fiducial", disc, geometry, truth, r_p=r_p_true, phi_p=0.0, seed=seed)
    timings["simulate_s"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    axisym = fit_axisymmetric(vis, geometry, progress=progress)
    timings["frank_s"] = time.perf_counter() - t1
    templates = []
    for mass in masses:
        right = truth if mass == 1.0 else make_template(mass, 3.0, 10.0, "R")
        templates += [right, right.mirror()]
    t2 = time.perf_counter()
    result = scan(vis, axisym, templates, geometry, r_p=np.linspace(0.02, 0.5, 25), distance=DEMO_DISTANCE,
                  progress=progress, client=dask)
    timings["scan_s"] = time.perf_counter() - t2
    alts = None
    if alternatives:
        t3 = time.perf_counter()
        alts = fit_alternatives(vis, axisym, geometry, progress=progress)
        timings["alternatives_s"] = time.perf_counter() - t3
    verdict = detect_with_planet_peak(result, vis, axisym, templates, geometry, alternatives=alts)
    out_dir.mkdir(parents=True, exist_ok=True)
    files = write_scan_outputs(result, verdict, out_dir, alternatives=alts, vis=vis, axisymmetric=axisym,
                               templates=templates)
    files.append(axisym.save(out_dir / "axisymmetric.h5"))
    timings["total_s"] = time.perf_counter() - t0
    return DemoResult(verdict, result, files, timings, alts)


def load_data(data: dict, geometry: DiscGeometry | None = None):
    """A :class:`Visibilities` from the ``[data]`` section of a configuration.

    With ``estimate_weights = true`` the weights are rescaled by one factor from the scatter of
    each visibility about the plane through its uv neighbours (``method="neighbours"`` of
    :func:`~spiralbayes.visibilities.estimate_weights`: no model, geometry or symmetry assumed;
    uv cells, the ``"scatter"`` method without a geometry, were measured 40x off on the fiducial
    set-up, where the bright disc's structure dominates the scatter within a cell); otherwise they
    are checked on load and a DataWarning gives this fix when they do not look statistical.
    ``geometry`` is kept for callers that pass it; the estimate does not use it.
    """
    if not data["path"]:
        raise InputError("data.path is empty: give the visibility file in the [data] section")
    kwargs = {}
    if data["uv_units"]:
        kwargs["uv_units"] = data["uv_units"]
    if data["wavelength"]:
        kwargs["wavelength"] = data["wavelength"]
    if data["conjugated"]:
        kwargs["conjugated"] = True
    vis = load_visibilities(data["path"], check_weights_on_load=not data["estimate_weights"], **kwargs).standardised()
    return estimate_weights(vis, method="neighbours") if data["estimate_weights"] else vis


def load_templates(templates: dict) -> list:
    """The templates chosen by the ``[templates]`` section of a configuration."""
    bank = default_bank() if templates["bank"] == "default" else TemplateBank.load(templates["bank"])
    return select_templates(bank, templates["mass"], templates["tau0"], templates["beta"], templates["hand"],
                            templates.get("h_p", ()))


def _geometry(config: dict) -> DiscGeometry:
    g = config["geometry"]
    return DiscGeometry(g["inc"], g["PA"], g["dRA"], g["dDec"])


def load_axisymmetric(config: dict, vis, *, progress: bool = True) -> AxisymmetricModel:
    """The axisymmetric model of a configuration: ``[frank] model`` if given, else a frank fit."""
    f = config["frank"]
    if f["model"]:
        model = AxisymmetricModel.load(f["model"])
        check_fitted_to(model, vis, f"[frank] model {f['model']}")
        return model
    if not config["geometry"]["fit"] and not geometry_given(config):
        raise ConfigError(f"{getattr(config, 'source', '') or 'the configuration'}: no [geometry] inc and PA, and frank "
                          "must be fitted: give the disc's inclination and position angle in degrees ([geometry] "
                          "inc = ..., PA = ...), or set [geometry] fit = true to fit them")
    axisym = fit_axisymmetric(vis, _geometry(config), N=f["N"] or None, Rmax=f["Rmax"], alpha=f["alpha"], p0=f["p0"],
                              weights_smooth=f["weights_smooth"], nonnegative=f["nonnegative"],
                              fit_geometry="nonparametric" if config["geometry"]["fit"] else None, progress=progress)
    return axisym.nonnegative() if f["nonnegative"] else axisym


def run_scan_config(config: dict, *, progress: bool = True, force_resume: bool = False):
    """Run a scan described by a merged configuration (:func:`spiralbayes.config.load_config`).

    Returns ``(verdict, scan, files)`` of the scan at the configured geometry; :func:`run_scan`
    (which this calls) also returns the alternatives and the geometry follow-up.
    """
    run = run_scan(config, progress=progress, force_resume=force_resume)
    return run.verdict, run.scan, run.files


def run_scan(config: dict, *, progress: bool = True, force_resume: bool = False) -> ScanRun:
    """The scan of a configuration, the alternatives of test 3, the verdict and, when needed, the follow-up.

    A checkpoint left in ``[output] dir`` is checked for integrity before anything slow runs,
    and resumed only if it was written for the same inputs (``force_resume`` overrides; see
    :func:`~spiralbayes.inference.scan.run.scan`). Writes the scan's outputs to ``[output] dir``
    (:func:`write_scan_outputs`). With ``[alternatives] refit_geometry`` on, no detection and the
    geometry alternative significant (ΔBIC > 10), frank is refitted at the fitted geometry and the
    scan, alternatives and verdict are repeated there
    (:func:`~spiralbayes.inference.detection.refit.rescan_at_fitted_geometry`), with their outputs and
    ``axisymmetric.h5`` in ``OUTPUT/refit_geometry/``.
    """
    out_dir = Path(config["output"]["dir"])
    s = config["scan"]
    checkpoint = out_dir / "scan_checkpoint.h5" if s["checkpoint"] else None
    if checkpoint is not None and checkpoint.exists():
        ScanResult.load(checkpoint)  # a truncated or foreign file fails now, not after the frank fit
    check_dask_address(s["dask"])
    vis = load_data(config["data"], _geometry(config))
    axisym = load_axisymmetric(config, vis, progress=progress)
    templates = load_templates(config["templates"])
    grid = config["grid"]
    r_p = np.linspace(grid["r_p_min"], grid["r_p_max"], grid["n_r_p"])
    out_dir.mkdir(parents=True, exist_ok=True)
    amplitude = "free" if s["amplitude"] == "free" else None
    result = scan(vis, axisym, templates, axisym.geometry, r_p=r_p, n_phi_p=grid["n_phi_p"],
                  distance=config["geometry"]["distance"], checkpoint=checkpoint, client=s["dask"] or None,
                  progress=progress, cell_factor=s["cell_factor"], nthreads=s["nthreads"], force_resume=force_resume,
                  rule=s["quadrature"], power_path=s["power_path"])
    a = config["alternatives"]
    alt_kwargs = {"models": a["models"] or None, "n_starts": a["n_starts"], "nthreads": s["nthreads"],
                  "progress": progress}
    alts = fit_alternatives(vis, axisym, axisym.geometry, **alt_kwargs) if a["fit"] else None
    detect_kwargs = {"alternative_threshold": a["threshold"], "mstar": config["limits"]["mstar"]}
    verdict = detect_with_planet_peak(result, vis, axisym, templates, axisym.geometry, amplitude, alternatives=alts,
                                      **detect_kwargs)
    plots = config["output"]["plots"]
    files = write_scan_outputs(result, verdict, out_dir, plots, amplitude, alternatives=alts, vis=vis,
                               axisymmetric=axisym, templates=templates)
    files.append(axisym.save(out_dir / "axisymmetric.h5"))
    forced = result.provenance.get("forced_resume")
    note = "" if not forced else ("# FORCED RESUME (--force-resume): the numbers kept from the checkpoint were computed "
                                  "with other inputs: " + "; ".join(forced["differences"]) + "\n")
    files.append(_write_text(out_dir / "config_used.toml", note + describe_config(config)))
    follow = None
    if alts is not None and a["refit_geometry"] and _geometry_error_significant(alts) and not verdict.detected:
        follow = rescan_at_fitted_geometry(vis, axisym, templates, alts, previous_scan=result, amplitude=amplitude,
                                           nthreads=s["nthreads"], progress=progress, alternative_kwargs=alt_kwargs,
                                           detect_kwargs=detect_kwargs, client=s["dask"] or None,
                                           cell_factor=s["cell_factor"])
        sub = out_dir / "refit_geometry"
        files += write_scan_outputs(follow.scan, follow.verdict, sub, plots, amplitude, alternatives=follow.alternatives,
                                    vis=vis, axisymmetric=follow.axisymmetric, templates=templates)
        files.append(follow.axisymmetric.save(sub / "axisymmetric.h5"))
    return ScanRun(verdict, result, alts, follow, files)


DASK_CONNECT_TIMEOUT_S = 3.0
"""How long :func:`check_dask_address` waits for the scheduler's port [s]."""


def check_dask_address(address: str, timeout: float = DASK_CONNECT_TIMEOUT_S) -> None:
    """Refuse an unreachable Dask scheduler before anything slow runs (frank, the scan set-up).

    ``""`` (serial) and ``"local"`` (a LocalCluster) need no check; ``tcp://host:port`` (or
    ``host:port``) must accept a TCP connection within ``timeout`` seconds.
    """
    import socket
    from urllib.parse import urlsplit

    if not address or address == "local":
        return
    parts = urlsplit(address if "://" in address else f"tcp://{address}")
    try:
        host, port = parts.hostname, parts.port or 8786
    except ValueError:
        raise InputError(f"scan.dask = {address!r} is not a scheduler address (tcp://host:8786, 'local' or "
                         "empty)") from None
    if not host:
        raise InputError(f"scan.dask = {address!r} is not a scheduler address (tcp://host:8786, 'local' or empty)")
    try:
        with socket.create_connection((host, port), timeout=timeout):
            pass
    except OSError as exc:
        raise InputError(f"scan.dask = {address!r}: no Dask scheduler answers at {host}:{port} within {timeout:g} s "
                         f"({exc.__class__.__name__}); start one (dask scheduler), use 'local', or leave it empty "
                         "for a serial scan") from None


def _geometry_error_significant(alternatives) -> bool:
    return "geometry" in alternatives.fits and alternatives.delta_bic()["geometry"] > DELTA_BIC_THRESHOLD


def _priors(config: dict, axisym: AxisymmetricModel) -> Priors:
    p = config["priors"]
    widths = {name: p[f"{name}_sigma"] for name in DEFAULT_WIDTHS}
    r_p = None
    if p["r_p_min"] or p["r_p_max"]:
        default = Priors.default(axisym, widths=widths).r_p
        r_p = (p["r_p_min"] or default[0], p["r_p_max"] or default[1])
    return Priors.default(axisym, r_p=r_p, widths=widths, amplitude_max=p["amplitude_max"] or None)


def run_sample_config(config: dict, *, progress: bool = True) -> PosteriorResult:
    """Run :func:`~spiralbayes.inference.posterior.sampler.sample_posterior` from a merged configuration.

    The axisymmetric model is ``[frank] model``, else ``OUTPUT/axisymmetric.h5`` written by a scan
    of the same configuration, else a new frank fit; the scan (walker starts, template pruning) is
    ``[sample] scan``, else ``OUTPUT/scan.h5`` when present. Saved files are reused only when
    made from these data, geometry and frank settings (:mod:`.reuse`); otherwise the run is refused
    before any sampling, naming what differs. Writes, in ``[output] dir``:
    ``chains/<run_name>.h5`` (the chains), ``<run_name>_posterior.h5`` (the result),
    ``<run_name>_summary.json`` (with the verdict: P(planet | data), the Bayes factor),
    ``<run_name>_corner.png`` (r_p in au at ``[geometry] distance``), ``<run_name>_hypotheses.png``,
    ``<run_name>_templates.png`` and ``<run_name>_config.toml`` (the configuration used).
    """
    out_dir = Path(config["output"]["dir"])
    out_dir.mkdir(parents=True, exist_ok=True)
    s = config["sample"]
    run_name = check_output_name(s["run_name"], "sample.run_name")
    vis = load_data(config["data"], _geometry(config))
    scanned = out_dir / "axisymmetric.h5"
    if not config["frank"]["model"] and scanned.exists():
        axisym = reusable_axisymmetric(scanned, vis, config)
    else:
        axisym = load_axisymmetric(config, vis, progress=progress)
    templates = load_templates(config["templates"])
    scan_path = s["scan"] or (out_dir / "scan.h5" if (out_dir / "scan.h5").exists() else "")
    scan_result = reusable_scan(scan_path, vis, axisym) if scan_path else None
    _write_text(out_dir / f"{run_name}_config.toml", describe_config(config))
    sampler = {k: s[k] for k in ("n_walkers", "max_steps", "check_every", "convergence", "min_ess", "seed",
                                  "prune_delta_lnL", "evidence_draws", "flush_every", "planet_prior")}
    result = sample_posterior(vis, axisym, templates, scan=scan_result, priors=_priors(config, axisym),
                              run_name=run_name, chains_dir=out_dir / "chains", n_steps=s["n_steps"] or None,
                              processes=s["processes"] if s["processes"] > 1 else None,
                              mcmc_templates=s["mcmc_templates"] or None, progress=progress, **sampler)
    result.save(out_dir / f"{run_name}_posterior.h5")
    summary = {**result.to_json(), "summary": _summary_with_units(result.summary())}
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


def run_axisym(vis: Visibilities, out_dir, geometry: DiscGeometry | None = None, *,
               distance: float | None = None, bin_width: float = 20e3, prefix: str = "axisym",
               **fit_kwargs) -> AxisymmetricModel:
    """Fit, then write the model (HDF5) and plots of the profile and binned visibilities.

    Parameters
    ----------
    vis : Visibilities
        The data.
    out_dir : path
        Output folder (created if missing).
    geometry : DiscGeometry, optional
        Passed to :func:`fit_axisymmetric`.
    distance : float, optional
        Source distance [pc], for an au axis on the profile plot.
    bin_width : float
        Width of the uv-distance bins in the visibility plot [lambda].
    prefix : str
        Stem of the output file names: ``{prefix}_model.h5``, ``{prefix}_profile.png``,
        ``{prefix}_visibilities.png``.
    **fit_kwargs
        Passed to :func:`fit_axisymmetric`.
    """
    out_dir = Path(out_dir)
    check_output_name(prefix, "prefix")
    out_dir.mkdir(parents=True, exist_ok=True)
    model = fit_axisymmetric(vis, geometry, **fit_kwargs)
    written = [model.save(out_dir / f"{prefix}_model.h5")]
    figures = {
        f"{prefix}_profile.png": plot_profile(model, distance=distance),
        f"{prefix}_visibilities.png": plot_binned_visibilities(vis, model, bin_width=bin_width),
    }
    for name, fig in figures.items():
        written.append(_save_figure(fig, out_dir / name, dpi=150))
    for path in written:
        log.info("wrote %s", path)
    return model
