"""Spiral templates: the δ-map format, template banks, the built-in wake generator and readers.

A template is the fractional residual brightness ``δ(r/r_p, φ) = I/<I>_φ − 1`` that a planet's
spiral adds to an axisymmetric disc (Stevenson et al. 2024). See
:mod:`spiralbayes.templates.template` for the conventions (φ anticlockwise on the sky display,
planet at φ = 0, hand R = anticlockwise orbit with trailing arms).

* :class:`SpiralTemplate` — one map with its metadata; mirror, evaluate, resample.
* :class:`TemplateBank` — many templates in one HDF5 file. :func:`default_bank` caches the
  morphology-robust bank: the paper's 64-template grid for H/r ∈ {0.05, 0.07, 0.10} in the
  compromise, hydro and wakeflow morphologies (576; :func:`variant_bank`, :mod:`.variants`);
  :func:`compromise_bank` the same grid in the compromise morphology alone (192, :func:`paper_grid`),
  for comparisons with the paper.
* :class:`TemplateFamily` — one morphology at any mass (and H/r) in a range, interpolated between
  generator templates on fine nodes (:mod:`.family`).
* :func:`make_template` — the built-in semi-analytic generator (:mod:`.wake`).
* :func:`read_fargo3d`, :func:`read_fits_template` — bring your own simulations.
* :class:`LearnedTemplateModel` — templates continuous in disc physics (planet mass, H/r, surface-density
  slope, viscosity, age), learned from hydrodynamic runs; :func:`learned_bank` puts its predictions on a
  grid into a bank for the scan (:mod:`.learned`).
* :func:`asymmetry_templates` — the competing explanations (arc/vortex, eccentric ring) as template
  families, for the posterior odds (:mod:`.asymmetry`).
"""

from .asymmetry import ASYMMETRY_KINDS, RingProfile, arc_template, asymmetry_templates, ring_template
from .bank import TemplateBank, compromise_bank, default_cache_dir
from .family import TemplateFamily
from .fargo3d import read_fargo3d
from .fits import read_fits_template, write_fits_template
from .generator import make_template, paper_grid
from .learned import LearnedTemplateModel, learned_bank
from .radiative import template_from_perturbation
from .template import SpiralTemplate
from .variants import default_bank, variant_bank
from .wake import WakeSettings, wake_shape

__all__ = [
    "ASYMMETRY_KINDS",
    "RingProfile",
    "arc_template",
    "asymmetry_templates",
    "ring_template",
    "LearnedTemplateModel",
    "SpiralTemplate",
    "TemplateBank",
    "TemplateFamily",
    "WakeSettings",
    "compromise_bank",
    "default_bank",
    "default_cache_dir",
    "learned_bank",
    "make_template",
    "paper_grid",
    "read_fargo3d",
    "read_fits_template",
    "template_from_perturbation",
    "variant_bank",
    "wake_shape",
    "write_fits_template",
]
