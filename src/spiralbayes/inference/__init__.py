"""Inference, by stage: the grid scan, its verdict, what the data rule out, and the posterior.

* :mod:`.scan` — Δχ² of every template at every planet position (:func:`~.scan.run.scan`), χ² and BIC;
* :mod:`.detection` — the paper's tests 1–3 on a scan (:func:`detect`), the competing asymmetries'
  fits and the geometry follow-up;
* :mod:`.limits` — exclusion limits, template families, the paper's Table 3, injection–recovery
  completeness and observation forecasts;
* :mod:`.posterior` — the emcee posterior with templates as a discrete choice: priors, the sampled
  (marginal) likelihood, the fixed-profile reference likelihood, evidences, chains, results;
* :mod:`.validation` — calibration harnesses (SBC, planted planets); tests and benchmarks import
  it, runtime code does not, so it is not imported here.

Every public name of the four runtime stages is re-exported here (``from spiralbayes.inference
import detect``), except ``scan``, which names the subpackage; the function is
``spiralbayes.scan`` or ``spiralbayes.inference.scan.scan``.
"""

from . import detection, limits, posterior, scan
from .detection import *  # noqa: F403
from .limits import *  # noqa: F403
from .posterior import *  # noqa: F403
from .scan import (  # not ``scan``: that name is the subpackage
    CHECK_AZIMUTHS,
    EXACT_EPSILON,
    N_SPIRAL_PARAMETERS,
    EngineSettings,
    ScanContext,
    ScanPeak,
    ScanResult,
    ScanSettings,
    TOLERANCE,
    TemplateTerms,
    UVLevel,
    VariantGroup,
    bic_threshold,
    build_level,
    check_terms,
    chi2,
    cross_template,
    default_rp_grid,
    delta_bic,
    delta_chi2_from_terms,
    direct_delta_chi2,
    exact_terms,
    fitted_amplitude,
    gaussian_log_likelihood,
    grid_radii,
    level_radii,
    pair_terms,
    perturbation_spectrum,
    power_all_phi,
    profile_and_model_vis,
    resume_key,
    scan_group,
    scan_template,
    theta_count,
    uv_weight_coefficients,
    building_block_groups,
    warn_if_inaccurate,
    with_residual,
)

__all__ = ["detection", "limits", "posterior", "scan", *detection.__all__, *limits.__all__,
           *posterior.__all__, *(n for n in scan.__all__ if n != "scan")]
