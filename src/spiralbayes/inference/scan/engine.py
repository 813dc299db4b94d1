"""The grid scan's engine: Δχ² of one template at every planet position (Stevenson et al. 2024, sec. 2.3).

For a template placed at ``(r_p, phi_p)`` with perturbation visibilities ΔV and residual
``R = V_O - V_A`` of the axisymmetric model,

    ``Δχ² = chi2_AO - chi2_SO = 2 Re sum_k w_k R_k* ΔV_k - sum_k w_k |ΔV_k|^2 = 2 cross - power``.

Neither term needs one image and one 2-D FFT per planet position (the authors' galario loop).
The perturbation is a set of point sources, the nodes of the product-integration rule of
:mod:`spiralbayes.quadrature` (exact to ~1e-11 of its L1 norm at every baseline the scan uses), on
a polar grid of the disc plane whose azimuths are a multiple of the scan's, so that moving the
planet in ``phi_p`` is a cyclic shift of the nodes:

* ``cross`` is the node fluxes correlated with the weighted residual dirty image
  ``D(s) = sum_k w_k R'_k exp(-2 pi i q_k . s)``, evaluated exactly (type-3 NUFFT) at the nodes
  once per radius; all azimuths come from FFTs along ``phi``.
* ``power`` depends on the data only through the uv coverage and weights. Two paths, chosen by
  their cost (``power_path="auto"``): the *polar* path computes the perturbation's power spectrum
  on polar uv grids and sums it against the weights' angular coefficients
  (:mod:`spiralbayes.inference.scan.uv_levels`): its cost per template does not grow with N. The
  *direct* path evaluates ΔV at every baseline rotated by every planet azimuth (one type-3 NUFFT to
  ``N n_phi_p`` points per radius) and sums both terms exactly: cheaper for small N (the 196
  visibilities of the AS 209 sample), and it needs no uv grid at all.

Accuracy rule and the error estimate
------------------------------------
A Δχ² is reported to within ``0.05 + 1e-4 |Δχ²|`` (:data:`.TOLERANCE`). The absolute part is what
matters near the detection threshold, where ``2 cross`` and ``power`` nearly cancel: with ``power``
up to ~1e3 there, each term must be good to ~1e-5 relative, and 1e-6 leaves a factor 10 for the
largest powers met in practice (a bright planet's own peak, where the relative part takes over).
Every template's terms carry an estimate of their error, stored in the scan result:

* the quadrature's bound ``B`` on ``|δΔV|`` at every baseline
  (:meth:`~spiralbayes.quadrature.ProductQuadrature.error_bound`, times cos i):
  ``|δ cross| <= B sum w |R|`` and ``|δ power| <= 2 B sqrt(sum w · power) + B^2 sum w``;
* the power algorithm's own error (interpolation in ``rho`` on the polar path, the NUFFT's
  ``epsilon``), measured once per scan by :func:`~.accuracy.check_terms` against exact
  sums (ΔV at every baseline) at the largest radius of each uv level and four azimuths, and
  added as ``CHECK_SAFETY`` times the worst relative discrepancy (:mod:`.accuracy`).

``rule="midpoint"`` (the earlier cells of ``1 / (cell_factor u_max)``, second order: ``Σ w |ΔV|^2``
low by 3-9e-4 at ``cell_factor`` 20) is kept as a reference; it has no bound, so its error
estimates are NaN. :func:`direct_delta_chi2` is the plain reference: ΔV for one instance at every
baseline and the χ² sums.

Why this module is long: the context (data, uv grids, per-grid caches), the two power paths, the
cross kernel, the per-instance error estimates and the entry points that reuse them (another
residual, the full uv grid of injection–recovery) share the same cached plans and node layout;
split apart, each piece would reach into the others' caches.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from ..._threads import blas_threads
from ...exceptions import InputError
from ...fourier import NUFFT_EPSILON
from ...geometry import DiscGeometry
from ...model import (
    DEFAULT_CELL_FACTOR,
    DEFAULT_RULE,
    RULES,
    make_quadrature,
    perturbation_flux,
    perturbation_visibilities,
    profile_breaks,
    profile_support,
)
from ...quadrature import ProductQuadrature, TemplateSpectrum
from ...units import ARCSEC
from .settings import POWER_PATHS, ScanSettings
from .statistics import chi2, delta_chi2_from_terms
from .uv_levels import (
    RHO_OVERSAMPLE,
    RHO_POINTS,
    THETA_TOLERANCE,
    UVLevel,
    build_level,
    level_radii,
    power_all_phi,
    theta_count,
)

__all__ = ["EngineSettings", "ScanContext", "TemplateTerms", "cross_template", "direct_delta_chi2",
           "perturbation_spectrum", "profile_and_model_vis", "scan_template", "with_residual"]


POWER_EPSILON = 1e-7
"""Accuracy of the power path's double-precision type-3 NUFFT."""
CHECK_SAFETY = 3.0
"""The power path's measured discrepancy (:func:`~.accuracy.check_terms`) enters the error
estimates times this."""
DIRECT_MAX_POINTS = 20_000_000
"""The direct path is not chosen when N n_phi_p exceeds this (memory of one radius' ΔV)."""


