"""The planet's surroundings in scale heights: the near-planet window and patch of the learned model.

The near-planet peak and the wake's start scale with the scale height ``H_p``, not with ``r_p``.
The learned model cuts them out of each map with the window ``W = exp(−(ξ² + η²)/2w²)`` in the
offsets ``ξ = (x − 1)/h_p``, ``η = φ/h_p`` from the planet (``w`` = :data:`PATCH_WIDTH`) and models
them on a grid in ``(ξ, η)`` (:func:`patch_grid`), where the runs' patches look alike at every
aspect ratio. :func:`to_patch` samples a windowed map on that grid and :func:`from_patch` puts a
patch back on a map's grid.
"""

from __future__ import annotations

import numpy as np

from ...units import wrap_angle
from ..template import bilinear

__all__ = ["PATCH_POINTS", "PATCH_RADIUS", "PATCH_WIDTH", "from_patch", "patch_grid", "scaled_offsets", "to_patch",
           "window"]

PATCH_WIDTH = 1.5
"""Width ``w`` of the near-planet window ``exp(−(ξ² + η²)/2w²)`` [scale heights H_p]."""
PATCH_RADIUS = 5.0
"""Half-size of the near-planet patch grid [H_p] (the window is 4e-3 there)."""
PATCH_POINTS = 101
"""Points of the patch grid along ξ and η (0.1 H_p apart: finer than the reduced maps' cells at any H/r ≥ 0.04)."""


def patch_grid() -> np.ndarray:
    """The patch grid's ``ξ = (x − 1)/h_p`` (= ``η = φ/h_p``) values [scale heights].

    Returns
    -------
    (PATCH_POINTS,) array
        From ``−PATCH_RADIUS`` to ``PATCH_RADIUS``.
    """
    return np.linspace(-PATCH_RADIUS, PATCH_RADIUS, PATCH_POINTS)


def scaled_offsets(x: np.ndarray, phi: np.ndarray, h_p: float) -> tuple[np.ndarray, np.ndarray]:
    """``(ξ, η)`` of the cells of a map: distance from the planet in scale heights, radially and in
    azimuth (φ wrapped into ``[−π, π)``).

    Parameters
    ----------
    x : (n_x,) array
        ``r / r_p`` of the map's rows.
    phi : (n_phi,) array
        The map's azimuths [rad], planet at 0.
    h_p : float
        ``H/r`` at r_p.

    Returns
    -------
    xi : (n_x, 1) array
    eta : (1, n_phi) array
    """
    return (x[:, None] - 1.0) / h_p, wrap_angle(phi)[None, :] / h_p


def window(x: np.ndarray, phi: np.ndarray, h_p: float) -> np.ndarray:
    """The near-planet window ``W`` on a map's grid (arguments as :func:`scaled_offsets`).

    Returns
    -------
    (n_x, n_phi) array
        ``exp(−(ξ² + η²)/2w²)``, 1 at the planet.
    """
    xi, eta = scaled_offsets(x, phi, h_p)
    return np.exp(-0.5 * (xi**2 + eta**2) / PATCH_WIDTH**2)


def to_patch(local: np.ndarray, x: np.ndarray, phi: np.ndarray, h_p: float) -> np.ndarray:
    """A windowed map sampled on the patch grid (bilinear in ``(ln x, φ)``, zero off the map's rows).

    Parameters
    ----------
    local : (n_x, n_phi) array
        The map times :func:`window`.
    x, phi, h_p
        As :func:`scaled_offsets`.

    Returns
    -------
    (PATCH_POINTS, PATCH_POINTS) array
        The patch, indexed ``[ξ, η]`` on :func:`patch_grid`.
    """
    g = patch_grid()
    xi, eta = np.meshgrid(g, g, indexing="ij")
    return bilinear(local, np.log(x), phi, np.log(np.clip(1.0 + h_p * xi, 1e-6, None)), h_p * eta)


def from_patch(patch: np.ndarray, x: np.ndarray, phi: np.ndarray, h_p: float) -> np.ndarray:
    """A patch put back on a map's grid (bilinear in ``(ξ, η)``, zero beyond the patch).

    Parameters
    ----------
    patch : (PATCH_POINTS, PATCH_POINTS) array
        Values on :func:`patch_grid`, indexed ``[ξ, η]``.
    x, phi, h_p
        As :func:`scaled_offsets`.

    Returns
    -------
    (n_x, n_phi) array
    """
    from scipy.interpolate import RegularGridInterpolator

    g = patch_grid()
    xi, eta = scaled_offsets(x, phi, h_p)
    xi, eta = np.broadcast_arrays(xi, eta)
    out = np.zeros(xi.shape)
    near = (np.abs(xi) <= PATCH_RADIUS) & (np.abs(eta) <= PATCH_RADIUS)
    if np.any(near):
        interp = RegularGridInterpolator((g, g), patch, bounds_error=False, fill_value=0.0)
        out[near] = interp(np.column_stack([xi[near], eta[near]]))
    return out
