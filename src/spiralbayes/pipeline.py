"""Every end-to-end run: the demo, the frank fit with plots, and scan and sample from a configuration.

The command line (:mod:`spiralbayes.cli`) only parses arguments and calls these; notebooks can call
them too. Outputs are written atomically (temporary file, then rename).
"""

from __future__ import annotations

import json
import logging
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._provenance import atomic_path, json_default
from .axisymmetric import AxisymmetricModel, fit_axisymmetric
from .config import describe_config
from .exceptions import InputError
from .geometry import DiscGeometry
from .inference.detection import detect, mirror_index
from .inference.priors import DEFAULT_WIDTHS, Priors
from .inference.results import PosteriorResult
from .inference.sampler import sample_posterior
from .inference.scan import ScanResult, scan
from .io import load_visibilities
from .plotting.axisymmetric import plot_binned_visibilities, plot_profile
from .plotting.posterior import plot_corner, plot_hypotheses, plot_template_probabilities
from .plotting.scan import plot_chi2_vs_rp, plot_heatmap_pair
from .simulate import DiscModel, simulate_observation
from .templates import TemplateBank, default_bank, make_template
from .visibilities import Visibilities, estimate_weights

__all__ = [
    "DemoResult",
    "load_axisymmetric",
    "load_data",
    "load_templates",
    "run_axisym",
    "run_demo",
    "run_sample_config",
    "run_scan_config",
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


def select_templates(bank, mass=(), tau0=(), beta=(), hand=()):
    """The templates of ``bank`` matching every non-empty criterion (lists of allowed values)."""
    chosen = bank.select(mass=list(mass) or None, tau0=list(tau0) or None, beta=list(beta) or None,
                         hand=list(hand) or None)
    if not len(chosen):
        raise InputError(f"no template matches mass={list(mass)}, tau0={list(tau0)}, beta={list(beta)}, "
                         f"hand={list(hand)}; the bank has {bank.names}")
    return list(chosen)


def _save_figure(fig, path: Path, dpi: int = 120) -> Path:
    """Write a Figure as PNG through a temporary file (no pyplot state is touched)."""
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=dpi)
    return path


def _write_text(path: Path, text: str) -> Path:
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return path


