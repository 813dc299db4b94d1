"""Competing non-spiral asymmetry models: what else could improve on the axisymmetric fit.

The models of test 3 (:func:`spiralbayes.inference.detection.verdict.detect`), each a few parameters on
top of the same axisymmetric profile and with exact visibilities:

* ``geometry`` — the profile under another inclination, PA and phase centre
  (:mod:`.geometry_error`);
* ``arc``, ``lopsided``, ``eccentric_ring``, ``eccentric_excess``, ``m2`` — brightness perturbations on a polar
  grid of the disc plane (:mod:`.fields`, transformed by :mod:`.grid`).

Their maximum-likelihood fits live in :mod:`spiralbayes.inference.detection.alternatives`.
"""

from __future__ import annotations

import numpy as np

from ..exceptions import InputError
from ..geometry import DiscGeometry
from .fields import FIELD_MODELS, FieldModel, ProfileContext
from .geometry_error import GEOMETRY_PARAMS, HankelTable, geometry_visibilities, offset_geometry
from .grid import DEFAULT_CELL_FACTOR, DiscGrid, FieldTransform, field_visibilities_dft, remove_ring_mean

__all__ = [
    "ALTERNATIVE_LABELS",
    "ALTERNATIVE_MODELS",
    "DEFAULT_CELL_FACTOR",
    "DiscGrid",
    "FIELD_MODELS",
    "FieldModel",
    "FieldTransform",
    "GEOMETRY_PARAMS",
    "HankelTable",
    "ProfileContext",
    "asymmetry_visibilities",
    "field_visibilities_dft",
    "geometry_visibilities",
    "n_parameters",
    "offset_geometry",
    "remove_ring_mean",
]

ALTERNATIVE_MODELS = ("geometry", *FIELD_MODELS)
"""Every alternative, by name: ``geometry``, ``arc``, ``lopsided``, ``eccentric_ring``, ``eccentric_excess``,
``m2``."""
ALTERNATIVE_LABELS = {"geometry": "geometry error", **{k: m.label for k, m in FIELD_MODELS.items()}}


def n_parameters(name: str) -> int:
    """Free parameters of an alternative (its BIC penalty is this times ln N)."""
    if name == "geometry":
        return len(GEOMETRY_PARAMS)
    if name not in FIELD_MODELS:
        raise InputError(f"unknown asymmetry model {name!r}: use one of {', '.join(ALTERNATIVE_MODELS)}")
    return FIELD_MODELS[name].n_params


def asymmetry_visibilities(name: str, theta, u, v, axisymmetric, geometry: DiscGeometry, grid: DiscGrid,
                           *, nthreads: int = 1) -> np.ndarray:
    """Model minus axisymmetric visibilities [Jy] of an alternative at baselines ``(u, v)`` [lambda].

    Parameters
    ----------
    name : str
        One of :data:`ALTERNATIVE_MODELS`.
    theta : array_like
        Its parameters (see :mod:`.fields` and :mod:`.geometry_error`).
    axisymmetric : AxisymmetricModel
        Provides ``brightness(r)`` and ``visibilities(u, v, geometry)``.
    geometry : DiscGeometry
        The geometry of the axisymmetric model (the scan's).
    grid : DiscGrid
        The grid of the fit (field models only).
    """
    n_parameters(name)
    if name == "geometry":
        V_A = axisymmetric.visibilities(u, v, geometry)
        return axisymmetric.visibilities(u, v, offset_geometry(geometry, theta)) - V_A
    ctx = ProfileContext.build(axisymmetric.brightness, grid)
    field = FIELD_MODELS[name].field(np.asarray(theta, dtype=float), ctx)
    return FieldTransform(grid, u, v, geometry, nthreads=nthreads).visibilities(field)
