"""The verdict on a scan: tests 1 and 2, the competing asymmetries (test 3) and the geometry follow-up.

* :mod:`.verdict` — :func:`detect` and its :class:`Verdict`;
* :mod:`.alternatives` — maximum-likelihood fits of the non-spiral asymmetries, scored by ΔBIC;
* :mod:`.settings` — the verdict's thresholds, :class:`DetectionSettings`, and the alternatives' options,
  :class:`AlternativesSettings`;
* :mod:`.starts` — their starting points, read off the residual dirty image;
* :mod:`.follow_up` — refit frank at the fitted geometry, scan again, decide again.
* :mod:`.geometry_fit` — the geometry alternative's least squares in memory that does not grow with the data;
* :mod:`.planet_peak` — the spiral hypothesis as spiral + compact source at the planet, scored in test 3.
* :mod:`.nested` — test 3 as a nested question: the best alternatives fitted jointly with the spiral;
* :mod:`.explanation` — what the verdict names as the residual structure's cause (calibration included);
* :mod:`~spiralbayes.inference.detection.kinds` — where the generator's templates and simulated maps
  each put the planet;
* :mod:`~spiralbayes.inference.detection.mass` — the planet's mass range;
* :mod:`.candidate` — the compact source a verdict names when a planet and another model both explain it.
"""

from .verdict import (
    Verdict,
    best_handed_candidate,
    detect,
    detect_with_planet_peak,
    handedness_ratio,
    localisation,
    mass_range,
    mirror_index,
    one_sidedness,
)
from .settings import (CANDIDATE_THRESHOLD, COMPACT_ARC_WIDTH, DELTA_BIC_THRESHOLD, MASS_BAND, NESTED_THRESHOLD,
                       AlternativesSettings, DetectionSettings)
from .candidate import (OUTCOMES, arc_excess_flux, compact_source, deeper_time_factor, explanation_labels,
                        next_steps_sentence)
from .nested import (HYPOTHESES, NestedFit, also_present_phrase, apply_nested, best_nested_test, nested_candidates,
                     nested_fit, nested_test)
from .explanation import (calibration_explains, calibration_sentence, explain, nested_sentence, phase_warns, rediagnose,
                          rediagnose_with_spiral, withhold)
from .kinds import best_by_kind, kind_position_sentence
from .starts import candidate_starts, linear_amplitudes
from .alternatives import (
    ALTERNATIVES_KIND,
    AlternativeFit,
    AlternativesResult,
    delta_chi2_direct,
    fit_alternatives,
)
from .follow_up import GeometryFollowUp, frank_settings, rescan_at_fitted_geometry
from .geometry_fit import BLOCK, GEOMETRY_SCALES, fit_geometry_offsets, geometry_bounds, normal_equations

from .planet_peak import (
    COMPACT_ALTERNATIVES,
    apply_planet_peak,
    rescore_with_planet_peak,
    spiral_with_planet_peak,
)

__all__ = [
    "CANDIDATE_THRESHOLD",
    "COMPACT_ARC_WIDTH",
    "OUTCOMES",
    "arc_excess_flux",
    "compact_source",
    "deeper_time_factor",
    "explanation_labels",
    "next_steps_sentence",
    "NESTED_THRESHOLD",
    "HYPOTHESES",
    "NestedFit",
    "also_present_phrase",
    "apply_nested",
    "best_nested_test",
    "nested_candidates",
    "nested_fit",
    "nested_test",
    "best_by_kind",
    "kind_position_sentence",
    "calibration_explains",
    "calibration_sentence",
    "explain",
    "nested_sentence",
    "rediagnose",
    "rediagnose_with_spiral",
    "phase_warns",
    "withhold",
    "rescore_with_planet_peak",
    "spiral_with_planet_peak",
    "apply_planet_peak",
    "detect_with_planet_peak",
    "COMPACT_ALTERNATIVES",
    "ALTERNATIVES_KIND",
    "AlternativeFit",
    "AlternativesResult",
    "AlternativesSettings",
    "DELTA_BIC_THRESHOLD",
    "DetectionSettings",
    "MASS_BAND",
    "GeometryFollowUp",
    "Verdict",
    "best_handed_candidate",
    "candidate_starts",
    "delta_chi2_direct",
    "detect",
    "fit_alternatives",
    "frank_settings",
    "handedness_ratio",
    "linear_amplitudes",
    "localisation",
    "mass_range",
    "mirror_index",
    "one_sidedness",
    "rescan_at_fitted_geometry",
    "BLOCK",
    "GEOMETRY_SCALES",
    "fit_geometry_offsets",
    "geometry_bounds",
    "normal_equations",
]
