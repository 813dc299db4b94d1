"""``spiralbayes limits`` and ``forecast``: exclusion limits, completeness and Table 3 from a scan; forecasts."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..axisymmetric import AxisymmetricModel, fit_axisymmetric
from ..config import describe_config
from ..geometry import DiscGeometry
from ..settings import DEFAULT_DISTANCE_PC
from ..inference.scan.run import scan
from ..simulate import DiscModel, simulate_observation
from ..templates import default_bank, make_template
from .._hdf5 import require_file
from .calibrate import calibration_settings, reusable_gains
from .inputs import load_data, load_templates
from .outputs import _write_text, save_figure
from .scan_command import run_scan_config, scan_settings
from .reuse import reusable_axisymmetric, reusable_scan

__all__ = ["LimitsRun", "TAURUS_DEMO", "default_limits_config", "run_forecast", "run_limits", "run_limits_config",
           "run_limits_demo"]

log = logging.getLogger(__name__)

TAURUS_DEMO: dict[str, Any] = {"distance": DEFAULT_DISTANCE_PC, "tau0": 0.3, "beta": 10.0, "h_p": 0.07,
                               "masses": (0.1, 0.3, 1.0, 3.0), "wavelength": 1.33e-3}
"""The Taurus demo: disc distance [pc], the scanned family (tau0, beta, H/r, masses [M_th]) of the
default bank, made for the ``taurus`` preset's wavelength [m]."""


@dataclass
class LimitsRun:
    limits: object
    completeness: list
    table: str
    files: list


def _slug(text: str) -> str:
    return "".join(c if c.isalnum() or c in ".-" else "_" for c in text).strip("_")


def run_limits(vis, axisym, templates, result, out_dir, *, limits_config: dict | None = None, name: str = "disc",
               distance: float | None = None, progress: bool = True, plots: bool = True,
               verdict=None, calibration: str | None = None) -> LimitsRun:
    """Exclusion limits, completeness (optional), Table 3 (ECSV and Markdown), HDF5 and plots in ``out_dir``.

    ``verdict`` (the scan's detection verdict or its dict, ``verdict.json``): radii near its planet or
    candidate and near its significant asymmetry models are flagged, not excluded
    (:func:`~spiralbayes.inference.limits.compute_limits`'s ``planets``). ``calibration``: what was done to
    the data's calibration before the scan (e.g. ``GainSolution.note()``), said first in the summary and
    in Table 3's notes."""
    from ..inference.limits.recovery import completeness, injection_engine
    from ..inference.limits.exclusion import compute_limits
    from ..inference.limits.settings import LimitSettings
    from ..settings import from_config
    from ..inference.limits.table3 import build_table3, markdown_table, write_table
    from ..plotting.limits import plot_completeness, plot_excluded_fraction, plot_mass_radius

    lc = {**default_limits_config(), **(limits_config or {})}
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    limits = compute_limits(result, settings=from_config(LimitSettings, lc), vis=vis, axisymmetric=axisym,
                            distance=distance, planets=verdict)
    files = [limits.save(out_dir / "limits.h5")]
    comps = []
    if lc["completeness"]:
        hands = list(lc["inject_hand"])
        keep = [templates[i] for fam in limits.families for h in hands for i in fam.members.get(h, []) if i is not None]
        engine = injection_engine(vis, axisym, templates, result, keep=keep, progress=progress)
        for fam in limits.families:
            if not all(h in fam.members for h in hands):
                log.warning("family %s lacks hand(s) %s: no completeness for it", fam.label, hands)
                continue
            comp = completeness(vis, axisym, templates, result, family=fam, n_azimuths=lc["n_azimuths"], hands=hands,
                                engine=engine, progress=progress)
            comps.append(comp)
            files.append(comp.save(out_dir / f"completeness_{_slug(fam.label)}.h5"))
    thresholds = tuple(lc["thresholds"])
    first = {c.family.label: c for c in comps}
    table3 = build_table3(limits, comps[0] if len(comps) == 1 else None, name=name, thresholds=thresholds)
    if len(comps) > 1:
        table3.meta["notes"] = list(table3.meta["notes"]) + [
            f"Minimum detectable mass, {label}: 50 %: {_det(c, 0.5)}; 90 %: {_det(c, 0.9)}"
            for label, c in first.items()]
    note = f"The data were corrected first: {calibration}." if calibration else None
    if note:
        table3.meta["notes"] = [note] + list(table3.meta.get("notes", []))
    table = markdown_table(table3)
    files += write_table(table3, out_dir / "table3")
    several = len(limits.families) > 1  # then the first line is the limit that holds for every family
    files.append(_write_text(out_dir / "limits_summary.txt",
                             "\n".join(([note] if note else []) + ([limits.summary()] if several else [])
                                       + [limits.summary(f) for f in limits.families]) + "\n"))
    if plots:
        if several:
            files.append(save_figure(plot_mass_radius(limits), out_dir / "mass_radius_all_families.png"))
        for fam in limits.families:
            slug = _slug(fam.label)
            files.append(save_figure(plot_excluded_fraction(limits, fam), out_dir / f"excluded_fraction_{slug}.png"))
            files.append(save_figure(plot_mass_radius(limits, fam, first.get(fam.label)),
                                      out_dir / f"mass_radius_{slug}.png"))
        for comp in comps:
            files.append(save_figure(plot_completeness(comp), out_dir / f"completeness_{_slug(comp.family.label)}.png"))
    return LimitsRun(limits, comps, table, files)