@dataclass(frozen=True)
class EngineSettings:
    """How the scan computes its terms (all part of the resume key).

    The user's options (the rule, ``cell_factor``, the power path) come from the public
    :class:`~.settings.ScanSettings` (:meth:`EngineSettings.of`); the
    other fields are numerical knobs with tested defaults.

    Attributes
    ----------
    rule : {"product", "midpoint"}
        The quadrature (:func:`spiralbayes.model.make_quadrature`).
    cell_factor : float
        Midpoint cells are at most ``1 / (cell_factor u_max)`` across (midpoint rule only).
    power_path : {"auto", "polar", "direct"}
        How ``power`` is computed (module docstring); "auto" takes the cheaper.
    rho_points, rho_oversample, theta_tolerance : int, float, float
        The polar uv grids (:mod:`spiralbayes.inference.scan.uv_levels`).
    power_epsilon : float
        Accuracy of the power term's NUFFT (double precision).
    multilevel : bool
        A ladder of uv grids (True) or one for every radius.
    banded : bool
        Each uv ring with the azimuths its own radius needs (True) or all with the outermost's
        (then the levels keep the full weight coefficients, ``UVLevel.hat``).
    """

    rule: str = DEFAULT_RULE
    cell_factor: float = DEFAULT_CELL_FACTOR
    power_path: str = "auto"
    rho_points: int = RHO_POINTS
    rho_oversample: float = RHO_OVERSAMPLE
    power_epsilon: float = POWER_EPSILON
    theta_tolerance: float = THETA_TOLERANCE
    multilevel: bool = True
    banded: bool = True

    def __post_init__(self):
        if self.rule not in RULES:
            raise InputError(f"rule = {self.rule!r}: the quadrature rules are {RULES}")
        if self.power_path not in POWER_PATHS:
            raise InputError(f"power_path = {self.power_path!r} must be one of {POWER_PATHS}")
        if isinstance(self.rho_points, bool) or int(self.rho_points) != self.rho_points or self.rho_points < 2 \
                or self.rho_points % 2:
            raise InputError(f"rho_points = {self.rho_points!r} must be an even integer >= 2 (default {RHO_POINTS})")

    @classmethod
    def of(cls, settings: ScanSettings) -> EngineSettings:
        """The engine settings of a scan's :class:`~.settings.ScanSettings` (numerical defaults otherwise)."""
        return cls(rule=settings.quadrature, cell_factor=float(settings.cell_factor), power_path=settings.power_path)

    def describe(self) -> dict:
        """The settings that change the numbers (``cell_factor`` only for the midpoint rule)."""
        out = {"rule": self.rule, "power_path": self.power_path, "rho_points": int(self.rho_points),
               "rho_oversample": float(self.rho_oversample), "power_epsilon": float(self.power_epsilon),
               "theta_tolerance": float(self.theta_tolerance), "multilevel": bool(self.multilevel),
               "banded": bool(self.banded)}
        if self.rule == "midpoint":
            out["cell_factor"] = float(self.cell_factor)
        return out


