"""The grid scan: Δχ² of every template at every planet position (Stevenson et al. 2024, sec. 2.3).

* :mod:`.run` — :func:`scan`, its :class:`ScanResult`, checkpoints and resume;
* :mod:`.settings` — :class:`ScanSettings`, every scan option with its default (``[grid]``, ``[scan]``);
* :mod:`.engine` — one template at every position (:class:`ScanContext`, :class:`EngineSettings`);
* :mod:`.uv_levels` — polar uv grids for the power term;
* :mod:`.building_blocks` — morphology variants ``s T + a B`` scanned through their generator
  templates and near-planet peaks, and the cross power of any two templates;
* :mod:`.accuracy` — the self-check against exact sums and the tolerance rule;
* :mod:`.statistics` — χ², the Gaussian likelihood, ΔBIC.
"""

from .statistics import (
    N_SPIRAL_PARAMETERS,
    bic_threshold,
    chi2,
    delta_bic,
    delta_chi2_from_terms,
    fitted_amplitude,
    gaussian_log_likelihood,
)
from .uv_levels import UVLevel, build_level, level_radii, power_all_phi, theta_count, uv_weight_coefficients
from .settings import ScanSettings, grid_radii
from .engine import (
    EngineSettings,
    ScanContext,
    TemplateTerms,
    cross_template,
    direct_delta_chi2,
    perturbation_spectrum,
    profile_and_model_vis,
    scan_template,
    with_residual,
)
from .accuracy import CHECK_AZIMUTHS, EXACT_EPSILON, TOLERANCE, check_terms, exact_terms, warn_if_inaccurate
from .building_blocks import VariantGroup, building_block_groups, pair_terms, scan_group
from .run import ScanPeak, ScanResult, default_rp_grid, resume_key, scan

__all__ = [
    "CHECK_AZIMUTHS",
    "EXACT_EPSILON",
    "EngineSettings",
    "N_SPIRAL_PARAMETERS",
    "ScanContext",
    "ScanPeak",
    "ScanResult",
    "ScanSettings",
    "TOLERANCE",
    "TemplateTerms",
    "UVLevel",
    "VariantGroup",
    "bic_threshold",
    "build_level",
    "check_terms",
    "chi2",
    "cross_template",
    "default_rp_grid",
    "delta_bic",
    "delta_chi2_from_terms",
    "direct_delta_chi2",
    "exact_terms",
    "fitted_amplitude",
    "gaussian_log_likelihood",
    "level_radii",
    "pair_terms",
    "perturbation_spectrum",
    "grid_radii",
    "power_all_phi",
    "profile_and_model_vis",
    "resume_key",
    "scan",
    "scan_group",
    "scan_template",
    "theta_count",
    "uv_weight_coefficients",
    "building_block_groups",
    "warn_if_inaccurate",
    "with_residual",
]