def _det(comp, level) -> str:
    m = comp.m_det(level)
    return "none" if not np.isfinite(m).any() else f"{np.nanmin(m):.2g}-{np.nanmax(m):.2g} M_th"


def default_limits_config() -> dict:
    from ..config import default_config

    return default_config()["limits"]


def run_limits_config(config: dict, *, progress: bool = True) -> LimitsRun:
    """``spiralbayes limits CONFIG``: reuse (or run) the scan of the configuration, then :func:`run_limits`.

    The scan is ``OUTPUT/scan.h5`` with the axisymmetric model ``OUTPUT/axisymmetric.h5`` beside
    it, reused only when both were made from this configuration's data, geometry, frank settings,
    templates and grid (:mod:`.reuse`; otherwise refused, naming what differs); when neither
    exists the scan is run first.
    """
    out_dir = Path(config["output"]["dir"])
    calibration_settings(config)
    templates = load_templates(config["templates"], progress=progress)
    settings = scan_settings(config)
    scan_file, model_file = out_dir / "scan.h5", out_dir / "axisymmetric.h5"
    if scan_file.exists() or model_file.exists():  # reused only when made from these inputs, else refused
        vis, gains = reusable_gains(config, load_data(config["data"], config=config), out_dir, required=True)
        axisym = reusable_axisymmetric(require_file(model_file, "axisymmetric model", "run 'spiralbayes scan' with "
                                                    "this configuration first"), vis, config)
        result = reusable_scan(require_file(scan_file, "scan"), vis, axisym, templates, settings.planet_radii(axisym),
                               settings.n_phi_p)
    else:
        _, result, _ = run_scan_config(config, progress=progress)
        vis, gains = reusable_gains(config, load_data(config["data"], config=config), out_dir, required=True)
        axisym = AxisymmetricModel.load(model_file)
    _write_text(out_dir / "config_used_limits.toml", describe_config(config))
    name = config["limits"]["name"] or Path(config["data"]["path"]).stem
    return run_limits(vis, axisym, templates, result, out_dir, limits_config=config["limits"], name=name,
                      distance=config["geometry"]["distance"], progress=progress, plots=config["output"]["plots"],
                      verdict=scan_verdict(out_dir), calibration=None if gains is None else gains.note())


def scan_verdict(out_dir) -> dict | None:
    """The detection verdict the scan command wrote beside ``scan.h5`` (``verdict.json``), or None
    when there is none or it is older than the scan (then it belongs to another scan)."""
    import json

    out_dir = Path(out_dir)
    path, scan_file = out_dir / "verdict.json", out_dir / "scan.h5"
    if not path.exists() or not scan_file.exists():
        return None
    if path.stat().st_mtime < scan_file.stat().st_mtime:
        log.warning("%s is older than %s: not used to flag radii near the detection", path, scan_file)
        return None
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        log.warning("cannot read %s (%s): radii near the detection are not flagged", path, exc)
        return None


def run_limits_demo(out_dir="spiralbayes-limits-demo", *, seed: int = 3, progress: bool = True) -> LimitsRun:
    """Table 3 for a synthetic Taurus-comparison disc, in one call (``spiralbayes limits --demo``).

    The Taurus set-up (C-6, 1.33 mm, 50 uJy/beam, 7 min) observes the paper's power-law disc
    (10-110 au at 140 pc, optical depth 0.3 at 50 au) without a planet; frank fits it; the default
    bank's family tau0 = 0.3, beta = 10, H/r = 0.07 (masses 0.1-3 M_th, both hands, in the
    compromise, hydro and wakeflow morphologies, made for 1.33 mm) is scanned on the paper's grid
    (25 radii, 0.02-0.5 arcsec, 90 azimuths); limits at 95 % that hold for every morphology, with
    the price of robustness, and completeness from 8 azimuths per radius.
    """
    out_dir = Path(out_dir)
    d = TAURUS_DEMO
    geometry = DiscGeometry(30.0, 60.0)
    disc = DiscModel(distance=d["distance"], tau_ref=d["tau0"])
    vis = simulate_observation("taurus", disc, geometry, seed=seed)
    axisym = fit_axisymmetric(vis, geometry, progress=progress)
    bank = default_bank(h_p=d["h_p"], wavelength=d["wavelength"])
    templates = list(bank.select(mass=list(d["masses"]), tau0=d["tau0"], beta=d["beta"]))
    result = scan(vis, axisym, templates, geometry, r_p=np.linspace(0.02, 0.5, 25), distance=d["distance"],
                  progress=progress)
    out_dir.mkdir(parents=True, exist_ok=True)
    files = [result.save(out_dir / "scan.h5"), axisym.save(out_dir / "axisymmetric.h5")]
    run = run_limits(vis, axisym, templates, result, out_dir, name="synthetic Taurus disc (no planet)",
                     distance=d["distance"], progress=progress)
    run.files[:0] = files
    return run


def run_forecast(args: dict) -> list:
    """Forecasts for the command line: ``args`` holds preset(s), template parameters and r_p [au]."""
    from ..inference.limits.forecasting import forecast

    template = make_template(args["mass"], args["tau0"], args["beta"], args["hand"], wavelength=args["wavelength"])
    disc = DiscModel(distance=args["distance"], tau_ref=args["disc_tau"] or args["tau0"])
    geometry = DiscGeometry(args["inc"], args["pa"])
    out = []
    for preset in args["presets"]:
        out.append(forecast(disc, template, args["r_au"] / args["distance"], preset, geometry=geometry,
                            time_on_source=args["time"], sensitivity=args["sensitivity"]))
    return out
