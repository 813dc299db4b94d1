"""spiralbayes: search ALMA visibilities for planet-driven dust spirals.

Implements and extends Stevenson et al. (2024, MNRAS), "Searching for planet-driven dust
spirals in ALMA visibilities". See ``docs/conventions.md`` for units and signs.

A notebook session needs only the names exported here::

    import spiralbayes as sb
    vis = sb.load_visibilities("disc.txt")
    disc = sb.fit_axisymmetric(vis, sb.DiscGeometry(inc=30, PA=60))
    result = sb.scan(vis, disc, sb.default_bank().select(tau0=3, beta=10))
    print(sb.detect(result).summary())
"""

import logging

__version__ = "0.1.0"

from .axisymmetric import AxisymmetricModel, fit_axisymmetric  # noqa: E402
from .detection import Verdict, detect  # noqa: E402
from .geometry import DiscGeometry  # noqa: E402
from .posterior import SpiralLikelihood  # noqa: E402
from .sampling import PosteriorResult, Priors, sample_posterior  # noqa: E402
from .scan import ScanResult, scan  # noqa: E402
from .simulate import PRESETS, DiscModel, simulate_observation, uv_coverage  # noqa: E402
from .templates import SpiralTemplate, TemplateBank, default_bank, make_template  # noqa: E402
from .visibilities import (  # noqa: E402
    Visibilities,
    bin_deprojected,
    estimate_weights,
    load_visibilities,
    save_visibilities,
)

logging.getLogger(__name__).addHandler(logging.NullHandler())

__all__ = [
    "PRESETS",
    "PosteriorResult",
    "Priors",
    "SpiralLikelihood",
    "AxisymmetricModel",
    "DiscGeometry",
    "DiscModel",
    "ScanResult",
    "SpiralTemplate",
    "TemplateBank",
    "Verdict",
    "Visibilities",
    "__version__",
    "bin_deprojected",
    "default_bank",
    "detect",
    "estimate_weights",
    "fit_axisymmetric",
    "load_visibilities",
    "make_template",
    "sample_posterior",
    "save_visibilities",
    "scan",
    "simulate_observation",
    "uv_coverage",
]
