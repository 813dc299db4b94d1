"""``spiralbayes demo`` and ``spiralbayes axisym``: a synthetic disc end to end, and a frank fit with its figures."""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from pathlib import Path

from .._provenance import check_output_name
from ..axisymmetric import AxisymmetricModel, fit_axisymmetric
from ..geometry import DiscGeometry
from ..settings import DEFAULT_DISTANCE_PC
from ..inference.detection.alternatives import AlternativesResult, fit_alternatives
from ..inference.detection.verdict import Verdict, detect_with_planet_peak
from ..inference.scan.run import ScanResult, scan
from ..plotting.axisymmetric import plot_binned_visibilities, plot_profile
from ..simulate import DiscModel, simulate_observation
from ..templates import default_bank, make_template
from ..visibilities import Visibilities
from .outputs import _save_figure, write_scan_outputs
from .scan_command import check_dask_address

__all__ = ["DemoResult", "run_axisym", "run_demo"]

log = logging.getLogger(__name__)


DEMO_DISTANCE = DEFAULT_DISTANCE_PC  # pc


DEMO_PLANET_AU = 50.0


@dataclass
class DemoResult:
    verdict: Verdict
    scan: ScanResult
    files: list
    timings: dict
    alternatives: AlternativesResult | None = None


def run_demo(out_dir="spiralbayes-demo", *, seed: int = 1, masses=(0.3, 1.0, 3.0), progress: bool = True,
             scheduler=None, alternatives: bool = True) -> DemoResult:
    """Simulate a fiducial-set observation with a planet, fit frank, scan, and decide.

    The planet: 1 M_th, tau0 = 3, beta = 10, right-handed, at 50 au (140 pc), phi_p = 0, in a
    power-law disc (10-110 au) whose optical depth at 50 au is the template's tau0 = 3, of
    inclination 30 deg and PA 60 deg. The scan takes the default bank's templates
    (:func:`~spiralbayes.templates.default_bank`: every morphology, both hands) at the masses given,
    tau0 = 3, beta = 10 and H/r = 0.07, on the
    default grid (:class:`~spiralbayes.inference.scan.settings.ScanSettings`): the path a user's own
    ``sb.scan(vis, disc, sb.default_bank().select(...))`` takes, on a smaller template set.
    With ``alternatives`` the competing asymmetry models are fitted too (test 3). ``scheduler`` as
    for :func:`~spiralbayes.inference.scan.run.scan` (default serial).
    """
    out_dir = Path(out_dir)
    if isinstance(scheduler, str):
        check_dask_address(scheduler)
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
    templates = list(default_bank().select(mass=list(masses), tau0=truth.tau0, beta=truth.beta, h_p=truth.h_p))
    t2 = time.perf_counter()
    result = scan(vis, axisym, templates, geometry, distance=DEMO_DISTANCE, progress=progress, scheduler=scheduler)
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
        Passed to :func:`.fit_axisymmetric`.
    distance : float, optional
        Source distance [pc], for an au axis on the profile plot.
    bin_width : float
        Width of the uv-distance bins in the visibility plot [lambda].
    prefix : str
        Stem of the output file names: ``{prefix}_model.h5``, ``{prefix}_profile.png``,
        ``{prefix}_visibilities.png``.
    **fit_kwargs
        Passed to :func:`.fit_axisymmetric`.
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
