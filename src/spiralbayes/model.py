"""The spiral model: axisymmetric profile × (1 + template) placed at the planet position.

The spiral model of Stevenson et al. (2024, sec. 2.2) is ``I_S(r, phi) = I_A(r) (1 + delta(r / r_p,
phi - phi_p))`` in the disc plane, inclined (flux × cos i), rotated to PA and shifted to
``(dRA, dDec)``. Everything here works with the *perturbation* ``P = I_A delta`` alone, whose
visibilities add to the axisymmetric model's:

    ΔV(u, v) = cos i · exp(2 pi i (u dRA + v dDec)) · sum_c P_c A_c exp(2 pi i q · s_c)

with ``q = (xi, eta)`` the baseline in the disc frame (:meth:`DiscGeometry.disc_frame_uv`) and
``s_c`` the centres of the cells of a polar quadrature grid (areas ``A_c`` [sr]). The sum is a
type-3 (non-uniform to non-uniform) FFT, done with ducc0; :func:`perturbation_visibilities_dft`
is the direct-sum reference and :func:`render_perturbation_image` the Cartesian image used by
the naive path (image + NUFFT), against which the quadrature is tested.

Quadrature: a polar grid log-spaced in ``x = r / r_p`` over the template's range and uniform in
``phi``, at least as fine as the template and with cells no larger than ``1 / (cell_factor
u_max)``, so that the window of a cell changes visibilities at the longest baseline by less
than ``(pi / cell_factor)^2 / 6`` (0.4 % for the default 20, at the longest baseline only).
Measured against supersampled 1-mas images of the same continuous model, ΔV agrees to 8e-4
relative RMS with the default (3e-3 with cell_factor 10, 3e-4 with 40).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Callable

import numpy as np

from .fourier import NUFFT_EPSILON, image_axes
from .geometry import DiscGeometry
from .units import ARCSEC

__all__ = [
    "PolarQuadrature",
    "make_quadrature",
    "perturbation_flux",
    "perturbation_visibilities",
    "perturbation_visibilities_dft",
    "render_perturbation_image",
]

DEFAULT_CELL_FACTOR = 20.0

Profile = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class PolarQuadrature:
    """Polar cells in the disc plane for one planet radius.

    Attributes
    ----------
    r_p : float
        Planet radius [arcsec].
    x_edges : ndarray
        Cell edges in ``x = r / r_p`` (log-spaced).
    n_phi : int
        Number of azimuth cells over 2 pi; cell ``j`` is centred on ``phi = 2 pi j / n_phi``.
    """

    r_p: float
    x_edges: np.ndarray
    n_phi: int

    @property
    def x(self) -> np.ndarray:
        """Cell centres in ``x`` (geometric means of the edges)."""
        return np.sqrt(self.x_edges[1:] * self.x_edges[:-1])

    @property
    def r(self) -> np.ndarray:
        """Cell-centre radii [arcsec]."""
        return self.r_p * self.x

    @property
    def phi(self) -> np.ndarray:
        """Cell-centre azimuths [rad]."""
        return 2 * np.pi * np.arange(self.n_phi) / self.n_phi

    @property
    def ring_area(self) -> np.ndarray:
        """Area of one cell of each ring [sr]."""
        r_edges = self.r_p * self.x_edges * ARCSEC
        return 0.5 * (r_edges[1:] ** 2 - r_edges[:-1] ** 2) * (2 * np.pi / self.n_phi)

    @property
    def shape(self) -> tuple[int, int]:
        return (self.x.size, self.n_phi)

    @cached_property
    def _positions(self) -> np.ndarray:
        r = self.r[:, None] * ARCSEC
        phi = self.phi[None, :]
        return np.stack([(r * np.cos(phi)).ravel(), (r * np.sin(phi)).ravel()], axis=-1)

    def positions(self) -> np.ndarray:
        """Cell centres ``(xi, eta)`` [rad], shape (n_x * n_phi, 2), ring-major (cached, read-only)."""
        return self._positions


def make_quadrature(template, r_p: float, uv_max: float, *, cell_factor: float = DEFAULT_CELL_FACTOR,
                    phi_multiple: int = 90) -> PolarQuadrature:
    """The polar quadrature for ``template`` at planet radius ``r_p`` [arcsec].

    Radial cells subdivide the template's own radial intervals (so that the template's bilinear
    interpolant is linear inside each cell) until none is wider than ``1 / (cell_factor uv_max)``
    [rad]; ``n_phi`` is a power-of-two multiple of ``phi_multiple`` (so that planet azimuths on
    that grid are cyclic shifts), at least the template's and fine enough at the outer edge.
    """
    x = np.asarray(template.x, dtype=float)
    max_cell = 1.0 / (cell_factor * uv_max) / ARCSEC  # arcsec
    widths = np.diff(x) * r_p
    parts = np.maximum(np.ceil(widths / max_cell - 1e-9).astype(int), 1)
    steps = np.repeat(np.diff(x) / parts, parts)
    edges = np.concatenate([[x[0]], x[0] + np.cumsum(steps)])
    edges[-1] = x[-1]
    n_phi_min = max(len(template.phi), int(np.ceil(2 * np.pi * r_p * x[-1] / max_cell)))
    return PolarQuadrature(float(r_p), edges, _next_pow2_multiple(n_phi_min, phi_multiple))


def _template_x_range(x: np.ndarray) -> tuple[float, float]:
    """The support of a template's interpolant: from its first to its last grid point."""
    return float(x[0]), float(x[-1])


