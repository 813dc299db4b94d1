"""Small instances of every result class, built from arrays of random numbers.

Shared by ``tests/test_result_protocol.py`` and ``tests/data/format1/make_format1.py`` (which runs
them against the code before the dataclass layout to write the format-1 files), so only names
that exist in both versions are imported here.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

try:
    from spiralbayes.alternatives import DiscGrid
except ImportError:  # the code before the renames (make_format1.py)
    from spiralbayes.asymmetries import DiscGrid
from spiralbayes.geometry import DiscGeometry
from spiralbayes.inference.detection import AlternativeFit, AlternativesResult, detect
from spiralbayes.inference.limits import CompletenessResult, Forecast, compute_limits
from spiralbayes.inference.limits.families import template_families
from spiralbayes.inference.posterior import NullRun, PosteriorResult, Priors, TemplateRun
from spiralbayes.inference.scan import ScanResult
from spiralbayes.inference.validation.planted import PlantedExclusion

if TYPE_CHECKING:  # annotations only: the code before the renames may lack these import paths
    from spiralbayes.inference.detection import Verdict
    from spiralbayes.inference.limits import ExclusionLimits


def _templates():
    return [{"name": f"wake_m{m:g}_tau3_b10_h0.07_{h}", "mass": m, "tau0": 3.0, "beta": 10.0, "hand": h,
             "h_p": 0.07, "note": None} for m in (0.3, 1.0, 3.0) for h in ("R", "L")]


def scan_result(seed: int = 1) -> ScanResult:
    rng = np.random.default_rng(seed)
    shape = (6, 5, 8)
    power = rng.uniform(20.0, 200.0, shape)
    cross = power * rng.normal(0.0, 0.3, shape)
    cross[0, 2, 3] = 2.0 * power[0, 2, 3]  # one clear peak
    return ScanResult(_templates(), np.linspace(0.1, 0.5, 5), np.linspace(0, 2 * np.pi, 8, endpoint=False),
                      cross, power, 12345.5, 4000, DiscGeometry(30.0, 60.0, 0.001, -0.002), 140.0,
                      {"created": "now", "resume_key": {"a": 1}}, rng.uniform(0, 1e-3, shape),
                      rng.uniform(0, 1e-3, shape))


def alternatives_result() -> AlternativesResult:
    fits = {"arc": AlternativeFit("arc", "arc / vortex", 5, 40.5, [0.1, 0.3, 1.0, 0.2, 0.5],
                                  {"A": 0.1, "r_c": 0.3}, 310, 2.5, True),
            "geometry": AlternativeFit("geometry", "geometry error", 4, 3.25, [0.01, -0.02, 0.001, 0.0],
                                       {"dinc": 0.01}, 12, 0.1, False)}
    return AlternativesResult(fits, 4000, 12345.5, DiscGeometry(30.0, 60.0), DiscGrid(1.2, 40, 256),
                              {"created": "now"})


def exclusion_limits() -> ExclusionLimits:
    result = scan_result()
    result.cross[:] = -np.abs(result.cross)  # nothing detected: limits everywhere
    return compute_limits(result, resolution=0.15, bright_radius=0.45, mstar=1.0)


def completeness_result() -> CompletenessResult:
    rng = np.random.default_rng(3)
    shape = (1, 3, 5, 4)
    detected = rng.random(shape) < 0.6
    return CompletenessResult(template_families(_templates())[0], ["R"], np.array([0.3, 1.0, 3.0]),
                              np.linspace(0.1, 0.5, 5), np.linspace(0, 2 * np.pi, 4, endpoint=False), detected,
                              detected & (rng.random(shape) < 0.8), rng.normal(5.0, 10.0, shape),
                              {"amplitude": "fixed", "max_rp_steps": 1}, None, {"method": "fast"})


def forecast() -> Forecast:
    return Forecast(_templates()[4], 0.3, np.linspace(0, 2 * np.pi, 6, endpoint=False),
                    np.array([30.0, 35.0, 80.0, 60.0, 41.0, 33.0]), 250_000, 45.0,
                    {"name": "fiducial", "configurations": ["C43-8"]}, distance=140.0)


def _template_run(name: str, seed: int, mode: str = "mcmc") -> TemplateRun:
    rng = np.random.default_rng(seed)
    samples = rng.normal([0.3, 0.0, 1.0, 30.0, 60.0, 0.0, 0.0], [0.01, 0.1, 0.1, 0.5, 0.5, 0.001, 0.001], (50, 7))
    return TemplateRun(name, {"mass": 1.0, "hand": name[-1], "beta": float("nan")}, mode, samples,
                       samples[0, [0, 1, 3, 4, 5, 6]], np.diag(rng.uniform(1e-4, 1e-2, 6)), -10.5 + seed,
                       0.2 if mode == "mcmc" else float("nan"), -10.0, {"tau": {"r_p": 12.0}, "converged": False},
                       f"/tmp/chains/{name}.h5", name)


def null_run() -> NullRun:
    rng = np.random.default_rng(9)
    return NullRun(rng.normal([30.0, 60.0, 0.0, 0.0], 0.5, (40, 4)), np.array([30.0, 60.0, 0.0, 0.0]),
                   np.eye(4) * 0.01, -14.0, 0.1, -13.5, {"r": [0.1, 0.2], "I": [1e10, 5e9], "I_err": None},
                   {"time_s": 1.5})


def posterior_result() -> PosteriorResult:
    priors = Priors((0.1, 0.6), (30.0, 2.0), (60.0, 2.0), (0.0, 0.01), (0.0, 0.01), 3.0)
    runs = [_template_run("wake_R", 1), _template_run("wake_L", 2, "laplace")]
    return PosteriorResult(runs, priors, np.array([0.5, 0.5]), "test_run", "/tmp/chains/test_run.h5",
                           {"created": "now"}, null_run(), 0.4)


def planted_exclusion() -> PlantedExclusion:
    wrong = np.array([False, True, False, False, False])
    return PlantedExclusion("wake_R", "tau0=3, beta=10", 1.0, 0.3, 0.5, np.array([2.0, 0.8, np.nan, 1.5, 3.0]),
                            wrong, 0.95, {"method": "all_phi"})


def verdict() -> Verdict:
    return detect(scan_result(), alternatives=alternatives_result())


def gain_solution():
    from spiralbayes.calibration import GainSolution  # absent from the code before the renames

    rng = np.random.default_rng(5)
    gains = np.exp(1j * rng.normal(0.0, 0.2, (3, 4)))
    gains[:, 0], gains[1, 3] = 1.0, np.nan
    sigma = np.full((3, 4), 1.5)
    return GainSolution("phase", 120.0, np.array([60.0, 180.0, 300.0]), np.array([[0, 60], [120, 240], [240, 360.0]]),
                        np.arange(4), gains, np.zeros(3, dtype=np.int64), sigma, np.full((3, 4), np.nan),
                        np.array([3.0, 9.0, 11.0, np.nan]), np.zeros(4), 10.2, 0.0, 500, 5.0)


BUILDERS = {"ScanResult": scan_result, "Verdict": verdict, "AlternativesResult": alternatives_result,
            "ExclusionLimits": exclusion_limits, "CompletenessResult": completeness_result, "Forecast": forecast,
            "TemplateRun": lambda: _template_run("wake_R", 1), "NullRun": null_run,
            "PosteriorResult": posterior_result, "PlantedExclusion": planted_exclusion,
            "GainSolution": gain_solution}
