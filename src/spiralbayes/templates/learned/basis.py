"""The learned model's bases: low-rank descriptions of the training runs' maps, gaps and patches.

:func:`fit_bases` turns the training runs' surface densities into three sets of numbers per run,
each the coefficients of a basis (the mean and the first principal components, by SVD):

* **the map** — ``(1 − W) δΣ/Σ`` (what the near-planet patch leaves, :mod:`.patch`) in the planet's
  frame (``x = r/r_p``, φ; hand R), every row rotated onto the linear wake's ridge,
  ``D(x, φ') = δΣ/Σ(x, φ' + φ_wake(x; h_p))``
  (:func:`~spiralbayes.templates.wake.wake_shape`, an exact Fourier shift per row): the ridge winds
  as ``1/h_p``, so unaligned maps at two aspect ratios hold their arms at different azimuths and no
  small basis spans them. The aligned map is weighted by ``w(x) = x I_axi(x)`` (what the
  visibilities see: disc area and brightness, :func:`~.training.row_weight`) and divided by its RMS
  ``A``;
* **the gap** ``ln(⟨Σ⟩_φ / Σ_init)(x)``: a depth ``D`` times a shape;
* **the near-planet patch** ``W δΣ/Σ`` on the grid in scale heights (:func:`~.patch.patch_grid`),
  divided by its RMS ``P``.

Dividing by the amplitudes makes every run count alike in the bases whatever its mass; ``ln A``,
``ln D`` and ``ln P`` are regressed beside the coefficients.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ...exceptions import InputError
from ..family import shift_rows
from ..wake import wake_shape
from .patch import PATCH_POINTS, from_patch, to_patch, window
from .scaling import compress, scale_factor
from .training import FLARING, TrainingRun, row_weight

__all__ = ["GAP_DEPTH_FLOOR", "Bases", "fit_bases"]

GAP_DEPTH_FLOOR = 0.01
"""RMS of ``ln(⟨Σ⟩_φ/Σ_init)`` below which a gap's shape is trusted less (``gap_depth``): its weight in the
shape basis and its coefficients are ``D / (D + floor)``."""


@dataclass(frozen=True, eq=False)
class Bases:
    """The bases of :func:`fit_bases` and the training runs' coefficients on them.

    Attributes
    ----------
    x : (n_x,) array
        ``r / r_p`` of the rows every training run holds (one contiguous band).
    weight : (n_x,) array
        :func:`~.training.row_weight` at ``x``.
    mean, components : (n_x, n_phi), (k, n_x, n_phi) arrays
        Mean and principal components of the aligned, weighted, normalised maps.
    gap_mean, gap_components : (n_x,), (kg, n_x) arrays
        Mean and principal components of the gaps (of their shapes with ``gap_depth``).
    patch_mean, patch_components : (n_p, n_p), (kp, n_p, n_p) arrays
        Mean and principal components of the normalised patches (empty without ``patch``).
    residual_variance : (n_x,) array
        Mean over the runs and azimuths of what the map basis leaves out, per row.
    targets : (n_runs, n_outputs) array
        Per run: the map's coefficients, the gap's, the patch's, then ``ln D`` (with ``gap_depth``),
        ``ln P`` (with ``patch``) and ``ln A``.
    """

    x: np.ndarray
    weight: np.ndarray
    mean: np.ndarray
    components: np.ndarray
    gap_mean: np.ndarray
    gap_components: np.ndarray
    patch_mean: np.ndarray
    patch_components: np.ndarray
    residual_variance: np.ndarray
    targets: np.ndarray


def _common_rows(runs: Sequence[TrainingRun]) -> np.ndarray:
    """Indices of the contiguous band of rows valid in every run (a gap positive and finite)."""
    x, phi = runs[0].x, runs[0].phi
    for r in runs[1:]:
        same = r.x.shape == x.shape and r.phi.shape == phi.shape
        if not (same and np.allclose(r.x, x) and np.allclose(r.phi, phi)):
            raise InputError(f"training run {r.name} is on another grid than {runs[0].name}: reduce every run "
                             "onto the reference grid (tools/fargo3d_library_reduce.py)")
    rows = np.logical_and.reduce([r.valid & np.isfinite(r.gap) & (r.gap > 0) for r in runs])
    if rows.sum() < 4:
        raise InputError("the training runs share fewer than 4 valid radii")
    rows = np.flatnonzero(rows)
    return np.arange(rows[0], rows[-1] + 1)


def _gap_basis(gaps: np.ndarray, kg: int, gap_depth: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(mean, components, coefficients)`` of the log gaps; with ``gap_depth`` the coefficients end
    with ``ln D``."""
    if gap_depth:  # ln gap = D × shape: D regressed in logs (a power law of mass and age), the shape apart
        depth = np.sqrt(np.mean(gaps**2, axis=1))
        trust = depth / (depth + GAP_DEPTH_FLOOR)  # shapes of gaps too shallow to matter count little
        shapes = gaps / depth[:, None]
        gap_mean = trust @ shapes / trust.sum()
        _, _, gvt = np.linalg.svd(trust[:, None] * (shapes - gap_mean), full_matrices=False)
        gcomps = gvt[:kg]
        gcoef = trust[:, None] * ((shapes - gap_mean) @ gcomps.T)
        return gap_mean, gcomps, np.column_stack([gcoef, np.log(depth)])
    gap_mean = gaps.mean(axis=0)
    _, _, gvt = np.linalg.svd(gaps - gap_mean, full_matrices=False)
    gcomps = gvt[:kg]
    return gap_mean, gcomps, (gaps - gap_mean) @ gcomps.T