def write_scan_outputs(result, verdict, out_dir: Path, plots: bool = True, amplitude=None) -> list[Path]:
    """Save the scan, the verdict (JSON and text) and the heatmap PNGs; return the paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    files = [result.save(out_dir / "scan.h5")]
    files.append(_write_text(out_dir / "verdict.json", json.dumps(verdict.to_dict(), indent=2)))
    files.append(_write_text(out_dir / "verdict.txt", verdict.summary() + "\n"))
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
    return files


def run_demo(out_dir="spiralbayes-demo", *, seed: int = 1, masses=(0.3, 1.0, 3.0), progress: bool = True,
             dask=None) -> DemoResult:
    """Simulate a fiducial-set observation with a planet, fit frank, scan, and decide.

    The planet: 1 M_th, tau0 = 3, beta = 10, right-handed, at 50 au (140 pc), phi_p = 0, in a
    power-law disc (10-110 au) whose optical depth at 50 au is the template's tau0 = 3, of
    inclination 30 deg and PA 60 deg. The scan uses the masses given, tau0 = 3 and
    beta = 10, both hands, on the paper's grid (25 radii from 0.02 to 0.5 arcsec, 90 azimuths).
    """
    out_dir = Path(out_dir)
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
    verdict = detect(result)
    out_dir.mkdir(parents=True, exist_ok=True)
    files = write_scan_outputs(result, verdict, out_dir)
    files.append(axisym.save(out_dir / "axisymmetric.h5"))
    timings["total_s"] = time.perf_counter() - t0
    return DemoResult(verdict, result, files, timings)


def load_data(data: dict):
    """A :class:`Visibilities` from the ``[data]`` section of a configuration."""
    if not data["path"]:
        raise InputError("data.path is empty: give the visibility file in the [data] section")
    kwargs = {}
    if data["uv_units"]:
        kwargs["uv_units"] = data["uv_units"]
    if data["wavelength"]:
        kwargs["wavelength"] = data["wavelength"]
    if data["conjugated"]:
        kwargs["conjugated"] = True
    vis = load_visibilities(data["path"], **kwargs).standardised()
    return estimate_weights(vis) if data["estimate_weights"] else vis


def load_templates(templates: dict) -> list:
    """The templates chosen by the ``[templates]`` section of a configuration."""
    bank = default_bank() if templates["bank"] == "default" else TemplateBank.load(templates["bank"])
    return select_templates(bank, templates["mass"], templates["tau0"], templates["beta"], templates["hand"])


def _geometry(config: dict) -> DiscGeometry:
    g = config["geometry"]
    return DiscGeometry(g["inc"], g["PA"], g["dRA"], g["dDec"])


def load_axisymmetric(config: dict, vis, *, progress: bool = True) -> AxisymmetricModel:
    """The axisymmetric model of a configuration: ``[frank] model`` if given, else a frank fit."""
    f = config["frank"]
    if f["model"]:
        return AxisymmetricModel.load(f["model"])
    axisym = fit_axisymmetric(vis, _geometry(config), N=f["N"], Rmax=f["Rmax"], alpha=f["alpha"], p0=f["p0"],
                              weights_smooth=f["weights_smooth"], nonnegative=f["nonnegative"],
                              fit_geometry="nonparametric" if config["geometry"]["fit"] else None, progress=progress)
    return axisym.nonnegative() if f["nonnegative"] else axisym


def run_scan_config(config: dict, *, progress: bool = True):
    """Run a scan described by a merged configuration (:func:`spiralbayes.config.load_config`)."""
    vis = load_data(config["data"])
    axisym = load_axisymmetric(config, vis, progress=progress)
    templates = load_templates(config["templates"])
    grid = config["grid"]
    r_p = np.linspace(grid["r_p_min"], grid["r_p_max"], grid["n_r_p"])
    out_dir = Path(config["output"]["dir"])
    out_dir.mkdir(parents=True, exist_ok=True)
    _write_text(out_dir / "config_used.toml", describe_config(config))
    s = config["scan"]
    amplitude = "free" if s["amplitude"] == "free" else None
    result = scan(vis, axisym, templates, axisym.geometry, r_p=r_p, n_phi_p=grid["n_phi_p"],
                  distance=config["geometry"]["distance"],
                  checkpoint=out_dir / "scan_checkpoint.h5" if s["checkpoint"] else None,
                  client=s["dask"] or None, progress=progress, cell_factor=s["cell_factor"], nthreads=s["nthreads"])
    verdict = detect(result, amplitude)
    files = write_scan_outputs(result, verdict, out_dir, config["output"]["plots"], amplitude)
    files.append(axisym.save(out_dir / "axisymmetric.h5"))
    return verdict, result, files


def _priors(config: dict, axisym: AxisymmetricModel) -> Priors:
    p = config["priors"]
    widths = {name: p[f"{name}_sigma"] for name in DEFAULT_WIDTHS}
    r_p = None
    if p["r_p_min"] or p["r_p_max"]:
        default = Priors.default(axisym, widths=widths).r_p
        r_p = (p["r_p_min"] or default[0], p["r_p_max"] or default[1])
    return Priors.default(axisym, r_p=r_p, widths=widths, amplitude_max=p["amplitude_max"] or None)


def run_sample_config(config: dict, *, progress: bool = True) -> PosteriorResult:
    """Run :func:`~spiralbayes.inference.sampler.sample_posterior` from a merged configuration.

    The axisymmetric model is ``[frank] model``, else ``OUTPUT/axisymmetric.h5`` written by a scan
    of the same configuration, else a new frank fit; the scan (walker starts, template pruning) is
    ``[sample] scan``, else ``OUTPUT/scan.h5`` when present. Writes, in ``[output] dir``:
    ``chains/<run_name>.h5`` (the chains), ``<run_name>_posterior.h5`` (the result),
    ``<run_name>_summary.json`` (with the verdict: P(planet | data), the Bayes factor),
    ``<run_name>_corner.png`` (r_p in au at ``[geometry] distance``), ``<run_name>_hypotheses.png``,
    ``<run_name>_templates.png`` and ``<run_name>_config.toml`` (the configuration used).
    """
    out_dir = Path(config["output"]["dir"])
    out_dir.mkdir(parents=True, exist_ok=True)
    s = config["sample"]
    run_name = s["run_name"]
    vis = load_data(config["data"])
    scanned = out_dir / "axisymmetric.h5"
    if not config["frank"]["model"] and scanned.exists():
        config = {**config, "frank": {**config["frank"], "model": str(scanned)}}
    axisym = load_axisymmetric(config, vis, progress=progress)
    templates = load_templates(config["templates"])
    scan_path = s["scan"] or (out_dir / "scan.h5" if (out_dir / "scan.h5").exists() else "")
    scan_result = ScanResult.load(scan_path) if scan_path else None
    _write_text(out_dir / f"{run_name}_config.toml", describe_config(config))
    sampler = {k: s[k] for k in ("n_walkers", "max_steps", "check_every", "convergence", "min_ess", "seed",
                                  "prune_delta_lnL", "evidence_draws", "flush_every", "planet_prior")}
    result = sample_posterior(vis, axisym, templates, scan=scan_result, priors=_priors(config, axisym),
                              run_name=run_name, chains_dir=out_dir / "chains", n_steps=s["n_steps"] or None,
                              processes=s["processes"] if s["processes"] > 1 else None,
                              mcmc_templates=s["mcmc_templates"] or None, progress=progress, **sampler)
    result.save(out_dir / f"{run_name}_posterior.h5")
    summary = {**result.to_json(), "summary": result.summary()}
    _write_text(out_dir / f"{run_name}_summary.json", json.dumps(summary, indent=2, default=json_default))
    _save_figure(plot_corner(result, distance=config["geometry"]["distance"]), out_dir / f"{run_name}_corner.png")
    _save_figure(plot_hypotheses(result), out_dir / f"{run_name}_hypotheses.png")
    _save_figure(plot_template_probabilities(result), out_dir / f"{run_name}_templates.png")
    return result


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
