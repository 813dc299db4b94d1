"""The posterior: no planet against a planet of each template, profile and amplitude integrated out.

* :mod:`.priors` — the parameters' priors;
* :mod:`.likelihood` — the sampled likelihood (profile and amplitude marginalised);
* :mod:`.conditional` — the likelihood at a fixed profile, the reference (:class:`SpiralLikelihood`);
* :mod:`.interpolation`, :mod:`.perturbation` — the fast perturbation tables;
* :mod:`.optimise` — the modes before sampling; :mod:`.evidence` — evidences and Bayes factors;
  :mod:`.scan_evidence` — the Bayes factors read off the scan's grid (which templates get a chain);
* :mod:`.sampler` — :func:`sample_posterior`; :mod:`.settings` — its :class:`SamplingSettings` and
  :class:`PriorSettings`; :mod:`.moves` — the wrapped DE move;
* :mod:`.chains`, :mod:`.chain_runner` — kill-safe chain files (an emcee backend) and the chain loop;
  :mod:`.forked` — forked worker processes that inherit the tables;
* :mod:`.diagnostics` — convergence; :mod:`.stopping` — when a chain may stop (every parameter, or
  the geometry and the evidence when the planet is not preferred);
* :mod:`.results` — :class:`PosteriorResult` and its runs;
* :mod:`~spiralbayes.inference.posterior.mass`, :mod:`.family_run` — the planet mass sampled within a template family
  (``mass="continuous"``);
* :mod:`.physics` — the disc's physics (H/r, slope, α, age) and the mass on a learned model's lattice
  (:func:`physics_posterior`);
* :mod:`.odds` — the posterior odds between a planet and the competing explanations (arc, eccentric ring).
"""

from .likelihood import (
    DEFAULT_AMPLITUDE_MAX,
    MarginalSpiralLikelihood,
    ProfileMarginal,
    draw_amplitude,
    log_amplitude_integral,
)
from .conditional import PARAMETER_LABELS, PARAMETER_NAMES, SpiralLikelihood, geometry_from_theta
from .interpolation import AxisymmetricTable, PerturbationTable
from .perturbation import CHECK_MARGIN, CHECKED_MIDPOINTS, FastPerturbation
from .priors import DEFAULT_WIDTHS, GEOMETRY_NAMES, N_DIM, Priors
from .moves import DEFAULT_MOVES, EnsembleGaussianMove, WrappedDEMove, default_moves
from .diagnostics import TAU_FACTOR, arviz_diagnostics, chain_inference_data, convergence_diagnostics
from .results import MASS_SAMPLE_NAMES, SAMPLE_NAMES, NullRun, PosteriorResult, TemplateRun, wrap_phi
from .chains import CHAIN_KIND, ChainBackend, ChainState, ChainStore
from .forked import can_fork, forked_map, pin_threads
from .chain_runner import (
    MAX_AUTO_THREADS,
    ThreadMap,
    WalkerPool,
    initial_walkers,
    make_pool,
    resolve_processes,
    resolve_threads,
    run_chain,
    streams,
    walker_pool,
)
from .evidence import GaussianGeometry, importance_evidence, laplace_evidence, savage_dickey_log_bayes
from .optimise import find_map, fit_null_geometry
from .stopping import MAX_LN_B_ERROR, StoppingRule, template_evidence
from .settings import CONVERGENCE_POLICIES, MASS_MODES, PRUNED_EVIDENCE, PriorSettings, SamplingSettings
from .mass import (
    MASS_PARAMETER_NAMES,
    MASS_SYSTEMATIC,
    FamilyPerturbation,
    MassLikelihood,
    MassLogPosterior,
    MassPrior,
    family_of,
    group_families,
)
from .family_run import family_evidence, family_metadata, family_name, sample_family
from .scan_evidence import GRID_LN_B_ERROR, GridEvidence, family_grid_evidence, grid_run, template_grid_evidence
from .sampler import LogPosterior, NullLogPosterior, lower_grid_runs, refit_axisymmetric, sample_posterior
from .physics import (
    DEFAULT_AGES,
    DEFAULT_H_STEP,
    DEFAULT_N_MASSES,
    DEFAULT_REFINE,
    GRID_FACTOR,
    PHYSICS_AXES,
    RESOLUTION_TOLERANCE,
    PhysicsPosterior,
    default_ages,
    physics_posterior,
)
from .position import (
    MIN_WINDOW_STEPS,
    REFINE_LN_B_RANGE,
    UPSAMPLE,
    PositionLevel,
    composite_ln_bayes,
    grid_log_likelihood,
    peak_window,
    position_ln_bayes,
)
from .odds import NO_ASYMMETRY, check_alternatives, hypothesis_weights, model_probabilities, scan_alternatives

