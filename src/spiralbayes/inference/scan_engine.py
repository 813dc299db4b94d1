"""The grid scan: Δχ² of every template at every planet position (Stevenson et al. 2024, sec. 2.3).

For a template placed at ``(r_p, phi_p)`` with perturbation visibilities ΔV and residual
``R = V_O - V_A`` of the axisymmetric model,

    Δχ² = chi2_AO - chi2_SO = 2 Re sum_k w_k R_k* ΔV_k - sum_k w_k |ΔV_k|^2 = 2 cross - power.

Neither term needs one image and one 2-D FFT per planet position (the authors' galario loop):

* ``cross`` is the perturbation's flux correlated with the weighted residual dirty image
  ``D(s) = sum_k w_k R'_k exp(-2 pi i q_k . s)`` evaluated exactly (type-3 NUFFT) at the cells of
  a polar quadrature grid, once per r_p. Moving the planet in ``phi_p`` is a cyclic shift on
  that grid, so all azimuths come from FFTs along ``phi``.
* ``power`` depends on the data only through the uv coverage and weights. With ``q_k`` in polar
  form ``(rho_k, theta_k)`` in the disc frame, ``power(phi_p) = cos^2 i sum_k w_k
  G(rho_k, theta_k - phi_p)`` where ``G = |P_hat|^2`` is the perturbation's power spectrum for
  ``phi_p = 0``. ``G`` is computed exactly at the nodes of a polar uv grid (one type-3 NUFFT per
  template and r_p), interpolated with cubic Lagrange polynomials in ``rho`` and exactly (its
  angular bandwidth is limited by the disc's size) in ``theta``; the data enter through the
  angular Fourier coefficients of their interpolation weights, computed once. All ``phi_p`` then
  follow from one FFT.

:func:`direct_delta_chi2` is the reference: it builds ΔV for one instance and sums χ².
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..fourier import NUFFT_EPSILON
from ..geometry import DiscGeometry
from ..model import (
    DEFAULT_CELL_FACTOR,
    PolarQuadrature,
    make_quadrature,
    perturbation_flux,
    perturbation_visibilities,
)
from ..exceptions import InputError
from ..units import ARCSEC
from .statistics import chi2, delta_chi2_from_terms

__all__ = ["ScanContext", "cross_template", "direct_delta_chi2", "perturbation_spectrum", "scan_template",
           "with_residual"]

POWER_EPSILON = 1e-5  # single precision, relative to max |P_hat|; errors in Δχ² are checked by tests
RHO_OVERSAMPLE = 4.0


def _profile_and_model_vis(axisymmetric, vis, geometry):
    """The brightness callable and the model visibilities of ``axisymmetric`` at the data."""
    if callable(getattr(axisymmetric, "brightness", None)):
        profile = axisymmetric.brightness
        V_A = axisymmetric.visibilities(vis.u, vis.v, geometry)
    elif isinstance(axisymmetric, tuple) and len(axisymmetric) == 2:
        profile, V_A = axisymmetric
    else:
        raise TypeError("axisymmetric must be an AxisymmetricModel or a (profile, V_A) tuple")
    return profile, np.asarray(V_A, dtype=complex)


@dataclass
class ScanContext:
    """Everything a scan needs that does not depend on the template (picklable, for Dask).

    Build it with :meth:`ScanContext.build`.
    """

    profile: object
    geometry: DiscGeometry
    u: np.ndarray
    v: np.ndarray
    weights: np.ndarray
    residual: np.ndarray  # (V_O - V_A) shifted to the disc centre
    chi2_AO: float
    r_p: np.ndarray
    n_phi_p: int
    cell_factor: float
    d_rho: float
    n_theta: int
    uv_weights_hat: np.ndarray = field(repr=False)  # (n_rho, n_theta) angular coefficients
    nthreads: int = 1
    _dirty_cache: dict = field(default_factory=dict, repr=False)
    _quad_cache: dict = field(default_factory=dict, repr=False)
    _plan_cache: dict = field(default_factory=dict, repr=False)

    def __getstate__(self):
        # NUFFT plans cannot be pickled; workers rebuild caches on first use
        return {**self.__dict__, "_dirty_cache": {}, "_plan_cache": {}}

    @classmethod
    def build(cls, vis, axisymmetric, geometry: DiscGeometry, r_p, n_phi_p: int = 90,
              cell_factor: float = DEFAULT_CELL_FACTOR, x_max: float = 2.2, nthreads: int = 1) -> "ScanContext":
        vis = vis.standardised()
        profile, V_A = _profile_and_model_vis(axisymmetric, vis, geometry)
        r_p = np.atleast_1d(np.asarray(r_p, dtype=float))
        residual = geometry.phase_shift(vis.u, vis.v, vis.V - V_A, inverse=True)
        xi, eta = geometry.disc_frame_uv(vis.u, vis.v)
        rho, theta = np.hypot(xi, eta), np.arctan2(eta, xi)
        r_out = float(r_p.max()) * x_max * ARCSEC
        d_rho = 1.0 / (RHO_OVERSAMPLE * 4 * r_out)
        m_max = 2 * np.pi * rho.max() * 2 * r_out
        n_theta = _multiple_at_least(int(np.ceil(2 * m_max + 8)), n_phi_p)
        hat = _uv_weight_coefficients(rho, theta, vis.weights, d_rho, n_theta, nthreads)
        return cls(profile, geometry, vis.u, vis.v, vis.weights, residual, chi2(V_A, vis.V, vis.weights),
                   r_p, int(n_phi_p), float(cell_factor), d_rho, n_theta, hat, nthreads)

    @property
    def uv_max(self) -> float:
        return float(np.max(np.hypot(self.u, self.v)))

    def quadrature(self, template, r_p: float) -> PolarQuadrature:
        """The quadrature grid for ``template`` at ``r_p`` (cached: templates of a bank share grids)."""
        x = np.asarray(template.x)
        key = (float(r_p), x.size, float(x[0]), float(x[-1]), len(template.phi))
        if key not in self._quad_cache:
            self._quad_cache[key] = make_quadrature(template, r_p, self.uv_max, cell_factor=self.cell_factor,
                                                    phi_multiple=self.n_phi_p)
        return self._quad_cache[key]

    @property
    def uv_nodes(self) -> np.ndarray:
        """Polar uv nodes ``(rho_j cos theta_m, rho_j sin theta_m)`` for ``theta_m < pi`` [lambda]."""
        n_rho, n_theta = self.uv_weights_hat.shape
        rho = np.arange(n_rho) * self.d_rho
        theta = 2 * np.pi * np.arange(n_theta // 2) / n_theta
        return np.stack([np.outer(rho, np.cos(theta)).ravel(), np.outer(rho, np.sin(theta)).ravel()], axis=-1)

    def power_plan(self, quad: PolarQuadrature):
        """A reusable single-precision type-3 plan from the quadrature cells to the uv nodes.

        Templates share it (it depends only on the grid), which halves the cost of the power term.
        """
        key = _grid_key(quad)
        if key not in self._plan_cache:
            import ducc0

            self._plan_cache[key] = ducc0.nufft.experimental.plan3(
                coord_in=(2 * np.pi * quad.positions()).astype(np.float32),
                coord_out=self.uv_nodes.astype(np.float32), epsilon=POWER_EPSILON, nthreads=self.nthreads)
        return self._plan_cache[key]

    def dirty_spectrum(self, quad: PolarQuadrature) -> np.ndarray:
        """``rfft`` along phi of :meth:`dirty_on` (cached: every template correlates with it)."""
        key = _grid_key(quad)
        if key not in self._dirty_cache:
            self._dirty_cache[key] = np.fft.rfft(self.dirty_on(quad), axis=1)
        return self._dirty_cache[key]

    def dirty_on(self, quad: PolarQuadrature) -> np.ndarray:
        """Real part of the residual dirty image at the quadrature cells, shape ``quad.shape``."""
        import ducc0

        q = np.stack(self.geometry.disc_frame_uv(self.u, self.v), axis=-1)
        dirty = ducc0.nufft.experimental.nu2nu(
            points_in=self.weights * self.residual, coord_in=np.ascontiguousarray(q),
            coord_out=2 * np.pi * quad.positions(), forward=True, epsilon=NUFFT_EPSILON, nthreads=self.nthreads)
        return dirty.real.reshape(quad.shape)


def _grid_key(quad: PolarQuadrature) -> tuple:
    """Identifies a quadrature grid for the per-grid caches."""
    return (quad.r_p, quad.x_edges[0], quad.x_edges[-1], quad.x.size, quad.n_phi)


def _multiple_at_least(n: int, base: int) -> int:
    return base * int(np.ceil(n / base))


def _lagrange_cubic(t: np.ndarray) -> np.ndarray:
    """Weights of nodes -1, 0, 1, 2 for a point at fractional offset ``t`` in [0, 1)."""
    return np.stack([-t * (t - 1) * (t - 2) / 6, (t + 1) * (t - 1) * (t - 2) / 2,
                     -(t + 1) * t * (t - 2) / 2, (t + 1) * t * (t - 1) / 6])


def _uv_weight_coefficients(rho, theta, weights, d_rho, n_theta, nthreads) -> np.ndarray:
    """``W[j, m] = sum_k w_k L_j(rho_k) exp(i m theta_k)``, m in FFT order.

    ``L_j`` are cubic Lagrange weights on the radial nodes ``rho_j = j d_rho``; a node at
    ``-d_rho`` is folded onto ``+d_rho`` (G is even: G(-q) = G(q)).
    """
    import ducc0

    f = rho / d_rho
    j0 = np.floor(f).astype(int)
    lag = _lagrange_cubic(f - j0)
    n_rho = int(j0.max()) + 3
    nodes = np.abs(j0[None, :] + np.arange(-1, 3)[:, None])
    values = (weights[None, :] * lag).ravel()
    nodes = nodes.ravel()
    angles = np.tile(theta, 4)
    order = np.argsort(nodes, kind="stable")
    nodes, values, angles = nodes[order], values[order], angles[order]
    bounds = np.searchsorted(nodes, np.arange(n_rho + 1))
    out = np.zeros((n_rho, n_theta), dtype=complex)
    for j in range(n_rho):
        sl = slice(bounds[j], bounds[j + 1])
        if sl.start == sl.stop:
            continue
        out[j] = ducc0.nufft.nu2u(points=values[sl].astype(complex), coord=angles[sl, None].copy(),
                                  out=np.empty(n_theta, dtype=complex), forward=False,
                                  epsilon=1e-12, nthreads=nthreads, fft_order=True)
    return out


def perturbation_spectrum(context: ScanContext, flux: np.ndarray, quad: PolarQuadrature) -> np.ndarray:
    """``P_hat = sum_c flux_c exp(2 pi i q . s_c)`` [Jy] at the polar uv nodes with ``theta < pi``.

    Shape ``(n_rho, n_theta // 2)``, single precision, planet at ``phi_p = 0`` and without the
    ``cos i`` factor; the other half follows from ``P_hat(rho, theta + pi) = conj(P_hat(rho, theta))``.
    """
    n_rho, n_theta = context.uv_weights_hat.shape
    p_hat = context.power_plan(quad).exec(forward=False, points_in=flux.ravel().astype(np.complex64))
    return p_hat.reshape(n_rho, n_theta // 2)


def _power_all_phi(context: ScanContext, flux: np.ndarray, quad: PolarQuadrature) -> np.ndarray:
    """``sum_k w_k |ΔV_k|^2`` for every azimuth of the uv grid (length ``n_theta``)."""
    p_hat = perturbation_spectrum(context, flux, quad)
    g_half = p_hat.real.astype(float) ** 2 + p_hat.imag.astype(float) ** 2
    g = np.concatenate([g_half, g_half], axis=1)  # G(rho, theta + pi) = G(rho, theta)
    coeff = np.fft.fft(g, axis=1) / g.shape[1]
    power = np.fft.fft(np.sum(coeff * context.uv_weights_hat, axis=0)).real
    return context.geometry.cos_inc ** 2 * power


def _cross_all_phi(context: ScanContext, flux: np.ndarray, quad: PolarQuadrature) -> np.ndarray:
    """``Re sum_k w_k R_k* ΔV_k`` for every azimuth of the quadrature grid (length ``n_phi``)."""
    spec = np.conj(np.fft.rfft(flux, axis=1)) * context.dirty_spectrum(quad)
    return context.geometry.cos_inc * np.fft.irfft(spec.sum(axis=0), n=quad.n_phi)


def cross_template(context: ScanContext, template) -> np.ndarray:
    """Only ``cross`` of one template over the context's grid (e.g. for another residual)."""
    out = np.empty((context.r_p.size, context.n_phi_p))
    for i, r_p in enumerate(context.r_p):
        quad = context.quadrature(template, r_p)
        flux = perturbation_flux(context.profile, template, quad)
        out[i] = _cross_all_phi(context, flux, quad)[:: quad.n_phi // context.n_phi_p]
    return out


def with_residual(context: ScanContext, residual) -> ScanContext:
    """A context for other residual visibilities ``R`` [Jy] (same data points, weights and grids).

    ``R`` is in the frame of the data (like ``V_O - V_A``; the disc-centre shift is applied here).
    The cross term is linear in ``R``: an injected signal or a noise realisation adds its own
    cross term, computed without rebuilding the uv weights or the quadratures.
    """
    residual = np.asarray(residual, dtype=complex)
    if residual.shape != context.residual.shape:
        raise InputError(f"residual has shape {residual.shape}, the data have {context.residual.shape}")
    shifted = context.geometry.phase_shift(context.u, context.v, residual, inverse=True)
    return replace(context, residual=shifted, _dirty_cache={}, _quad_cache=context._quad_cache,
                   _plan_cache=context._plan_cache)


def scan_template(context: ScanContext, template) -> tuple[np.ndarray, np.ndarray]:
    """``cross`` and ``power`` of one template over the context's ``r_p`` × ``phi_p`` grid."""
    n_rp, n_phi_p = context.r_p.size, context.n_phi_p
    cross = np.empty((n_rp, n_phi_p))
    power = np.empty((n_rp, n_phi_p))
    for i, r_p in enumerate(context.r_p):
        quad = context.quadrature(template, r_p)
        flux = perturbation_flux(context.profile, template, quad)
        cross[i] = _cross_all_phi(context, flux, quad)[:: quad.n_phi // n_phi_p]
        power[i] = _power_all_phi(context, flux, quad)[:: context.n_theta // n_phi_p]
    return cross, power


def direct_delta_chi2(vis, axisymmetric, geometry: DiscGeometry, template, r_p: float, phi_p: float,
                      *, cell_factor: float = DEFAULT_CELL_FACTOR, amplitude=None) -> float:
    """Δχ² of one instance by building ΔV at every baseline and summing χ² (the reference)."""
    vis = vis.standardised()
    profile, V_A = _profile_and_model_vis(axisymmetric, vis, geometry)
    dV = perturbation_visibilities(vis.u, vis.v, geometry, profile, template, r_p, phi_p, cell_factor=cell_factor)
    R = vis.V - V_A
    cross = np.sum(vis.weights * (np.conj(R) * dV).real)
    power = np.sum(vis.weights * np.abs(dV) ** 2)
    return float(delta_chi2_from_terms(cross, power, amplitude))
