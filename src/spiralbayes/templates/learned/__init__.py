"""A spiral-template model continuous in disc physics, learned from hydrodynamic runs.

The variant bank holds templates at a few masses and aspect ratios of one disc (Σ ∝ r⁻¹, one
viscosity, 20 orbits). :class:`~spiralbayes.templates.learned.model.LearnedTemplateModel` returns a
template at any planet mass ``M_p``, aspect ratio ``h_p = H/r`` at the planet, surface-density slope
``p`` (Σ ∝ r^-p), viscosity ``α`` at the planet and age (orbits) inside the box its training runs
span, from a low-rank model of the runs' surface-density maps. Its leave-one-run-out error
(``tools/learned_model_loro.py``), beside the variant bank's and for other representations, is in
docs/templates.md, "A template model continuous in disc physics". One concept per module:

* :mod:`.training` — the training runs (:func:`~.training.read_training_runs`: the isothermal gas
  runs of reduced FARGO3D files) and the per-radius weight of the maps (:func:`~.training.row_weight`);
* :mod:`.patch` — optionally (``patch=True``), the planet's surroundings, cut out with a window in
  scale heights and modelled on a grid in ``((x − 1)/h_p, φ/h_p)``, where the runs' near-planet peaks
  look alike at every aspect ratio;
* :mod:`.basis` — the bases: the map with every row rotated onto the linear wake's ridge and weighted
  as the visibilities see it, the gap as a depth times a shape (and the patch), each divided by its
  RMS and reduced to its mean and first principal components;
* :mod:`.scaling` — the aligned rows seen at azimuth offsets divided by ``(h_p/h_min)^q``
  (``azimuth_scaling``, default :data:`~.scaling.AZIMUTH_SCALING`), so that arms about as wide as the
  disc is thick line up better across H/r;
* :mod:`.regression` — every coefficient and amplitude a Gaussian process (scikit-learn) of
  ``(ln M_p, h_p, p, log10 α, ln orbits)`` over a linear trend, its length scales no shorter than a
  tenth of the training box (``MIN_LENGTH_SCALE``);
* :mod:`.model` — :class:`~.model.LearnedTemplateModel`: fit, predict a
  :class:`~spiralbayes.templates.template.SpiralTemplate` through the package's isothermal transfer
  (one model serves every optical depth τ0), save and load;
* :mod:`.uncertainty` — the predictive uncertainty (:class:`~.uncertainty.PredictionUncertainty`);
* :mod:`.bank` — :func:`~.bank.learned_bank`: a
  :class:`~spiralbayes.templates.bank.TemplateBank` of predictions on a grid of the physics, for the scan;
* :mod:`.family` — :func:`~.family.learned_family`: one disc's templates with the mass continuous
  (a :class:`~spiralbayes.templates.family.TemplateFamily`), for the posterior.

Masses are in thermal masses ``M_th = h_p³ M_*``; ``α`` is the Shakura–Sunyaev parameter at
``r_p`` (``ν = α h_p² r_p² Ω_p``); ages in orbits of the planet. Predictions outside the training
box raise :class:`~spiralbayes.exceptions.InputError` unless ``extrapolate=True``.
"""

from .bank import DEFAULT_ALPHAS, DEFAULT_ORBITS, DEFAULT_SLOPES, learned_bank, model_key
from .basis import GAP_DEPTH_FLOOR, Bases, fit_bases
from .family import learned_family, model_from_file
from .model import LEARNED_KIND, MODEL_VERSION, LearnedTemplateModel
from .patch import PATCH_POINTS, PATCH_RADIUS, PATCH_WIDTH, from_patch, patch_grid, scaled_offsets, to_patch, window
from .regression import MIN_LENGTH_SCALE, TRENDS
from .scaling import AZIMUTH_SCALING
from .training import (
    DISC_EXTENT,
    FLARING,
    MAX_CHANGE,
    NUMERICAL_CHECKS,
    OUTSIDE_WEIGHT,
    PARAMETERS,
    REFERENCE_FILES,
    WEIGHT_TAU0,
    TrainingRun,
    parameter_vector,
    read_training_runs,
    reference_files,
    row_weight,
)
from .uncertainty import PredictionUncertainty

__all__ = [
    "AZIMUTH_SCALING",
    "DEFAULT_ALPHAS",
    "DEFAULT_ORBITS",
    "DEFAULT_SLOPES",
    "DISC_EXTENT",
    "FLARING",
    "GAP_DEPTH_FLOOR",
    "LEARNED_KIND",
    "MAX_CHANGE",
    "MIN_LENGTH_SCALE",
    "MODEL_VERSION",
    "NUMERICAL_CHECKS",
    "OUTSIDE_WEIGHT",
    "PARAMETERS",
    "PATCH_POINTS",
    "PATCH_RADIUS",
    "PATCH_WIDTH",
    "REFERENCE_FILES",
    "TRENDS",
    "WEIGHT_TAU0",
    "Bases",
    "LearnedTemplateModel",
    "PredictionUncertainty",
    "TrainingRun",
    "fit_bases",
    "from_patch",
    "learned_bank",
    "learned_family",
    "model_from_file",
    "model_key",
    "parameter_vector",
    "patch_grid",
    "read_training_runs",
    "reference_files",
    "row_weight",
    "scaled_offsets",
    "to_patch",
    "window",
]
