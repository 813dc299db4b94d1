"""Azimuth scaling of the aligned maps: offsets from the wake's ridge in units that follow H/r.

A planet's arms are about as wide in azimuth as the disc is thick, so once every row is rotated onto
the linear wake's ridge (:mod:`.basis`) the maps of a thin and a thick disc still differ in width,
and a small basis fitted to all of them spans the thinnest discs' narrow arms worst. With
``azimuth_scaling = q > 0`` (:meth:`~.model.LearnedTemplateModel.fit`) the basis sees each aligned
row of a run at aspect ratio ``h_p`` at the offsets ``ψ = φ'/s`` with

    s = (h_p / h_min)^q ≥ 1,

``h_min`` the training box's smallest ``H/r``: a thicker disc's row is compressed into
``|ψ| ≤ π/s`` (zero outside) and :func:`expand` restores it, exactly up to the linear
interpolation, so nothing of a training map is cut. ``q = 1`` makes widths proportional to ``h_p``
alike; ``q = 0`` leaves the maps as they are. The default, :data:`AZIMUTH_SCALING`, is the power with
the fewest poorly recovered runs left out one at a time (docs/templates.md). Rows must lie on a
uniform azimuth grid over one period.
"""

from __future__ import annotations

import numpy as np

from ...exceptions import InputError
from ...units import wrap_angle
from ..wake import periodic_interp

__all__ = ["AZIMUTH_SCALING", "check_power", "compress", "expand", "scale_factor"]

AZIMUTH_SCALING = 0.3
"""Default power ``q``: milder powers leave the thinnest discs' arms too narrow for the basis, stronger
ones smear the old, thick discs' (docs/templates.md, leave-one-run-out by power)."""


def check_power(power: float, align: bool) -> float:
    """``power`` as a float, or :class:`~spiralbayes.exceptions.InputError` naming the fix."""
    if not (np.isfinite(power) and 0 <= power <= 3):
        raise InputError(f"azimuth_scaling = {power!r}: use a power in [0, 3] (0: off)")
    if power and not align:
        raise InputError("azimuth_scaling scales offsets from the wake's ridge: it needs align=True")
    return float(power)


def scale_factor(h_p: float, h_min: float, power: float) -> float:
    """``s = (h_p / h_min)^power``: how much narrower the basis sees a run at ``h_p``."""
    return float((h_p / h_min) ** power)


def _periodic_linear(rows: np.ndarray, phi: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Each row of ``rows`` (on the uniform periodic grid ``phi``) linearly interpolated at ``at`` [rad]."""
    pos = (np.asarray(at, dtype=float) - phi[0]) * (phi.size / (2.0 * np.pi))  # fractional grid indices
    return periodic_interp(rows, np.arange(rows.shape[0]), np.broadcast_to(pos, rows.shape))


def compress(rows: np.ndarray, phi: np.ndarray, s: float) -> np.ndarray:
    """``D(x, ψ s)`` at every ``ψ`` of ``phi`` (offsets from the ridge, [rad]), zero where ``|ψ| > π/s``.

    Parameters
    ----------
    rows : (n_x, n_phi) array
        Aligned map (the ridge at φ' = 0).
    phi : (n_phi,) array
        Uniform azimuth grid over one period [rad], holding 0.
    s : float
        :func:`scale_factor`; ``s = 1`` returns ``rows``.
    """
    if s == 1.0:
        return np.array(rows, dtype=float)
    psi = wrap_angle(phi)
    out = _periodic_linear(rows, phi, psi * s)
    if s > 1.0:  # beyond π/s the samples wrap round the circle: no part of the run's row
        out[:, np.abs(psi) > np.pi / s] = 0.0
    return out


def expand(rows: np.ndarray, phi: np.ndarray, s: float) -> np.ndarray:
    """The inverse of :func:`compress`: ``D_s(x, φ'/s)`` at every ``φ'`` of ``phi`` [rad]."""
    if s == 1.0:
        return np.array(rows, dtype=float)
    psi = wrap_angle(phi)
    return _periodic_linear(rows, phi, psi / s)
