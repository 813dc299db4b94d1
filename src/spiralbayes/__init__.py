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

from . import exceptions  # noqa: E402
from ._version import __version__  # noqa: E402
from .axisymmetric import AxisymmetricModel, FrankSettings, fit_axisymmetric  # noqa: E402
from .geometry import DiscGeometry  # noqa: E402
from .inference.detection.alternatives import AlternativesResult, fit_alternatives  # noqa: E402
from .inference.detection.settings import AlternativesSettings, DetectionSettings  # noqa: E402
from .inference.detection.follow_up import rescan_at_fitted_geometry  # noqa: E402
from .inference.detection.verdict import Verdict, detect  # noqa: E402
from .inference.limits.exclusion import ExclusionLimits, compute_limits  # noqa: E402
from .inference.limits.forecasting import Forecast, forecast  # noqa: E402
from .inference.limits.recovery import CompletenessResult, completeness  # noqa: E402
from .inference.limits.settings import CompletenessSettings, ForecastSettings, LimitSettings  # noqa: E402
from .inference.posterior.conditional import SpiralLikelihood  # noqa: E402
from .inference.posterior.priors import Priors  # noqa: E402
from .inference.posterior.results import PosteriorResult  # noqa: E402
from .inference.posterior.sampler import sample_posterior  # noqa: E402
from .inference.posterior.settings import PriorSettings, SamplingSettings  # noqa: E402
from .inference.scan.run import ScanResult, scan  # noqa: E402
from .inference.scan.settings import ScanSettings  # noqa: E402
from .io import load_visibilities, save_visibilities  # noqa: E402
from .simulate import PRESETS, DiscModel, simulate_observation, uv_coverage  # noqa: E402
from .templates import SpiralTemplate, TemplateBank, compromise_bank, default_bank, make_template, variant_bank  # noqa: E402
from .visibilities import Visibilities, bin_deprojected, estimate_weights  # noqa: E402

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
        "estimate_weights", "PRESETS", "DiscModel", "simulate_observation", "uv_coverage"]
"""Data: visibilities, disc geometry, files, synthetic observations."""
MODELS = ["AxisymmetricModel", "FrankSettings", "fit_axisymmetric", "SpiralTemplate", "TemplateBank", "default_bank",
          "compromise_bank", "variant_bank", "make_template"]
"""Models: the axisymmetric (frank) profile and the spiral templates."""
SEARCH = ["ScanResult", "ScanSettings", "scan"]
"""Search: the template scan."""
DETECTION = ["Verdict", "DetectionSettings", "detect", "AlternativesResult", "AlternativesSettings", "fit_alternatives",
             "rescan_at_fitted_geometry"]
"""Detection: tests 1-3, the competing asymmetries, the geometry follow-up."""
LIMITS = ["ExclusionLimits", "LimitSettings", "compute_limits", "CompletenessResult", "CompletenessSettings",
          "completeness", "Forecast", "ForecastSettings", "forecast"]
"""Limits: exclusion limits, completeness, forecasts."""
POSTERIOR = ["PosteriorResult", "Priors", "PriorSettings", "SamplingSettings", "SpiralLikelihood", "sample_posterior"]
"""Posterior: the sampled posterior and its parts."""
PLOTTING = ["plotting"]
"""Plotting: ``spiralbayes.plotting`` (Matplotlib, imported on first use)."""
SURVEY = ["run_survey"]
"""Survey: many discs on Dask (imported on first use)."""

__all__ = ["__version__", "exceptions", *DATA, *MODELS, *SEARCH, *DETECTION, *LIMITS, *POSTERIOR, *PLOTTING,
           *SURVEY]