def fit_bases(runs: Sequence[TrainingRun], *, n_components: int, n_gap_components: int, n_patch_components: int,
              align: bool, gap_depth: bool, patch: bool, azimuth_scaling: float = 0.0) -> Bases:
    """The bases of the runs' maps, gaps and patches (the module docstring), and each run's coefficients.

    Parameters
    ----------
    runs : sequence of TrainingRun
        On one grid.
    n_components, n_gap_components, n_patch_components : int
        Principal components kept (at most one fewer than the runs).
    align, gap_depth, patch : bool
        As :meth:`~spiralbayes.templates.learned.model.LearnedTemplateModel.fit`.
    azimuth_scaling : float
        As there: the aligned rows seen at offsets divided by ``(h_p/h_min)^azimuth_scaling``
        (:mod:`.scaling`; the amplitude ``A`` is the RMS before).

    Returns
    -------
    Bases
    """
    runs = list(runs)
    rows = _common_rows(runs)
    phi = runs[0].phi
    xm = runs[0].x[rows]
    k = min(int(n_components), len(runs) - 1)
    kg = min(int(n_gap_components), len(runs) - 1)
    kp = min(int(n_patch_components), len(runs) - 1) if patch else 0
    w = row_weight(xm)
    map_rows: list[np.ndarray] = []
    gap_rows: list[np.ndarray] = []
    patch_rows: list[np.ndarray] = []
    log_amp: list[float] = []
    h_min = min(r.h_p for r in runs)
    for r in runs:
        d = r.dsigma[rows]
        if patch:  # the rest is what the patch, put back on the map, leaves: the two add up exactly
            local = to_patch(window(xm, phi, r.h_p) * d, xm, phi, r.h_p)
            patch_rows.append(local.ravel())
            d = d - from_patch(local, xm, phi, r.h_p)
        if align:
            d = shift_rows(d, -wake_shape(xm, r.h_p, FLARING))
        d = d * w[:, None]
        a = float(np.sqrt(np.mean(d**2)))
        if not a > 0:
            raise InputError(f"training run {r.name} has an empty δΣ/Σ map")
        if azimuth_scaling:
            d = compress(d, phi, scale_factor(r.h_p, h_min, azimuth_scaling))
        map_rows.append((d / a).ravel())
        log_amp.append(math.log(a))
        gap_rows.append(np.log(r.gap[rows]))
    maps, gaps = np.array(map_rows), np.array(gap_rows)
    mean = maps.mean(axis=0)
    _, _, vt = np.linalg.svd(maps - mean, full_matrices=False)
    comps = vt[:k]
    coef = (maps - mean) @ comps.T
    resid = (maps - mean - coef @ comps).reshape(len(runs), xm.size, phi.size)
    gap_mean, gcomps, gcoef = _gap_basis(gaps, kg, gap_depth)
    n_p = PATCH_POINTS
    if patch:
        patches = np.array(patch_rows)
        p_amp = np.sqrt(np.mean(patches**2, axis=1))
        patches = patches / p_amp[:, None]
        p_mean = patches.mean(axis=0)
        _, _, pvt = np.linalg.svd(patches - p_mean, full_matrices=False)
        p_comps = pvt[:kp]
        pcoef = np.column_stack([(patches - p_mean) @ p_comps.T, np.log(p_amp)])
        p_mean, p_comps = p_mean.reshape(n_p, n_p), p_comps.reshape(kp, n_p, n_p)
    else:
        pcoef, p_mean, p_comps = np.zeros((len(runs), 0)), np.zeros((0, 0)), np.zeros((0, 0, 0))
    # outputs: map coefficients, gap shape coefficients, patch coefficients, then ln D, ln P, ln A
    gshape, gdepth = (gcoef[:, :-1], gcoef[:, -1:]) if gap_depth else (gcoef, gcoef[:, :0])
    pshape, pdepth = (pcoef[:, :-1], pcoef[:, -1:]) if patch else (pcoef, pcoef)
    targets = np.column_stack([coef, gshape, pshape, gdepth, pdepth, np.array(log_amp)])
    return Bases(x=xm, weight=w, mean=mean.reshape(xm.size, phi.size), components=comps.reshape(k, xm.size, phi.size),
                 gap_mean=gap_mean, gap_components=gcomps, patch_mean=p_mean, patch_components=p_comps,
                 residual_variance=np.mean(resid**2, axis=(0, 2)), targets=targets)