__all__ = [
    "DEFAULT_AGES",
    "DEFAULT_H_STEP",
    "DEFAULT_N_MASSES",
    "DEFAULT_REFINE",
    "GRID_FACTOR",
    "PHYSICS_AXES",
    "RESOLUTION_TOLERANCE",
    "default_ages",
    "UPSAMPLE",
    "MIN_WINDOW_STEPS",
    "REFINE_LN_B_RANGE",
    "PositionLevel",
    "composite_ln_bayes",
    "grid_log_likelihood",
    "peak_window",
    "PhysicsPosterior",
    "physics_posterior",
    "position_ln_bayes",
    "NO_ASYMMETRY",
    "check_alternatives",
    "hypothesis_weights",
    "lower_grid_runs",
    "model_probabilities",
    "scan_alternatives",
    "can_fork",
    "forked_map",
    "pin_threads",
    "MAX_AUTO_THREADS",
    "ThreadMap",
    "resolve_processes",
    "resolve_threads",
    "GRID_LN_B_ERROR",
    "GridEvidence",
    "PRUNED_EVIDENCE",
    "family_grid_evidence",
    "grid_run",
    "template_grid_evidence",
    "AxisymmetricTable",
    "FamilyPerturbation",
    "MASS_MODES",
    "MASS_PARAMETER_NAMES",
    "MASS_SAMPLE_NAMES",
    "MASS_SYSTEMATIC",
    "MassLikelihood",
    "MassLogPosterior",
    "MassPrior",
    "family_evidence",
    "family_metadata",
    "family_name",
    "family_of",
    "group_families",
    "sample_family",
    "CHAIN_KIND",
    "ChainBackend",
    "ChainState",
    "ChainStore",
    "CONVERGENCE_POLICIES",
    "DEFAULT_AMPLITUDE_MAX",
    "DEFAULT_MOVES",
    "DEFAULT_WIDTHS",
    "CHECKED_MIDPOINTS",
    "CHECK_MARGIN",
    "EnsembleGaussianMove",
    "FastPerturbation",
    "GEOMETRY_NAMES",
    "GaussianGeometry",
    "LogPosterior",
    "MAX_LN_B_ERROR",
    "MarginalSpiralLikelihood",
    "N_DIM",
    "NullLogPosterior",
    "NullRun",
    "PARAMETER_LABELS",
    "PARAMETER_NAMES",
    "PerturbationTable",
    "PosteriorResult",
    "PriorSettings",
    "Priors",
    "ProfileMarginal",
    "SAMPLE_NAMES",
    "SamplingSettings",
    "SpiralLikelihood",
    "StoppingRule",
    "TAU_FACTOR",
    "TemplateRun",
    "WalkerPool",
    "WrappedDEMove",
    "arviz_diagnostics",
    "chain_inference_data",
    "convergence_diagnostics",
    "default_moves",
    "draw_amplitude",
    "find_map",
    "fit_null_geometry",
    "geometry_from_theta",
    "importance_evidence",
    "initial_walkers",
    "laplace_evidence",
    "log_amplitude_integral",
    "make_pool",
    "refit_axisymmetric",
    "run_chain",
    "sample_posterior",
    "savage_dickey_log_bayes",
    "streams",
    "template_evidence",
    "walker_pool",
    "wrap_phi",
]