class TemplateTerms(tuple):
    """``(cross, power)`` of one template, shape ``(n_rp, n_phi_p)`` each, with their error
    estimates as the attributes ``cross_error`` and ``power_error`` (same shape; NaN when the rule
    has none). Unpacks as a pair."""

    cross_error: np.ndarray
    power_error: np.ndarray

    def __new__(cls, cross, power, cross_error=None, power_error=None):
        self = super().__new__(cls, (cross, power))
        self.cross_error = np.full(np.shape(cross), np.nan) if cross_error is None else cross_error
        self.power_error = np.full(np.shape(power), np.nan) if power_error is None else power_error
        return self

    def __reduce__(self):
        return (TemplateTerms, (self[0], self[1], self.cross_error, self.power_error))


def profile_and_model_vis(axisymmetric, vis, geometry):
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

    profile: Callable[[np.ndarray], np.ndarray]  # I(r) [Jy/sr], r [arcsec]
    geometry: DiscGeometry
    u: np.ndarray
    v: np.ndarray
    weights: np.ndarray
    residual: np.ndarray  # (V_O - V_A) shifted to the disc centre
    chi2_AO: float
    r_p: np.ndarray
    n_phi_p: int
    settings: EngineSettings = field(default_factory=EngineSettings)
    power_path: str = "polar"  # resolved: "polar" or "direct"
    levels: list = field(default_factory=list, repr=False)  # UVLevel, largest first (polar path)
    support: float | None = None  # radius beyond which the profile vanishes [arcsec]
    x_max: float = 2.2
    rho_max: float = 0.0  # longest disc-frame baseline [lambda]
    weighted_abs_residual: float = 0.0  # sum w |R|
    weight_sum: float = 0.0
    nthreads: int = 1
    algorithm_error: dict = field(default_factory=dict)  # relative discrepancies measured by check_terms
    breaks: tuple = ()  # radii where the profile jumps inside the support [arcsec]
    _dirty_cache: dict = field(default_factory=dict, repr=False)
    _quad_cache: dict = field(default_factory=dict, repr=False)
    _plan_cache: dict = field(default_factory=dict, repr=False)
    _spectrum_cache: dict = field(default_factory=dict, repr=False)

    def __getstate__(self):
        # NUFFT plans cannot be pickled; workers rebuild caches on first use
        return {**self.__dict__, "_dirty_cache": {}, "_plan_cache": {}, "_spectrum_cache": {}}

    @classmethod
    def build(cls, vis, axisymmetric, geometry: DiscGeometry, r_p, n_phi_p: int = ScanSettings.n_phi_p,
              cell_factor: float = DEFAULT_CELL_FACTOR, x_max: float = 2.2, nthreads: int = 1, *,
              rule: str | None = None, power_path: str | None = None,
              settings: EngineSettings | ScanSettings | None = None) -> ScanContext:
        """Residual, weights and (polar path) the uv grids for the radii ``r_p`` [arcsec].

        ``x_max`` is the largest ``r / r_p`` of the templates to scan; ``settings`` (or the
        shortcuts ``rule``, ``power_path``) say how the terms are computed.
        """
        if isinstance(settings, ScanSettings):
            settings = EngineSettings.of(settings)
        settings = settings or EngineSettings(rule=rule or DEFAULT_RULE, cell_factor=float(cell_factor),
                                              power_path=power_path or "auto")
        vis = vis.standardised()
        profile, V_A = profile_and_model_vis(axisymmetric, vis, geometry)
        support = profile_support(profile) if settings.rule == "product" else None
        r_p = np.atleast_1d(np.asarray(r_p, dtype=float))
        residual = geometry.phase_shift(vis.u, vis.v, vis.V - V_A, inverse=True)
        xi, eta = geometry.disc_frame_uv(vis.u, vis.v)
        rho, theta = np.hypot(xi, eta), np.arctan2(eta, xi)
        radii = _radii(r_p, x_max, support)
        path = _choose_power_path(settings, radii, rho.max(), vis.n, int(n_phi_p))
        levels = []
        if path == "polar":
            order = np.argsort(rho, kind="stable")
            for r_out in level_radii(radii, settings.multilevel):
                levels.append(build_level(rho[order], theta[order], vis.weights[order], r_out, int(n_phi_p),
                                          points=settings.rho_points, oversample=settings.rho_oversample,
                                          theta_tolerance=settings.theta_tolerance, banded=settings.banded,
                                          nthreads=nthreads))
        return cls(profile, geometry, vis.u, vis.v, vis.weights, residual, chi2(V_A, vis.V, vis.weights), r_p,
                   int(n_phi_p), settings, path, levels, support, float(x_max), float(rho.max()),
                   float(np.sum(vis.weights * np.abs(residual))), float(np.sum(vis.weights)), int(nthreads),
                   breaks=profile_breaks(profile) if settings.rule == "product" else ())

    # -- compatibility and description -----------------------------------------------------------
    @property
    def cell_factor(self) -> float:
        return self.settings.cell_factor

    @property
    def uv_max(self) -> float:
        return float(np.max(np.hypot(self.u, self.v)))

    @property
    def d_rho(self) -> float:
        """Radial step [lambda] of the largest uv level (0 on the direct path)."""
        return self.levels[0].d_rho if self.levels else 0.0

    @property
    def n_theta(self) -> int:
        """Azimuths of the largest uv level (0 on the direct path)."""
        return self.levels[0].n_theta if self.levels else 0

    @property
    def uv_weights_hat(self) -> np.ndarray:
        """The largest level's weight coefficients ``W[j, m]`` (FFT order of m); needs a context
        built with ``EngineSettings(power_path="polar", banded=False)``."""
        if not self.levels or self.levels[0].hat is None:
            raise InputError("this scan context keeps no full uv weight coefficients: build it with "
                             "settings=EngineSettings(power_path='polar', banded=False)")
        return self.levels[0].hat

    def with_full_grid(self) -> ScanContext:
        """This context with one unbanded polar uv grid for every radius (the full weight
        coefficients :attr:`uv_weights_hat`, which injection–recovery needs); itself if it has one."""
        if self.power_path == "polar" and len(self.levels) == 1 and self.levels[0].hat is not None:
            return self
        settings = replace(self.settings, power_path="polar", banded=False, multilevel=False)
        xi, eta = self.geometry.disc_frame_uv(self.u, self.v)
        rho, theta = np.hypot(xi, eta), np.arctan2(eta, xi)
        order = np.argsort(rho, kind="stable")
        r_out = float(np.max(_radii(self.r_p, self.x_max, self.support)))
        level = build_level(rho[order], theta[order], self.weights[order], r_out, self.n_phi_p,
                            points=settings.rho_points, oversample=settings.rho_oversample,
                            theta_tolerance=settings.theta_tolerance, banded=False, nthreads=self.nthreads)
        return replace(self, settings=settings, power_path="polar", levels=[level], _dirty_cache=self._dirty_cache,
                       _quad_cache={}, _plan_cache={}, _spectrum_cache={})

    def describe(self) -> dict:
        """The resolved numerical set-up (JSON-able), for provenance and the resume key."""
        return {**self.settings.describe(), "power_path_used": self.power_path,
                "levels": [{"r_out": lv.r_out, "d_rho": lv.d_rho, "n_theta": lv.n_theta, "n_rho": lv.n_rho,
                            "nodes": lv.size} for lv in self.levels]}

    # -- grids ---------------------------------------------------------------------------------------
    def level(self, quad) -> UVLevel:
        """The smallest uv level whose ``r_out`` holds the perturbation of ``quad``."""
        return self._level_for(_radius(quad))

    def _level_for(self, radius: float) -> UVLevel:
        fitting = [lv for lv in self.levels if lv.r_out >= radius * (1 - 1e-12)]
        if not fitting:
            raise InputError(f"a template reaches {radius:.4g} arcsec, beyond the scan's uv grid "
                             f"({self.levels[0].r_out:.4g} arcsec = largest r_p x x_max): build the context with "
                             "x_max = the templates' largest r / r_p")
        return fitting[-1]

    def quadrature(self, template, r_p: float):
        """The quadrature for ``template`` at ``r_p`` (cached: templates of a bank share grids).

        The product rule is made exact out to the longest baseline the power path evaluates: the
        data's on the direct path, the last node of the ``rho`` stencil on the polar path.
        """
        x = np.asarray(template.x, dtype=float)
        key = (float(r_p), x.size, float(x[0]), float(x[-1]), len(template.phi))
        if key not in self._quad_cache:
            if self.settings.rule == "product":
                reach = self.rho_max
                if self.power_path == "polar":
                    reach = self._level_for(_radii(np.array([r_p]), float(x[-1]), self.support)[0]).reach
                quad = make_quadrature(template, r_p, reach, phi_multiple=self.n_phi_p, support=self.support,
                                       breaks=self.breaks)
            else:
                quad = make_quadrature(template, r_p, self.uv_max, cell_factor=self.settings.cell_factor,
                                       phi_multiple=self.n_phi_p, rule="midpoint")
            self._quad_cache[key] = quad
        return self._quad_cache[key]

    def spectrum(self, template) -> TemplateSpectrum:
        """The template's exact angular series (cached for the template in hand)."""
        held = self._spectrum_cache.get("template")
        if held is None or held[0] is not template:
            held = (template, TemplateSpectrum(template))
            self._spectrum_cache["template"] = held
        return held[1]

    def flux(self, template, quad) -> np.ndarray:
        """Node fluxes [Jy] of ``template`` on ``quad`` (face on), planet at ``phi = 0``, flat."""
        if isinstance(quad, ProductQuadrature):
            return quad.flux(self.profile, self.spectrum(template))
        return perturbation_flux(self.profile, template, quad).ravel()

    # -- per-grid caches shared by the templates ------------------------------------------------------
    def power_plan(self, quad):
        """A reusable double-precision type-3 plan from the nodes to the uv nodes of the quadrature's
        level (polar path) or to the baselines rotated by every planet azimuth (direct path)."""
        if quad.key not in self._plan_cache:
            import ducc0

            out = self.level(quad).nodes() if self.power_path == "polar" else self.rotated_baselines()
            self._plan_cache[quad.key] = ducc0.nufft.experimental.plan3(
                coord_in=2 * np.pi * quad.positions(), coord_out=out, epsilon=self.settings.power_epsilon,
                nthreads=self.nthreads)
        return self._plan_cache[quad.key]

    def rotated_baselines(self, phi_index=None) -> np.ndarray:
        """``R(-phi_p) q_k`` for the planet azimuths (all, or ``phi_index``), azimuth-major, shape (n, 2)."""
        xi, eta = self.geometry.disc_frame_uv(self.u, self.v)
        index = np.arange(self.n_phi_p) if phi_index is None else np.atleast_1d(phi_index)
        phi = 2 * np.pi * index / self.n_phi_p
        c, s = np.cos(phi)[:, None], np.sin(phi)[:, None]
        return np.stack([(c * xi + s * eta).ravel(), (-s * xi + c * eta).ravel()], axis=-1)

    def dirty_spectrum(self, quad) -> list[np.ndarray]:
        """``rfft`` along phi of :meth:`dirty_on`, one array per group of rings (cached: every
        template correlates with it)."""
        if quad.key not in self._dirty_cache:
            self._dirty_cache[quad.key] = [np.fft.rfft(d, axis=1) for d in quad.split(self.dirty_on(quad))]
        return self._dirty_cache[quad.key]

    def dirty_on(self, quad) -> np.ndarray:
        """Real part of the residual dirty image at the quadrature nodes (flat, node order)."""
        import ducc0

        q = np.stack(self.geometry.disc_frame_uv(self.u, self.v), axis=-1)
        dirty = ducc0.nufft.experimental.nu2nu(
            points_in=self.weights * self.residual, coord_in=np.ascontiguousarray(q),
            coord_out=2 * np.pi * quad.positions(), forward=True, epsilon=NUFFT_EPSILON, nthreads=self.nthreads)
        return dirty.real

