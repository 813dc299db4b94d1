"""A polar grid of the disc plane and the exact transform of brightness fields on it.

The competing asymmetry models (:mod:`spiralbayes.alternatives.fields`) are brightness
perturbations ``P(r, phi)`` [Jy/sr] in the disc plane. As for the spiral model
(:mod:`spiralbayes.model`), their visibilities are a sum over the cells of a polar grid,

    ΔV(u, v) = cos i · exp(2 pi i (u dRA + v dDec)) · sum_c P_c A_c exp(2 pi i q · s_c),

with ``q`` the baseline in the disc frame (:meth:`.DiscGeometry.disc_frame_uv`), ``s_c`` the cell
centres and ``A_c`` their areas [sr]: a type-3 NUFFT (ducc0), planned once for fixed baselines.
The sum is the exact transform of the gridded model (points of flux ``P_c A_c``), which is a
valid sky brightness in its own right, and approximates the continuous field by the midpoint
rule. Here the grid is uniform in ``r`` (the models are localised anywhere in the disc, not
around a planet) with ``dr <= 1 / (cell_factor uv_max)``, and ``n_phi`` is a power of two above
the angular bandwidth of ``exp(2 pi i q · s)`` at the outer edge plus that of the fields, so the
azimuthal sums are exact for band-limited fields (periodic trapezoid rule). In radius the
midpoint rule errs by at most ``~ (pi q dr)^2 / 24`` (0.4 % at the longest baseline for the
default ``cell_factor = 10``) and is far better for smooth fields that vanish before the grid's
edge: against order-m Hankel transforms of such fields, 3e-8 relative RMS (the NUFFT's accuracy;
``tests/alternatives/test_grid.py``).

:meth:`FieldTransform.gradient_map` is the adjoint: the map ``g_c`` with
``d/dP_c Re sum_k y_k* ΔV_k = g_c``, which turns the gradient of χ² with respect to every cell
into one transform, whatever the number of model parameters.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..exceptions import InputError
from ..fourier import point_sources_dft
from ..geometry import DiscGeometry
from ..units import ARCSEC

__all__ = ["DEFAULT_CELL_FACTOR", "DiscGrid", "FieldTransform", "field_visibilities_dft", "remove_ring_mean"]

DEFAULT_CELL_FACTOR = 10.0
"""Radial cells are at most ``1 / (cell_factor uv_max)`` wide."""
FIELD_BANDWIDTH = 64
"""Angular Fourier modes allowed for the fields themselves (arcs as narrow as ~0.05 rad)."""
NUFFT_EPSILON = 1e-7
SINGLE_EPSILON = 1e-5


@dataclass(frozen=True)
class DiscGrid:
    """Cells of the disc plane, uniform in radius and azimuth.

    Attributes
    ----------
    r_max : float
        Outer edge [arcsec]; rings span ``[k dr, (k + 1) dr]``, ``dr = r_max / n_r``.
    n_r, n_phi : int
        Number of rings and of azimuth cells per ring (cell ``j`` centred on ``2 pi j / n_phi``).
    """

    r_max: float
    n_r: int
    n_phi: int

    def __post_init__(self):
        if not (np.isfinite(self.r_max) and self.r_max > 0):
            raise InputError(f"DiscGrid.r_max = {self.r_max!r} must be a positive radius in arcsec")
        if self.n_r < 2 or self.n_phi < 8:
            raise InputError(f"DiscGrid needs n_r >= 2 and n_phi >= 8, got {self.n_r}, {self.n_phi}")

    @classmethod
    def for_baselines(cls, uv_max: float, r_max: float, cell_factor: float = DEFAULT_CELL_FACTOR) -> DiscGrid:
        """The grid for baselines up to ``uv_max`` [lambda] and emission within ``r_max`` [arcsec]."""
        dr_max = 1.0 / (cell_factor * uv_max) / ARCSEC
        n_r = max(int(np.ceil(r_max / dr_max)), 2)
        bandwidth = 2 * np.pi * uv_max * r_max * ARCSEC + FIELD_BANDWIDTH
        n_phi = 64
        while n_phi < 1.2 * bandwidth:
            n_phi *= 2
        return cls(float(r_max), n_r, n_phi)

    @property
    def dr(self) -> float:
        return self.r_max / self.n_r

    @property
    def r(self) -> np.ndarray:
        """Ring mid-radii [arcsec] (all > 0)."""
        return (np.arange(self.n_r) + 0.5) * self.dr

    @property
    def phi(self) -> np.ndarray:
        """Cell-centre azimuths [rad] (disc azimuth convention)."""
        return 2 * np.pi * np.arange(self.n_phi) / self.n_phi

    @property
    def shape(self) -> tuple[int, int]:
        return (self.n_r, self.n_phi)

    @property
    def cell_area(self) -> np.ndarray:
        """Area of one cell of each ring [sr], shape (n_r,)."""
        edges = np.arange(self.n_r + 1) * self.dr * ARCSEC
        return 0.5 * (edges[1:] ** 2 - edges[:-1] ** 2) * (2 * np.pi / self.n_phi)

    @cached_property
    def positions(self) -> np.ndarray:
        """Cell centres ``(xi, eta)`` [rad], shape (n_r * n_phi, 2), ring-major."""
        r = self.r[:, None] * ARCSEC
        phi = self.phi[None, :]
        return np.stack([(r * np.cos(phi)).ravel(), (r * np.sin(phi)).ravel()], axis=-1)


def remove_ring_mean(field: np.ndarray) -> np.ndarray:
    """The field minus its mean over azimuth on every ring (the part frank cannot hold).

    An orthogonal projection (cells of a ring have equal areas), so it is its own adjoint.
    """
    return field - field.mean(axis=-1, keepdims=True)


class FieldTransform:
    """Visibilities of brightness fields on a :class:`DiscGrid` at fixed baselines (plan reused).

    Parameters
    ----------
    grid : DiscGrid
    u, v : array_like
        Baselines [lambda].
    geometry : DiscGeometry
        Inclination, PA and phase-centre offset of the disc.
    epsilon : float
        NUFFT accuracy.
    nthreads : int
        ducc0 threads.
    single : bool
        Single-precision transform (accuracy ~1e-5, about twice as fast; the fits optimise with
        it and report Δχ² from a double-precision one).
    """

    def __init__(self, grid: DiscGrid, u, v, geometry: DiscGeometry, *, epsilon: float = NUFFT_EPSILON,
                 nthreads: int = 1, single: bool = False):
        import ducc0

        self.grid = grid
        self.geometry = geometry
        u = np.asarray(u, dtype=float)
        v = np.asarray(v, dtype=float)
        q = np.stack(geometry.disc_frame_uv(u, v), axis=-1)
        real = np.float32 if single else np.float64
        self._complex = np.complex64 if single else np.complex128
        self._plan = ducc0.nufft.experimental.plan3(
            coord_in=np.ascontiguousarray(2 * np.pi * grid.positions, dtype=real),
            coord_out=np.ascontiguousarray(q, dtype=real), epsilon=max(epsilon, SINGLE_EPSILON if single else 0.0),
            nthreads=nthreads)
        self._factor = geometry.cos_inc * geometry.phase_factor(u, v)
        self._area = grid.cell_area[:, None]
        self.n_vis = u.size

    def visibilities(self, field: np.ndarray) -> np.ndarray:
        """ΔV [Jy] of ``field`` [Jy/sr], shape ``grid.shape`` (or ``(k, *grid.shape)`` for k fields)."""
        field = np.asarray(field, dtype=float)
        flux = (field * self._area).reshape(*field.shape[:-2], -1).astype(self._complex)
        return self._factor * self._plan.exec(forward=False, points_in=flux)

    def gradient_map(self, y) -> np.ndarray:
        """``g`` with ``g_c = d/dP_c Re sum_k conj(y_k) ΔV_k`` [Jy sr^-1]^-1, shape ``grid.shape``.

        With ``y = w (V_O - V_model)``, ``-2 g`` is the gradient of χ² with respect to the field.
        """
        points = np.ascontiguousarray(np.conj(self._factor) * np.asarray(y), dtype=self._complex)
        dirty = self._plan.exec_adjoint(forward=False, points_in=points).real.astype(float)
        return dirty.reshape(self.grid.shape) * self._area


def field_visibilities_dft(field, grid: DiscGrid, u, v, geometry: DiscGeometry, chunk: int = 512) -> np.ndarray:
    """Plain NumPy direct sum of :meth:`FieldTransform.visibilities` (the reference; slow)."""
    u = np.asarray(u, dtype=float)
    v = np.asarray(v, dtype=float)
    flux = (np.asarray(field, dtype=float) * grid.cell_area[:, None]).ravel()
    pos = grid.positions
    xi, eta = geometry.disc_frame_uv(u, v)
    out = point_sources_dft(xi, eta, pos[:, 0], pos[:, 1], flux, chunk=chunk)
    return geometry.cos_inc * geometry.phase_factor(u, v) * out
