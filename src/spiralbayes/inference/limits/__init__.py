"""What the data rule out and what they could detect: exclusion limits, completeness, forecasts.

* :mod:`.exclusion` — :func:`compute_limits`, the limiting mass M_lim(r_p); :mod:`.settings` — its options;
* :mod:`.families` — templates grouped by everything but mass and hand;
* :mod:`.table3` — the paper's Table 3 from computed limits (astropy Table, ECSV and Markdown);
* :mod:`.wording` — thresholds, r_p ranges and sentences as every output spells them;
* :mod:`.injection` — injected planets' Δχ² without re-scanning;
* :mod:`.recovery` — detection completeness by injection–recovery, M_det;
* :mod:`.forecasting` — expected Δχ², detection probability and time on source for a set-up.
* :mod:`.robust` — limits over several families and morphology variants (robust exclusion).
"""

from .families import Family, select_family, template_families
from .settings import (
    HANDS,
    LIMIT_METHODS,
    TABLE3_THRESHOLDS,
    CompletenessSettings,
    ForecastSettings,
    LimitSettings,
)
from .table3 import (
    build_table3,
    describe_family_limits,
    families_text,
    limits_table,
    markdown_table,
    price_text,
    table_markdown,
    write_table,
)
from .wording import THRESHOLDS, format_range, format_ranges, guard_sentences, runs
from .exclusion import (
    ExclusionLimits,
    amplitude_upper_limit,
    compute_limits,
    data_resolution,
    bright_extent,
    z_score,
)
from .guards import ASYMMETRY_THRESHOLD, asymmetry_bands, candidate_source, planet_radii
from .injection import Injection, InjectionEngine, brute_force_injection, injected_cross_reference
from .recovery import (
    CompletenessResult,
    completeness,
    completeness_brute_force,
    injection_engine,
    injection_plan,
)
from .forecasting import Forecast, compare_setups, detectable_mass, forecast, format_minutes, setup_for_time

from .robust import (
    H_P_SENSITIVE_TAU0,
    SINGLE_VARIANT,
    UNLABELLED,
    aspect_ratio_note,
    combined_m_lim,
    combined_m_lim_mjup,
    describe_over_families,
    family_morphology,
    morphologies,
    morphology_note,
    near_planet_mask,
    overall_price,
    price_of_robustness,
    variant_groups,
)

__all__ = [
    "H_P_SENSITIVE_TAU0",
    "aspect_ratio_note",
    "UNLABELLED",
    "family_morphology",
    "morphologies",
    "morphology_note",
    "overall_price",
    "variant_groups",
    "price_of_robustness",
    "near_planet_mask",
    "describe_over_families",
    "combined_m_lim_mjup",
    "combined_m_lim",
    "SINGLE_VARIANT",
    "CompletenessResult",
    "CompletenessSettings",
    "HANDS",
    "LIMIT_METHODS",
    "TABLE3_THRESHOLDS",
    "ExclusionLimits",
    "Family",
    "Forecast",
    "ForecastSettings",
    "Injection",
    "InjectionEngine",
    "LimitSettings",
    "amplitude_upper_limit",
    "ASYMMETRY_THRESHOLD",
    "THRESHOLDS",
    "asymmetry_bands",
    "candidate_source",
    "planet_radii",
    "bright_extent",
    "build_table3",
    "brute_force_injection",
    "compare_setups",
    "completeness",
    "completeness_brute_force",
    "compute_limits",
    "data_resolution",
    "describe_family_limits",
    "families_text",
    "format_range",
    "format_ranges",
    "guard_sentences",
    "detectable_mass",
    "forecast",
    "format_minutes",
    "injected_cross_reference",
    "injection_engine",
    "injection_plan",
    "limits_table",
    "markdown_table",
    "price_text",
    "runs",
    "select_family",
    "setup_for_time",
    "table_markdown",
    "template_families",
    "write_table",
    "z_score",
]