def _radii(r_p: np.ndarray, x_max: float, support: float | None) -> np.ndarray:
    """Outer radius [arcsec] of the perturbation at each r_p."""
    radii = np.asarray(r_p, dtype=float) * x_max
    return radii if support is None else np.minimum(radii, support)


def _radius(quad) -> float:
    x_end = quad.x_end if isinstance(quad, ProductQuadrature) else float(quad.x_edges[-1])
    return float(quad.r_p) * x_end


def _choose_power_path(settings: EngineSettings, radii, rho_max: float, n_data: int, n_phi_p: int) -> str:
    """``"direct"`` when ΔV at the N n_phi_p rotated baselines costs fewer NUFFT outputs than the uv grids."""
    if settings.power_path != "auto":
        return settings.power_path
    if n_data * n_phi_p > DIRECT_MAX_POINTS:
        return "polar"
    ladder = level_radii(radii, settings.multilevel)
    sizes = []
    for r_out in ladder:
        d_rho = 1.0 / (settings.rho_oversample * 4 * r_out * ARCSEC)
        reach = rho_max + (settings.rho_points // 2 + 1) * d_rho
        sizes.append((reach / d_rho + 1) * theta_count(reach, r_out, n_phi_p, settings.theta_tolerance) / 2)
    polar = sum(sizes[max(i for i, r in enumerate(ladder) if r >= radius * (1 - 1e-12))] for radius in radii)
    return "direct" if n_data * n_phi_p * len(radii) <= polar else "polar"


# --- the kernels ---------------------------------------------------------------------------------------
def _cross_all_phi(context: ScanContext, flux: np.ndarray, quad) -> np.ndarray:
    """``Re sum_k w_k R_k* ΔV_k`` at the scan's planet azimuths: per group of rings a circular
    correlation of the fluxes with the dirty image along phi (one FFT), taken at the azimuths."""
    out = np.zeros(context.n_phi_p)
    for f, d, (_, _, n) in zip(quad.split(flux), context.dirty_spectrum(quad), quad.blocks):
        spec = np.einsum("am,am->m", np.conj(np.fft.rfft(f, axis=1)), d)
        out += np.fft.irfft(spec, n=n)[:: n // context.n_phi_p]
    return context.geometry.cos_inc * out


def _node_transform(context: ScanContext, flux: np.ndarray, quad) -> np.ndarray:
    """The nodes' fluxes sent to the power path's points: ``P_hat`` at the uv nodes (polar path)
    or ΔV at every rotated baseline, shape ``(n_phi_p, N)`` (direct path); face on."""
    out = context.power_plan(quad).exec(forward=False, points_in=flux.astype(complex))
    return out.reshape(context.n_phi_p, -1) if context.power_path == "direct" else out


def _polar_power(context: ScanContext, flux: np.ndarray, quad) -> np.ndarray:
    """``sum_k w_k |ΔV_k|^2`` at the scan's planet azimuths, from the power spectrum on the uv grid."""
    p_hat = _node_transform(context, flux, quad)
    return context.geometry.cos_inc ** 2 * power_all_phi(context.level(quad), p_hat, context.n_phi_p)


def _direct_terms(context: ScanContext, flux: np.ndarray, quad) -> tuple[np.ndarray, np.ndarray]:
    """``cross`` and ``power`` from ΔV at the data's baselines for every planet azimuth (small N)."""
    dV = _node_transform(context, flux, quad)
    cross = context.geometry.cos_inc * ((dV.real * context.residual.real + dV.imag * context.residual.imag)
                                        @ context.weights)
    power = context.geometry.cos_inc ** 2 * ((dV.real ** 2 + dV.imag ** 2) @ context.weights)
    return cross, power


def _terms_at(context: ScanContext, template, r_p: float) -> tuple[np.ndarray, np.ndarray, object, np.ndarray]:
    quad = context.quadrature(template, r_p)
    flux = context.flux(template, quad)
    if context.power_path == "direct":
        cross, power = _direct_terms(context, flux, quad)
    else:
        cross = _cross_all_phi(context, flux, quad)
        power = _polar_power(context, flux, quad)
    return cross, power, quad, flux


def scan_template(context: ScanContext, template) -> TemplateTerms:
    """``cross`` and ``power`` of one template over the context's ``r_p`` × ``phi_p`` grid, and
    their error estimates (module docstring), as a :class:`TemplateTerms` pair."""
    with blas_threads(1):  # small products: threads spinning cost more
        return _scan_template(context, template)


def _scan_template(context: ScanContext, template) -> TemplateTerms:
    n_rp, n_phi_p = context.r_p.size, context.n_phi_p
    cross, power = np.empty((n_rp, n_phi_p)), np.empty((n_rp, n_phi_p))
    cross_err, power_err = np.full((n_rp, n_phi_p), np.nan), np.full((n_rp, n_phi_p), np.nan)
    ci = context.geometry.cos_inc
    for i, r_p in enumerate(context.r_p):
        cross[i], power[i], quad, _ = _terms_at(context, template, r_p)
        if isinstance(quad, ProductQuadrature):
            B = ci * quad.error_bound(context.profile, context.spectrum(template))["total"]
            cross_err[i], power_err[i] = _error_estimates(context, B, power[i])
    return TemplateTerms(cross, power, cross_err, power_err)


def _error_estimates(context: ScanContext, bound: float, power: np.ndarray, power_scale: np.ndarray | None = None):
    """``cross_error`` and ``power_error`` at one radius (module docstring) from the quadrature's
    bound on ``|δΔV|`` [Jy] (cos i included) and the power; ``power_scale`` (default the power)
    is what the power path's measured relative discrepancy multiplies."""
    P = np.maximum(power, 0.0)
    scale = P if power_scale is None else power_scale
    cross_err = bound * context.weighted_abs_residual
    power_err = 2 * bound * np.sqrt(context.weight_sum * P) + bound * bound * context.weight_sum
    alg = context.algorithm_error
    if alg:
        cross_err = cross_err + CHECK_SAFETY * alg["cross"] * np.sqrt(context.chi2_AO * scale)
        power_err = power_err + CHECK_SAFETY * alg["power"] * scale
    return cross_err, power_err


def perturbation_spectrum(context: ScanContext, flux: np.ndarray, quad) -> np.ndarray:
    """``P_hat = sum_c flux_c exp(2 pi i q . s_c)`` [Jy] at the uv nodes with ``theta < pi`` of a
    context with one full grid (:meth:`ScanContext.with_full_grid`).

    Shape ``(n_rho, n_theta // 2)``, complex64, planet at ``phi_p = 0`` and without the ``cos i``
    factor; the other half follows from ``P_hat(rho, theta + pi) = conj(P_hat(rho, theta))``.
    """
    context.uv_weights_hat  # noqa: B018  (the property raises unless the context has the full grid)
    n_rho, n_theta = context.levels[0].n_rho, context.levels[0].n_theta
    p_hat = context.power_plan(quad).exec(forward=False, points_in=np.ravel(flux).astype(complex))
    return p_hat.reshape(n_rho, n_theta // 2).astype(np.complex64)


def cross_template(context: ScanContext, template) -> np.ndarray:
    """Only ``cross`` of one template over the context's grid (e.g. for another residual)."""
    out = np.empty((context.r_p.size, context.n_phi_p))
    with blas_threads(1):  # small products: threads spinning cost more
        for i, r_p in enumerate(context.r_p):
            quad = context.quadrature(template, r_p)
            out[i] = _cross_all_phi(context, context.flux(template, quad), quad)
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
    return replace(context, residual=shifted, weighted_abs_residual=float(np.sum(context.weights * np.abs(shifted))),
                   _dirty_cache={}, _quad_cache=context._quad_cache, _plan_cache=context._plan_cache,
                   _spectrum_cache=context._spectrum_cache)


def direct_delta_chi2(vis, axisymmetric, geometry: DiscGeometry, template, r_p: float, phi_p: float,
                      *, cell_factor: float = DEFAULT_CELL_FACTOR, amplitude=None, rule: str = DEFAULT_RULE) -> float:
    """Δχ² of one instance by building ΔV at every baseline and summing χ² (the reference)."""
    vis = vis.standardised()
    profile, V_A = profile_and_model_vis(axisymmetric, vis, geometry)
    dV = perturbation_visibilities(vis.u, vis.v, geometry, profile, template, r_p, phi_p, cell_factor=cell_factor,
                                   rule=rule)
    R = vis.V - V_A
    cross = np.sum(vis.weights * (np.conj(R) * dV).real)
    power = np.sum(vis.weights * np.abs(dV) ** 2)
    return float(delta_chi2_from_terms(cross, power, amplitude))
