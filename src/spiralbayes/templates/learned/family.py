"""A :class:`~spiralbayes.templates.family.TemplateFamily` of one disc of the learned model: the
planet's mass continuous at fixed aspect ratio, surface-density slope, viscosity, age and τ0.

:func:`learned_family` makes the family whose node templates the model predicts
(:meth:`~.model.LearnedTemplateModel.predict`) on the family's mass nodes, so that the posterior's
continuous mass (``sample_posterior(..., mass="continuous")``) works on a learned bank as on the
generator's: :func:`~spiralbayes.inference.posterior.mass.family_of` builds it from a learned
template that records its model file (``[templates] bank = "learned"`` does), and a notebook passes
the family itself among the templates.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from ...exceptions import InputError
from ..family import MASS_RANGE, N_MASS_NODES, TemplateFamily
from ..template import SpiralTemplate, validate_hand
from .model import LearnedTemplateModel

__all__ = ["learned_family", "model_from_file"]


class _LearnedNodes:
    """The hand-R node template at ``(mass, h_p)`` of one disc (a plain object: families pickle for
    worker processes)."""

    def __init__(self, model: LearnedTemplateModel, slope: float, alpha: float, orbits: float, tau0: float):
        self.model, self.slope, self.alpha, self.orbits, self.tau0 = model, slope, alpha, orbits, tau0

    def __call__(self, mass: float, h_p: float) -> SpiralTemplate:
        return self.model.predict(mass, h_p, self.slope, self.alpha, self.orbits, self.tau0)

    @property
    def physics(self) -> dict:
        """``{slope, alpha, orbits}`` of the disc (the posterior's run metadata)."""
        return {"slope": self.slope, "alpha": self.alpha, "orbits": self.orbits}


def learned_family(model: LearnedTemplateModel, h_p: float, slope: float, alpha: float, orbits: float, tau0: float,
                   hand: str = "R", *, mass_range: tuple[float, float] = MASS_RANGE,
                   n_masses: int = N_MASS_NODES) -> TemplateFamily:
    """The template family of one disc of the learned model, continuous in the planet's mass.

    Parameters
    ----------
    model : LearnedTemplateModel
    h_p : float
        Aspect ratio ``H/r`` at r_p.
    slope, alpha, orbits : float
        Surface-density slope ``p``, viscosity ``α`` at r_p and age [orbits].
    tau0 : float
        Initial optical depth at r_p.
    hand : {'R', 'L'}
    mass_range : (float, float)
        ``(M_min, M_max)`` [M_th]; it must lie in the model's training box.
    n_masses : int
        Log-spaced mass nodes over ``mass_range``.

    Returns
    -------
    TemplateFamily
        Variant ``learned_p<p>_a<α>_o<orbits>`` (the learned bank's), nodes predicted when first needed.

    Raises
    ------
    InputError
        A parameter (or an end of ``mass_range``) outside the training box.
    """
    lo, hi = (float(m) for m in mass_range)
    if not (0 < lo < hi):
        raise InputError(f"mass_range must be (M_min, M_max) with 0 < M_min < M_max [M_th], got {mass_range}")
    for mass in (lo, hi):  # the whole range inside the box, checked before any node is predicted
        model._check(mass, h_p, slope, alpha, orbits, False)
    if int(n_masses) < 2:
        raise InputError(f"n_masses must be at least 2, got {n_masses}")
    nodes = _LearnedNodes(model, float(slope), float(alpha), float(orbits), float(tau0))
    return TemplateFamily(np.geomspace(lo, hi, int(n_masses)), np.array([float(h_p)]), nodes,
                          variant=f"learned_p{slope:g}_a{alpha:.2g}_o{orbits:g}", tau0=float(tau0), beta=0.0,
                          hand=validate_hand(hand))


@functools.lru_cache(maxsize=4)
def _cached_model(path: str, mtime_ns: int) -> LearnedTemplateModel:
    return LearnedTemplateModel.load(path)


def model_from_file(path) -> LearnedTemplateModel:
    """The learned model saved at ``path``, read once per file version (the configuration's bank and the
    posterior's families share it).

    Raises
    ------
    DataFileError
        No model at ``path`` (the message of ``LearnedTemplateModel.load`` names the file).
    """
    p = Path(path)
    if not p.is_file():
        return LearnedTemplateModel.load(p)  # raises the loader's missing-file error
    return _cached_model(str(p.resolve()), p.stat().st_mtime_ns)
