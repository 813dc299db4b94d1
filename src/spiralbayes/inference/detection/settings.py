"""How a scan is judged: :class:`DetectionSettings` (tests 1-3 of :func:`~spiralbayes.inference.detection.detect`)
and :class:`AlternativesSettings` (how test 3's competing asymmetries are fitted, ``[alternatives]``)."""

from __future__ import annotations

import numbers
from dataclasses import dataclass

from ...alternatives import ALTERNATIVE_MODELS, DEFAULT_CELL_FACTOR
from ...exceptions import InputError
from ...settings import DEFAULT_MSTAR_MSUN, documented, is_finite_number, is_integer, option

__all__ = ["AlternativesSettings", "CANDIDATE_THRESHOLD", "COMPACT_ARC_WIDTH", "DELTA_BIC_THRESHOLD",
           "DetectionSettings", "MASS_BAND", "NESTED_THRESHOLD"]

DELTA_BIC_THRESHOLD = 10.0
"""Test 1: the best template's ΔBIC must exceed this ("very strong" evidence, Stevenson et al. 2024)."""
MASS_BAND = 10.0
"""Templates within this ΔBIC of the best (near its position) make the reported mass range."""
NESTED_THRESHOLD = 10.0
"""Nested test 3: BIC(alternative) − BIC(alternative + spiral) must exceed this (docs/verdict.md: calibration)."""
CANDIDATE_THRESHOLD = -30.0
"""Test 3's statistic above which a spiral that fails only test 3 is a candidate (docs/verdict.md, "Candidates")."""
COMPACT_ARC_WIDTH = 40.0
"""Widest arc fit [deg, sigma_phi] that names a candidate compact source (docs/verdict.md, "Candidates")."""


@documented
@dataclass(frozen=True)
class AlternativesSettings:
    """Options of :func:`~spiralbayes.inference.detection.fit_alternatives` and of test 3 in
    :func:`~spiralbayes.inference.detection.detect` (TOML section ``[alternatives]``, which adds the
    pipeline's switches ``fit`` and ``refit_geometry``).

    Every field's description is its ``metadata["doc"]``; ``help()``, the API pages and ``--print-config`` show them.
    """

    models: tuple | None = option(None, "which of geometry, arc, lopsided, eccentric_ring, eccentric_excess, m2 to fit "
                                  "(empty: all)",
                                  toml=[])
    threshold: float = option(10.0, "test 3: the spiral's Delta BIC must exceed the best alternative's by more "
                                    "than this")
    n_starts: int = option(2, "optimiser starts per alternative model (the shapes that best match the residual "
                              "image)")
    # code only
    max_iter: int = option(100, "L-BFGS-B iterations per start", config=False)
    r_max: float | None = option(None, "outer radius of the grid [arcsec] (default: 1.1 times the radius holding "
                                       "99.5 % of the profile's flux)", config=False)
    cell_factor: float = option(DEFAULT_CELL_FACTOR, "radial cells at most 1 / (cell_factor uv_max) wide",
                                config=False)
    nthreads: int = option(1, "threads of the NUFFTs (the pipeline uses [scan] nthreads)", config=False)

    def __post_init__(self):
        if self.models is not None:
            unknown = [m for m in self.models if m not in ALTERNATIVE_MODELS]
            if isinstance(self.models, str) or unknown:
                raise InputError(f"models = {self.models!r} names an unknown asymmetry model; choose from "
                                 f"{', '.join(repr(m) for m in ALTERNATIVE_MODELS)}")
        if not is_finite_number(self.threshold):
            raise InputError(f"threshold = {self.threshold!r} must be a finite number (Delta BIC)")
        if not is_integer(self.n_starts) or self.n_starts < 1:
            raise InputError(f"n_starts = {self.n_starts!r} must be an integer >= 1")
        if not is_integer(self.max_iter) or self.max_iter < 1:
            raise InputError(f"max_iter = {self.max_iter!r} must be an integer >= 1")


@documented
@dataclass(frozen=True)
class DetectionSettings:
    """Thresholds of the verdict (:func:`~spiralbayes.inference.detection.detect`): tests 1 and 2 of
    Stevenson et al. (2024), test 3 against the competing asymmetries, and the reported mass range.

    Every field's description is its ``metadata["doc"]``.
    """

    neighbourhood: int = option(2, "test 2: radius steps around the best instance searched for the mirror "
                                   "template's Delta chi^2")
    max_handedness_ratio: float = option(0.5, "test 2: the mirror template's Delta chi^2 near the peak must be "
                                              "below this fraction of the best")
    max_localisation: float = option(0.1, "test 2: fraction of the scanned disc area above half the peak must be "
                                          "below this")
    bic_threshold_value: float = option(DELTA_BIC_THRESHOLD, "test 1: the best template's Delta BIC must exceed "
                                                             "this")
    alternative_threshold: float = option(AlternativesSettings.threshold, "test 3: the spiral's Delta BIC must "
                                          "exceed the best alternative's by more than this")
    nested_threshold: float = option(NESTED_THRESHOLD, "test 3 (nested): the spiral must lower the BIC of the best "
                                     "alternative model by more than this when fitted jointly with it")
    candidate_threshold: float = option(CANDIDATE_THRESHOLD, "a spiral that passes tests 1 and 2 but not test 3 "
                                        "is named a candidate compact source when test 3's statistic exceeds this")
    compact_arc_width: float = option(COMPACT_ARC_WIDTH, "an arc/vortex fit at most this wide in azimuth "
                                      "(sigma_phi [deg]) names a candidate compact source when no spiral passes "
                                      "tests 1 and 2")
    nested_alternatives: int = option(2, "test 3 (nested): how many alternatives, best first, each get a joint "
                                         "fit with the spiral (the spiral must pass against every one)")
    mass_band: float = option(MASS_BAND, "Delta BIC band of the templates that make the reported mass range")
    mstar: float = option(DEFAULT_MSTAR_MSUN, "stellar mass [M_sun], for the mass range in M_Jup "
                                              "(M_th = h_p^3 M_*)")

    def __post_init__(self):
        if not is_integer(self.neighbourhood) or self.neighbourhood < 0:
            raise InputError(f"neighbourhood = {self.neighbourhood!r} must be an integer >= 0 (radius steps)")
        for name in ("max_handedness_ratio", "max_localisation"):
            value = getattr(self, name)
            # infinity switches the criterion off
            if isinstance(value, bool) or not isinstance(value, numbers.Real) or not float(value) > 0:
                raise InputError(f"{name} = {value!r} must be a positive fraction (inf: no limit)")
        if not is_integer(self.nested_alternatives) or self.nested_alternatives < 1:
            raise InputError(f"nested_alternatives = {self.nested_alternatives!r} must be an integer >= 1")
        for name in ("bic_threshold_value", "alternative_threshold", "nested_threshold", "mass_band",
                     "candidate_threshold"):
            if not is_finite_number(getattr(self, name)):
                raise InputError(f"{name} = {getattr(self, name)!r} must be a finite number (Delta BIC)")
        if not is_finite_number(self.compact_arc_width) or not 0 < self.compact_arc_width <= 180:
            raise InputError(f"compact_arc_width = {self.compact_arc_width!r} must be an azimuthal width in "
                             "(0, 180] deg")
        if not is_finite_number(self.mstar) or self.mstar <= 0:
            raise InputError(f"mstar = {self.mstar!r} must be a positive stellar mass [M_sun]")
