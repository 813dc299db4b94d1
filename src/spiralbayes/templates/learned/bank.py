"""A :class:`~spiralbayes.templates.bank.TemplateBank` of the learned model's templates on a grid of disc physics.

:func:`learned_bank` predicts a template (:meth:`~.model.LearnedTemplateModel.predict`) at every
combination of planet mass, aspect ratio, surface-density slope, viscosity, age and optical depth
given, in each hand, so that the scan, the verdict and the limits can use the learned model as they
use the variant bank (:func:`~spiralbayes.templates.variants.default_bank`). Templates of one disc
(slope, viscosity, age) share a ``variant`` (``learned_p<p>_a<α>_o<orbits>``) and so form one mass
family. Banks are cached on disk like the built-in banks (``learned-<key>.h5``, the key hashing the
model's content, :func:`model_key`, and the grid).
"""

from __future__ import annotations

import contextlib
import hashlib
import itertools
import json
import logging
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ...exceptions import InputError
from ..bank import TemplateBank, cached_bank, default_cache_dir
from ..template import validate_hand
from .model import MODEL_VERSION, LearnedTemplateModel

__all__ = ["DEFAULT_ALPHAS", "DEFAULT_ORBITS", "DEFAULT_SLOPES", "learned_bank", "model_key"]

log = logging.getLogger(__name__)

_ARRAYS = ("x", "phi", "weight", "mean", "components", "gap_mean", "gap_components", "inputs", "targets", "thetas",
           "residual_variance", "trends", "patch_mean", "patch_components")


DEFAULT_SLOPES = (0.5, 1.0, 1.5)
"""Surface-density slopes ``p`` (Σ ∝ r^-p) of a learned bank when none are given (``[templates] slope``):
the disc physics set's and the continuum design's range."""
DEFAULT_ALPHAS = (2e-4, 1e-3, 1e-2)
"""Viscosities ``α`` at r_p of a learned bank when none are given (``[templates] alpha``): near the
training box's ends (its runs span α 1.3e-4–2e-2) and between them."""
DEFAULT_ORBITS = (200.0,)
"""Planet age [orbits] of a learned bank when none is given (``[templates] orbits``): the oldest age the
training set holds at several masses and aspect ratios (docs/templates.md, the coverage table)."""


def model_key(model: LearnedTemplateModel) -> str:
    """A hash of a learned model's content (bases, training inputs and outputs, hyperparameters, options):
    models that predict alike share it.

    Parameters
    ----------
    model : LearnedTemplateModel

    Returns
    -------
    str
        16 hexadecimal digits.
    """
    h = hashlib.sha256(f"learned{MODEL_VERSION}".encode())
    for name in _ARRAYS:
        a = np.ascontiguousarray(getattr(model, name), dtype=float)
        h.update(f"{name}{a.shape}".encode())
        h.update(a.tobytes())
    h.update(json.dumps([list(model.run_names), model.options], sort_keys=True, default=str).encode())
    return h.hexdigest()[:16]


def _values(name: str, values) -> tuple[float, ...]:
    out = tuple(float(v) for v in np.atleast_1d(np.asarray(values, dtype=float)))
    if not out:
        raise InputError(f"{name}: give at least one value")
    if len(set(out)) < len(out):
        raise InputError(f"{name} = {list(out)} repeats a value")
    return out


def learned_bank(model: LearnedTemplateModel, masses, h_ps, slopes, alphas, orbits, tau0s,
                 hands: Sequence[str] = ("R", "L"), *, extrapolate: bool = False, cache_dir=None,
                 rebuild: bool = False, progress: bool = False) -> TemplateBank:
    """The learned model's templates at every point of a grid of disc physics, as a template bank.

    Parameters
    ----------
    model : LearnedTemplateModel
        The fitted model.
    masses : float or sequence of float
        Planet masses ``M_p/M_th``.
    h_ps : float or sequence of float
        Aspect ratios ``H/r`` at r_p.
    slopes : float or sequence of float
        Surface-density slopes ``p`` (Σ ∝ r^-p).
    alphas : float or sequence of float
        Viscosities ``α`` at r_p.
    orbits : float or sequence of float
        Ages [planet orbits].
    tau0s : float or sequence of float
        Optical depths τ0 at r_p.
    hands : sequence of {'R', 'L'}
        The hands (L: the mirror image of R's template).
    extrapolate : bool
        Allow grid points outside the model's training box (otherwise such a point raises
        :class:`~spiralbayes.exceptions.InputError` naming it).
    cache_dir : path, optional
        Where the bank is cached (default :func:`~spiralbayes.templates.bank.default_cache_dir`).
    rebuild : bool
        Predict the templates even when a cached copy exists.
    progress : bool
        Show a progress bar while predicting.

    Returns
    -------
    TemplateBank
        ``len(masses) × len(h_ps) × len(slopes) × len(alphas) × len(orbits) × len(tau0s) × len(hands)``
        templates, each the template :meth:`~.model.LearnedTemplateModel.predict` returns at its point,
        ordered by slope, viscosity, age, aspect ratio, mass, optical depth and hand (the last fastest).
    """
    grid = {name: _values(name, v) for name, v in (("masses", masses), ("h_ps", h_ps), ("slopes", slopes),
                                                     ("alphas", alphas), ("orbits", orbits), ("tau0s", tau0s))}
    hands = tuple(validate_hand(h) for h in ([hands] if isinstance(hands, str) else hands))
    if not hands or len(set(hands)) < len(hands):
        raise InputError(f"hands = {list(hands)}: give 'R', 'L' or both, once each")
    blob = json.dumps({"model": model_key(model), "grid": grid, "hands": hands, "extrapolate": bool(extrapolate)},
                      sort_keys=True)
    key = hashlib.sha256(blob.encode()).hexdigest()[:16]
    points = list(itertools.product(grid["slopes"], grid["alphas"], grid["orbits"], grid["h_ps"], grid["masses"]))
    n_expected = len(points) * len(grid["tau0s"]) * len(hands)
    path = (Path(cache_dir).expanduser() if cache_dir is not None else default_cache_dir()) / f"learned-{key}.h5"
    cached = cached_bank(path, "learned_bank_key", key, n_expected, rebuild)
    if cached is not None:
        return cached
    for slope, alpha, age, h_p, mass in points:  # every point checked before any is predicted
        model._check(mass, h_p, slope, alpha, age, extrapolate)
    t0 = time.perf_counter()
    iterator = points
    if progress:
        from tqdm.auto import tqdm

        iterator = tqdm(points, desc="learned templates", unit="point")
    templates = []
    for slope, alpha, age, h_p, mass in iterator:
        for tau0 in grid["tau0s"]:
            right = model.predict(mass, h_p, slope, alpha, age, tau0, extrapolate=extrapolate)
            templates += [right if hand == "R" else right.mirror() for hand in hands]
    bank = TemplateBank(templates, {"learned_bank_key": key, "model_key": model_key(model), "grid": grid,
                                    "hands": list(hands), "extrapolate": bool(extrapolate),
                                    "runs": list(model.run_names), "options": dict(model.options),
                                    "generator": "spiralbayes.templates.learned.learned_bank"})
    log.info("predicted the learned template bank (%d templates) in %.1f s", len(bank), time.perf_counter() - t0)
    with contextlib.suppress(OSError):  # a read-only cache folder costs a rebuild next time, nothing more
        bank.save(path)
    return bank
