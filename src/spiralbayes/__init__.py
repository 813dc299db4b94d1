"""spiralbayes: search ALMA visibilities for planet-driven dust spirals.

Implements and extends Stevenson et al. (2024, MNRAS), "Searching for planet-driven dust
spirals in ALMA visibilities". See ``docs/conventions.md`` for units and signs.
"""

import logging

__version__ = "0.1.0"

from .geometry import DiscGeometry  # noqa: E402
from .visibilities import Visibilities  # noqa: E402

logging.getLogger(__name__).addHandler(logging.NullHandler())

__all__ = ["DiscGeometry", "Visibilities", "__version__"]
