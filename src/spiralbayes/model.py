"""The spiral model: axisymmetric profile × (1 + template) placed at the planet position.

The spiral model of Stevenson et al. (2024, sec. 2.2) is ``I_S(r, phi) = I_A(r) (1 + delta(r / r_p,
phi - phi_p))`` in the disc plane, inclined (flux × cos i), rotated to PA and shifted to
``(dRA, dDec)``. Everything here works with the *perturbation* ``P = I_A delta`` alone, whose
visibilities add to the axisymmetric model's:

    ΔV(u, v) = cos i · exp(2 pi i (u dRA + v dDec)) · sum_c P_c A_c exp(2 pi i q · s_c)

with ``q = (xi, eta)`` the baseline in the disc frame (:meth:`.DiscGeometry.disc_frame_uv`) and
``s_c`` the centres of the cells of a polar quadrature grid (areas ``A_c`` [sr]). The sum is a
type-3 (non-uniform to non-uniform) FFT, done with ducc0; :func:`perturbation_visibilities_dft`
is the direct-sum reference and :func:`render_perturbation_image` the Cartesian image used by
the naive path (image + NUFFT), against which the quadrature is tested.

Quadrature (:func:`make_quadrature`): by default the product rule of :mod:`spiralbayes.quadrature`,
which integrates the template's bilinear interpolant and the profile exactly and interpolates
only the Fourier kernel; its error is below ~1e-11 of the perturbation's L1 norm at every baseline
up to ``uv_max``, and it reports a bound (:meth:`.ProductQuadrature.error_bound`).
``rule="midpoint"`` keeps the earlier polar cells, log-spaced in ``x = r / r_p`` over the
template's range and uniform in ``phi``, no larger than ``1 / (cell_factor u_max)``: second order,
with ``Σ w |ΔV|^2`` low by 3-9e-4 at the default ``cell_factor`` 20; it is kept as the
reference of that behaviour.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from collections.abc import Callable

import numpy as np

from .exceptions import InputError
from .fourier import NUFFT_EPSILON, image_axes, point_sources_dft
from .geometry import DiscGeometry
from .quadrature import ProductQuadrature, TemplateSpectrum, make_product_quadrature
from .units import ARCSEC

__all__ = [
    "PolarQuadrature",
    "RULES",
    "make_quadrature",
    "profile_support",
    "perturbation_flux",
    "perturbation_visibilities",
    "perturbation_visibilities_dft",
    "render_perturbation_image",
]

DEFAULT_CELL_FACTOR = 20.0
DEFAULT_RULE = "product"
RULES = ("product", "midpoint")
"""Quadrature rules: the exact product rule (default) and the earlier midpoint cells."""

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

    @property
    def size(self) -> int:
        return self.x.size * self.n_phi

    @property
    def key(self) -> tuple:
        """Identifies the cell grid (for caches of plans and dirty images)."""
        return ("midpoint", self.r_p, self.x_edges[0], self.x_edges[-1], self.x.size, self.n_phi)

    @property
    def blocks(self) -> list[tuple[int, int, int]]:
        """One group of rings, all with ``n_phi`` cells (the product rule has several)."""
        return [(0, self.x.size, self.n_phi)]

    def split(self, flat: np.ndarray) -> list[np.ndarray]:
        """A flat array over the cells as ``[(n_x, n_phi)]``."""
        return [flat.reshape(self.shape)]

    kind = "midpoint"

    @cached_property
    def _positions(self) -> np.ndarray:
        r = self.r[:, None] * ARCSEC
        phi = self.phi[None, :]
        return np.stack([(r * np.cos(phi)).ravel(), (r * np.sin(phi)).ravel()], axis=-1)

    def positions(self) -> np.ndarray:
        """Cell centres ``(xi, eta)`` [rad], shape (n_x * n_phi, 2), ring-major (cached, read-only)."""
        return self._positions


def make_quadrature(template, r_p: float, uv_max: float, *, cell_factor: float = DEFAULT_CELL_FACTOR,
                    phi_multiple: int = 90, rule: str = DEFAULT_RULE, support: float | None = None, breaks=()):
    """The quadrature for ``template`` at planet radius ``r_p`` [arcsec], for baselines up to ``uv_max`` [lambda].

    ``rule="product"`` (default): :func:`spiralbayes.quadrature.make_product_quadrature`, exact to
    ~1e-11 of the perturbation's L1 norm (``cell_factor`` unused; ``support`` [arcsec] is the
    radius beyond which the profile vanishes, e.g. frank's ``Rmax``: give it when the profile
    jumps to zero there, see :func:`profile_support`).

    ``rule="midpoint"``: :class:`PolarQuadrature` cells that subdivide the template's own radial
    intervals until none is wider than ``1 / (cell_factor uv_max)`` [rad]; ``n_phi`` is a
    power-of-two multiple of ``phi_multiple``, at least the template's and fine enough at the
    outer edge. In both rules ``n_phi`` is a multiple of ``phi_multiple`` (planet azimuths on that
    grid are cyclic shifts of the nodes).
    """
    if rule == "product":
        return make_product_quadrature(template, r_p, uv_max, phi_multiple=phi_multiple, support=support,
                                       breaks=breaks)
    if rule != "midpoint":
        raise InputError(f"rule = {rule!r}: the quadrature rules are {RULES}")
    x = np.asarray(template.x, dtype=float)
    max_cell = 1.0 / (cell_factor * uv_max) / ARCSEC  # arcsec
    widths = np.diff(x) * r_p
    parts = np.maximum(np.ceil(widths / max_cell - 1e-9).astype(int), 1)
    steps = np.repeat(np.diff(x) / parts, parts)
    edges = np.concatenate([[x[0]], x[0] + np.cumsum(steps)])
    edges[-1] = x[-1]
    n_phi_min = max(len(template.phi), int(np.ceil(2 * np.pi * r_p * x[-1] / max_cell)))
    return PolarQuadrature(float(r_p), edges, _next_pow2_multiple(n_phi_min, phi_multiple))


def profile_support(profile) -> float | None:
    """The radius [arcsec] beyond which ``profile`` vanishes, when it says so, else None.

    A frank model's ``brightness`` (a bound method of an object with ``Rmax``) is zero from
    ``Rmax`` on; the product rule puts a break there, so that the jump is integrated exactly.
    """
    owner = getattr(profile, "__self__", None)
    r_max = getattr(owner, "Rmax", None)
    return None if r_max is None else float(r_max)


def profile_breaks(profile) -> tuple:
    """Radii [arcsec] where ``profile`` jumps inside its support, when its owner declares them
    (a ``breaks`` attribute, e.g. a model disc's edges), else ``()``; the product rule splits there."""
    owner = getattr(profile, "__self__", None)
    return tuple(float(b) for b in getattr(owner, "breaks", ()) or ())


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

    The template's bilinear interpolant in ``(ln x, phi)``
    (:meth:`~spiralbayes.templates.template.SpiralTemplate.evaluate`), evaluated as two 1-D linear
    interpolations: a tensor-product grid needs no more.
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


def perturbation_flux(profile: Profile, template, quad, delta=None, *,
                      spectrum: TemplateSpectrum | None = None) -> np.ndarray:
    """Flux of each quadrature node (cell) of ``I_A delta`` [Jy] (face on), planet at ``phi = 0``.

    Product rule: flat, in the order of ``quad.positions()`` (``quad.split`` gives one
    ``(rings, n_phi)`` array per group of rings); ``spectrum`` (the template's
    :class:`~spiralbayes.quadrature.TemplateSpectrum`) may be passed to reuse it. Midpoint rule:
    shape ``quad.shape``; ``delta`` (:func:`.template_on_quadrature`) may be passed.
    """
    if isinstance(quad, ProductQuadrature):
        return quad.flux(profile, spectrum if spectrum is not None else TemplateSpectrum(template))
    if delta is None:
        delta = template_on_quadrature(template, quad)
    weight = np.asarray(profile(quad.r), dtype=float) * quad.ring_area
    return delta * weight[:, None]


def _rotate_flux(flux: np.ndarray, phi_p: float) -> tuple[np.ndarray, float]:
    """Shift the grid by whole cells towards ``phi_p``; return the remaining angle."""
    n_phi = flux.shape[1]
    shift = int(np.round(phi_p / (2 * np.pi) * n_phi))
    return np.roll(flux, shift, axis=1), phi_p - 2 * np.pi * shift / n_phi


def _cell_positions(quad, extra_angle: float) -> np.ndarray:
    return _rotated(quad.positions(), extra_angle)


def _rotated(pos: np.ndarray, angle: float) -> np.ndarray:
    """Positions ``(xi, eta)`` rotated anticlockwise by ``angle`` [rad]."""
    if not angle:
        return pos
    c, s = np.cos(angle), np.sin(angle)
    return pos @ np.array([[c, s], [-s, c]])


def _placed_cells(u, v, profile, template, r_p, phi_p, quad, cell_factor, rule=DEFAULT_RULE):
    """Cell fluxes [Jy] (flattened) and positions [rad] of the perturbation with the planet at ``phi_p``."""
    if quad is None:
        quad = make_quadrature(template, r_p, float(np.max(np.hypot(u, v))), cell_factor=cell_factor, rule=rule,
                               support=profile_support(profile), breaks=profile_breaks(profile))
    flux = perturbation_flux(profile, template, quad)
    if isinstance(quad, ProductQuadrature):  # nodes rotate exactly: no need to move whole cells
        return flux, _rotated(quad.positions(), phi_p)
    flux, rest = _rotate_flux(flux, phi_p)
    return flux.ravel(), _cell_positions(quad, rest)


def perturbation_visibilities(u, v, geometry: DiscGeometry, profile: Profile, template, r_p: float,
                              phi_p: float, *, quad=None, cell_factor: float = DEFAULT_CELL_FACTOR,
                              nthreads: int = 1, epsilon: float = NUFFT_EPSILON,
                              rule: str = DEFAULT_RULE) -> np.ndarray:
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
    quad : ProductQuadrature or PolarQuadrature, optional
        The quadrature (default: :func:`make_quadrature` with ``rule`` for these baselines).
    """
    import ducc0

    u = np.asarray(u, dtype=float)
    v = np.asarray(v, dtype=float)
    flux, pos = _placed_cells(u, v, profile, template, r_p, phi_p, quad, cell_factor, rule)
    q = np.stack(geometry.disc_frame_uv(u, v), axis=-1)
    vis = ducc0.nufft.experimental.nu2nu(
        points_in=flux.astype(complex), coord_in=2 * np.pi * pos,
        coord_out=np.ascontiguousarray(q), forward=False, epsilon=epsilon, nthreads=nthreads)
    return geometry.cos_inc * geometry.phase_factor(u, v) * vis


def perturbation_visibilities_dft(u, v, geometry: DiscGeometry, profile: Profile, template, r_p: float,
                                  phi_p: float, *, quad=None, cell_factor: float = DEFAULT_CELL_FACTOR,
                                  chunk: int = 256, rule: str = DEFAULT_RULE) -> np.ndarray:
    """Plain NumPy direct sum of :func:`perturbation_visibilities` (the reference; slow)."""
    u = np.asarray(u, dtype=float)
    v = np.asarray(v, dtype=float)
    flux, pos = _placed_cells(u, v, profile, template, r_p, phi_p, quad, cell_factor, rule)
    xi, eta = geometry.disc_frame_uv(u, v)
    out = point_sources_dft(xi, eta, pos[:, 0], pos[:, 1], flux, chunk=chunk)
    return geometry.cos_inc * geometry.phase_factor(u, v) * out


def render_perturbation_image(profile: Profile, template, r_p: float, phi_p: float, inc: float,
                              shape, pixel_size: float, supersample: int = 3) -> np.ndarray:
    """Image [Jy/pixel] of ``I_A delta`` in the frame of :func:`spiralbayes.fourier.sample_image`.

    Major axis north (PA and offsets are applied in uv space by the sampler); each pixel is the
    mean of ``supersample ** 2`` point samples of the continuous model (bilinear template).
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
