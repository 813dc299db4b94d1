"""spiralbayes: search ALMA visibilities for planet-driven dust spirals.

Implements and extends Stevenson et al. (2024, MNRAS), "Searching for planet-driven dust
spirals in ALMA visibilities". See ``docs/conventions.md`` for units and signs.

A notebook session needs only the names exported here::

    import spiralbayes as sb
    vis = sb.load_visibilities("disc.txt")
    disc = sb.fit_axisymmetric(vis, sb.DiscGeometry(inc=30, PA=60))
    result = sb.scan(vis, disc, sb.default_bank().select(tau0=3, beta=10, h_p=0.07))
    print(sb.detect(result).summary())
"""

import logging

from . import exceptions
from ._version import __version__
from .calibration import (CalibrationDiagnostic, CalibrationSettings, GainSolution, diagnose_calibration, selfcal,
                          solve_gains)
from .axisymmetric import AxisymmetricModel, FrankSettings, fit_axisymmetric
from .geometry import DiscGeometry
from .inference.detection.alternatives import AlternativesResult, fit_alternatives
from .inference.detection.settings import AlternativesSettings, DetectionSettings
from .inference.detection.follow_up import rescan_at_fitted_geometry
from .inference.detection.verdict import Verdict, detect
from .inference.limits.exclusion import ExclusionLimits, compute_limits
from .inference.limits.forecasting import Forecast, forecast
from .inference.limits.recovery import CompletenessResult, completeness
from .inference.limits.settings import CompletenessSettings, ForecastSettings, LimitSettings
from .inference.posterior.conditional import SpiralLikelihood
from .inference.posterior.mass import MassPrior
from .inference.posterior.physics import PhysicsPosterior, physics_posterior
from .inference.posterior.priors import Priors
from .inference.posterior.results import PosteriorResult
from .inference.posterior.sampler import sample_posterior
from .inference.posterior.settings import PriorSettings, SamplingSettings
from .inference.scan.run import ScanResult, scan
from .inference.scan.settings import ScanSettings
from .io import load_visibilities, save_visibilities
from .simulate import PRESETS, DiscModel, GainErrors, simulate_observation, uv_coverage
from .templates import (
    SpiralTemplate,
    TemplateBank,
    TemplateFamily,
    compromise_bank,
    default_bank,
    make_template,
    variant_bank,
)
from .averaging import AveragingReport, average_visibilities
from .visibilities import Visibilities, bin_deprojected, estimate_weights

logging.getLogger(__name__).addHandler(logging.NullHandler())


def __getattr__(name):
    # plotting imports Matplotlib: loaded on first use (``sb.plotting.plot_corner``), not at import time
    if name == "plotting":
        import importlib

        return importlib.import_module(".plotting", __name__)
    if name == "run_survey":  # the survey runner imports dask.distributed: loaded on first use too
        from .pipeline.survey import run_survey

        return run_survey
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# The public names, grouped by stage (as astropy.cosmology's ``__all__``); each stage's list is also
# importable, e.g. ``spiralbayes.POSTERIOR``.
DATA = ["Visibilities", "DiscGeometry", "load_visibilities", "save_visibilities", "bin_deprojected",
        "estimate_weights", "average_visibilities", "AveragingReport",
        "PRESETS", "DiscModel", "GainErrors", "simulate_observation", "uv_coverage",
        "CalibrationDiagnostic", "diagnose_calibration", "CalibrationSettings", "GainSolution", "solve_gains",
        "selfcal"]
"""Data: visibilities, disc geometry, files, synthetic observations (with gain errors), calibration checks and
antenna gain solves."""
MODELS = ["AxisymmetricModel", "FrankSettings", "fit_axisymmetric", "SpiralTemplate", "TemplateBank", "default_bank",
          "compromise_bank", "variant_bank", "make_template", "TemplateFamily"]
"""Models: the axisymmetric (frank) profile and the spiral templates."""
SEARCH = ["ScanResult", "ScanSettings", "scan"]
"""Search: the template scan."""
DETECTION = ["Verdict", "DetectionSettings", "detect", "AlternativesResult", "AlternativesSettings", "fit_alternatives",
             "rescan_at_fitted_geometry"]
"""Detection: tests 1-3, the competing asymmetries, the geometry follow-up."""
LIMITS = ["ExclusionLimits", "LimitSettings", "compute_limits", "CompletenessResult", "CompletenessSettings",
          "completeness", "Forecast", "ForecastSettings", "forecast"]
"""Limits: exclusion limits, completeness, forecasts."""
POSTERIOR = ["PosteriorResult", "Priors", "MassPrior", "PriorSettings", "SamplingSettings", "SpiralLikelihood",
             "sample_posterior", "PhysicsPosterior", "physics_posterior"]
"""Posterior: the sampled posterior and its parts."""
PLOTTING = ["plotting"]
"""Plotting: ``spiralbayes.plotting`` (Matplotlib, imported on first use)."""
SURVEY = ["run_survey"]
"""Survey: many discs on Dask (imported on first use)."""

__all__ = ["__version__", "exceptions", *DATA, *MODELS, *SEARCH, *DETECTION, *LIMITS, *POSTERIOR, *PLOTTING,
           *SURVEY]