def _next_pow2_multiple(n: int, base: int) -> int:
    m = base
    while m < n:
        m *= 2
    return m


def template_on_quadrature(template, quad: PolarQuadrature) -> np.ndarray:
    """``delta`` at the quadrature's cell centres with the planet at ``phi = 0``; shape ``quad.shape``.

    The template's bilinear interpolant in ``(ln x, phi)`` (:meth:`SpiralTemplate.evaluate`),
    evaluated as two 1-D linear interpolations: a tensor-product grid needs no more.
    """
    log_x = np.log(np.asarray(template.x, dtype=float))
    delta = np.asarray(template.delta, dtype=float)
    lq = np.clip(np.log(quad.x), log_x[0], log_x[-1])
    i = np.clip(np.searchsorted(log_x, lq, side="right") - 1, 0, log_x.size - 2)
    w = ((lq - log_x[i]) / (log_x[i + 1] - log_x[i]))[:, None]
    rows = (1 - w) * delta[i] + w * delta[i + 1]
    phi_t = np.asarray(template.phi, dtype=float)
    n_t = phi_t.size
    if quad.n_phi % n_t == 0 and phi_t[0] == 0.0:
        return _refine_periodic(rows, quad.n_phi // n_t)
    s = (quad.phi - phi_t[0]) / (2 * np.pi / n_t)
    j0 = np.floor(s).astype(np.int64)
    wp = s - j0
    j0 %= n_t
    return (1 - wp) * rows[:, j0] + wp * rows[:, (j0 + 1) % n_t]


def _refine_periodic(rows: np.ndarray, factor: int) -> np.ndarray:
    """Linear interpolation along the periodic last axis onto a grid ``factor`` times finer."""
    out = np.empty((rows.shape[0], rows.shape[1] * factor))
    following = np.roll(rows, -1, axis=1)
    for k in range(factor):
        w = k / factor
        out[:, k::factor] = rows if k == 0 else (1 - w) * rows + w * following
    return out


def perturbation_flux(profile: Profile, template, quad: PolarQuadrature, delta=None) -> np.ndarray:
    """Flux of each quadrature cell of ``I_A delta`` [Jy] (face on), planet at ``phi = 0``."""
    if delta is None:
        delta = template_on_quadrature(template, quad)
    weight = np.asarray(profile(quad.r), dtype=float) * quad.ring_area
    return delta * weight[:, None]


def _rotate_flux(flux: np.ndarray, phi_p: float) -> tuple[np.ndarray, float]:
    """Shift the grid by whole cells towards ``phi_p``; return the remaining angle."""
    n_phi = flux.shape[1]
    shift = int(np.round(phi_p / (2 * np.pi) * n_phi))
    return np.roll(flux, shift, axis=1), phi_p - 2 * np.pi * shift / n_phi


def _cell_positions(quad: PolarQuadrature, extra_angle: float) -> np.ndarray:
    pos = quad.positions()
    if extra_angle:
        c, s = np.cos(extra_angle), np.sin(extra_angle)
        pos = pos @ np.array([[c, s], [-s, c]])
    return pos


def _placed_cells(u, v, profile, template, r_p, phi_p, quad, cell_factor):
    """Cell fluxes [Jy] (flattened) and positions [rad] of the perturbation with the planet at ``phi_p``."""
    if quad is None:
        quad = make_quadrature(template, r_p, float(np.max(np.hypot(u, v))), cell_factor=cell_factor)
    flux, rest = _rotate_flux(perturbation_flux(profile, template, quad), phi_p)
    return flux.ravel(), _cell_positions(quad, rest)


def perturbation_visibilities(u, v, geometry: DiscGeometry, profile: Profile, template, r_p: float,
                              phi_p: float, *, quad: PolarQuadrature | None = None,
                              cell_factor: float = DEFAULT_CELL_FACTOR, nthreads: int = 1,
                              epsilon: float = NUFFT_EPSILON) -> np.ndarray:
    """Visibilities ΔV [Jy] of the spiral perturbation ``I_A delta`` at baselines ``(u, v)`` [lambda].

    Parameters
    ----------
    geometry : DiscGeometry
        Disc inclination, PA and offset.
    profile : callable
        Axisymmetric brightness ``I_A(r [arcsec])`` [Jy/sr].
    template : SpiralTemplate
        Fractional residual ``delta(r / r_p, phi)``, planet at ``phi = 0``.
    r_p : float
        Planet radius [arcsec].
    phi_p : float
        Planet azimuth [rad] (disc azimuth convention, :mod:`spiralbayes.geometry`).
    """
    import ducc0

    u = np.asarray(u, dtype=float)
    v = np.asarray(v, dtype=float)
    flux, pos = _placed_cells(u, v, profile, template, r_p, phi_p, quad, cell_factor)
    q = np.stack(geometry.disc_frame_uv(u, v), axis=-1)
    vis = ducc0.nufft.experimental.nu2nu(
        points_in=flux.astype(complex), coord_in=2 * np.pi * pos,
        coord_out=np.ascontiguousarray(q), forward=False, epsilon=epsilon, nthreads=nthreads)
    return geometry.cos_inc * geometry.phase_factor(u, v) * vis


def perturbation_visibilities_dft(u, v, geometry: DiscGeometry, profile: Profile, template, r_p: float,
                                  phi_p: float, *, quad: PolarQuadrature | None = None,
                                  cell_factor: float = DEFAULT_CELL_FACTOR, chunk: int = 256) -> np.ndarray:
    """Plain NumPy direct sum of :func:`perturbation_visibilities` (the reference; slow)."""
    u = np.asarray(u, dtype=float)
    v = np.asarray(v, dtype=float)
    flux, pos = _placed_cells(u, v, profile, template, r_p, phi_p, quad, cell_factor)
    xi, eta = geometry.disc_frame_uv(u, v)
    out = np.empty(u.size, dtype=complex)
    for start in range(0, u.size, chunk):
        sl = slice(start, start + chunk)
        phase = 2 * np.pi * (np.outer(xi[sl], pos[:, 0]) + np.outer(eta[sl], pos[:, 1]))
        out[sl] = np.exp(1j * phase) @ flux
    return geometry.cos_inc * geometry.phase_factor(u, v) * out


def render_perturbation_image(profile: Profile, template, r_p: float, phi_p: float, inc: float,
                              shape, pixel_size: float, supersample: int = 3) -> np.ndarray:
    """Image [Jy/pixel] of ``I_A delta`` in the frame of :func:`spiralbayes.fourier.sample_image`.

    Major axis north (PA and offsets are applied in uv space by the sampler); each pixel is the
    mean of ``supersample``² point samples of the continuous model (bilinear template).
    """
    geom0 = DiscGeometry(inc, 0.0, 0.0, 0.0)
    l_axis, m_axis = image_axes(shape, pixel_size)
    offsets = (np.arange(supersample) + 0.5) / supersample - 0.5
    r_table = np.linspace(0.0, r_p * float(np.max(template.x)) * 1.01, 40_001)
    i_table = np.asarray(profile(r_table), dtype=float)  # the profile once, finely, not per pixel
    image = np.zeros(shape)
    for oy in offsets:
        for ox in offsets:
            L, M = np.meshgrid(l_axis - ox * pixel_size, m_axis + oy * pixel_size)
            r, phi = geom0.sky_to_disc(L, M)
            image += np.interp(r, r_table, i_table, right=0.0) * template.evaluate(r, phi, r_p, phi_p)
    pixel_sr = (pixel_size * ARCSEC) ** 2
    # flux x cos i: the sky pixel sees brightness I per sr over its own (sky) solid angle
    return image / supersample ** 2 * pixel_sr
