"""End-to-end runs used by the command line: the demo and a scan from a configuration."""

from __future__ import annotations

import json
import logging
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .config import describe_config
from .geometry import DiscGeometry

__all__ = ["DemoResult", "load_data", "run_demo", "run_scan_config", "select_templates", "write_scan_outputs"]

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
        raise ValueError(f"no template matches mass={list(mass)}, tau0={list(tau0)}, beta={list(beta)}, "
                         f"hand={list(hand)}; the bank has {bank.names}")
    return list(chosen)


def write_scan_outputs(result, verdict, out_dir: Path, plots: bool = True, amplitude=None) -> list[Path]:
    """Save the scan, the verdict (JSON and text) and the heatmap PNGs; return the paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .detection import mirror_index
    from .plotting.scan import plot_chi2_vs_rp, plot_heatmap_pair

    out_dir.mkdir(parents=True, exist_ok=True)
    files = [result.save(out_dir / "scan.h5")]
    (out_dir / "verdict.json").write_text(json.dumps(verdict.to_dict(), indent=2))
    (out_dir / "verdict.txt").write_text(verdict.summary() + "\n")
    files += [out_dir / "verdict.json", out_dir / "verdict.txt"]
    if not plots:
        return files
    done = set()
    for t, meta in enumerate(result.templates):
        j = mirror_index(result, t)
        if meta.get("hand") != "R" or j is None or t in done:
            continue
        done.update({t, j})
        fig = plot_heatmap_pair(result, t, j, amplitude=amplitude)
        path = out_dir / f"heatmap_{meta['name']}.png"
        fig.savefig(path, dpi=120)
        plt.close(fig)
        files.append(path)
    fig = plot_chi2_vs_rp(result, amplitude=amplitude)
    fig.savefig(out_dir / "chi2_vs_rp.png", dpi=120)
    plt.close(fig)
    files.append(out_dir / "chi2_vs_rp.png")
    return files


def run_demo(out_dir="spiralbayes-demo", *, seed: int = 1, masses=(0.3, 1.0, 3.0), progress: bool = True,
             dask=None) -> DemoResult:
    """Simulate a fiducial-set observation with a planet, fit frank, scan, and decide.

    The planet: 1 M_th, tau0 = 3, beta = 10, right-handed, at 50 au (140 pc), phi_p = 0, in a
    power-law disc (10-110 au) whose optical depth at 50 au is the template's tau0 = 3, of
    inclination 30 deg and PA 60 deg. The scan uses the masses given, tau0 = 3 and
    beta = 10, both hands, on the paper's grid (25 radii from 0.02 to 0.5 arcsec, 90 azimuths).
    """
    from .axisymmetric import fit_axisymmetric
    from .detection import detect
    from .scan import scan
    from .simulate import DiscModel, simulate_observation
    from .templates import make_template

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
    from .visibilities import estimate_weights, load_visibilities

    if not data["path"]:
        raise ValueError("data.path is empty: give the visibility file in the [data] section")
    kwargs = {}
    if data["uv_units"]:
        kwargs["uv_units"] = data["uv_units"]
    if data["wavelength"]:
        kwargs["wavelength"] = data["wavelength"]
    if data["conjugated"]:
        kwargs["conjugated"] = True
    vis = load_visibilities(data["path"], **kwargs).standardised()
    return estimate_weights(vis) if data["estimate_weights"] else vis


def run_scan_config(config: dict, *, progress: bool = True):
    """Run a scan described by a merged configuration (:func:`spiralbayes.config.load_config`)."""
    from .axisymmetric import fit_axisymmetric
    from .detection import detect
    from .scan import scan
    from .templates import TemplateBank, default_bank

    vis = load_data(config["data"])
    g = config["geometry"]
    geometry = DiscGeometry(g["inc"], g["PA"], g["dRA"], g["dDec"])
    f = config["frank"]
    axisym = fit_axisymmetric(vis, geometry, N=f["N"], Rmax=f["Rmax"], alpha=f["alpha"], p0=f["p0"],
                              weights_smooth=f["weights_smooth"], nonnegative=f["nonnegative"],
                              fit_geometry="nonparametric" if g["fit"] else None, progress=progress)
    if f["nonnegative"]:
        axisym = axisym.nonnegative()
    tcfg = config["templates"]
    bank = default_bank() if tcfg["bank"] == "default" else TemplateBank.load(tcfg["bank"])
    templates = select_templates(bank, tcfg["mass"], tcfg["tau0"], tcfg["beta"], tcfg["hand"])
    grid = config["grid"]
    r_p = np.linspace(grid["r_p_min"], grid["r_p_max"], grid["n_r_p"])
    out_dir = Path(config["output"]["dir"])
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "config_used.toml").write_text(describe_config(config))
    s = config["scan"]
    amplitude = "free" if s["amplitude"] == "free" else None
    result = scan(vis, axisym, templates, axisym.geometry, r_p=r_p, n_phi_p=grid["n_phi_p"],
                  distance=g["distance"], checkpoint=out_dir / "scan_checkpoint.h5" if s["checkpoint"] else None,
                  client=s["dask"] or None, progress=progress, cell_factor=s["cell_factor"], nthreads=s["nthreads"])
    verdict = detect(result, amplitude)
    files = write_scan_outputs(result, verdict, out_dir, config["output"]["plots"], amplitude)
    files.append(axisym.save(out_dir / "axisymmetric.h5"))
    return verdict, result, files
