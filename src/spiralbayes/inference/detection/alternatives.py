"""Maximum-likelihood fits of the competing asymmetry models, scored by ΔBIC (test 3).

Each alternative of :mod:`spiralbayes.alternatives` is fitted to the same visibilities and
weights as the scan, relative to the same axisymmetric model ``V_A``:
``Δχ²_alt = χ²_AO − min_θ χ²(V_A + ΔV_alt(θ), V_O)`` and ``ΔBIC_alt = Δχ²_alt − k_alt ln N``
(k = 4 for ``geometry``, ``lopsided`` and ``eccentric_ring``, 5 for ``arc``, ``eccentric_excess`` and ``m2``), to be
compared with the best spiral's ``ΔBIC = Δχ² − 6 ln N`` (:func:`~spiralbayes.inference.detection.detect`).

How:

* ``geometry``: Levenberg–Marquardt-type least squares (``scipy.optimize.least_squares``,
  trust-region reflective) of the four offsets, with the analytic Jacobian of
  :func:`~spiralbayes.alternatives.geometry_visibilities`, started at zero offset, its normal
  equations accumulated over blocks of visibilities (:mod:`.geometry_fit`); the final Δχ²
  uses the model's own exact visibilities at the fitted geometry.
* field models: L-BFGS-B over all parameters (bounded) with the exact gradient — one forward and
  one adjoint type-3 transform per evaluation, whatever the number of parameters
  (``dχ²/dθ = −2 sum_c (dP_c/dθ) g_c``, ``g`` the gradient map of ``w (V_O − V_model)``), from
  the best ``n_starts`` of the shapes that correlate best with the residual dirty image
  (:mod:`spiralbayes.inference.detection.starts`).

The plain NumPy reference :func:`delta_chi2_direct` rebuilds a fitted model's visibilities by
direct Fourier sums; the tests check the fits' Δχ² against it.
"""

from __future__ import annotations

import json
import logging
import time
from dataclasses import dataclass, field

import numpy as np

from ..._provenance import data_hash, json_safe, provenance_record
from ..._threads import blas_threads
from ...alternatives import (
    ALTERNATIVE_LABELS,
    ALTERNATIVE_MODELS,
    FIELD_MODELS,
    DiscGrid,
    FieldTransform,
    HankelTable,
    ProfileContext,
    field_visibilities_dft,
    n_parameters,
    offset_geometry,
)
from ...exceptions import InputError
from ...results import ResultMixin, fields_dict
from ...geometry import DiscGeometry
from ...settings import with_overrides
from ...units import ARCSEC
from ...visibilities import Visibilities
from .settings import AlternativesSettings
from .starts import candidate_starts
from ..scan.statistics import bic_threshold, chi2

__all__ = ["ALTERNATIVES_KIND", "AlternativeFit", "AlternativesResult", "delta_chi2_direct", "fit_alternatives"]

log = logging.getLogger(__name__)

ALTERNATIVES_KIND = "spiralbayes.AlternativesResult"
PARAM_SCALES = {"A": 0.3, "a_c": 0.1, "a_s": 0.1, "c_c": 0.1, "c_s": 0.1, "e_c": 0.05, "e_s": 0.05,
                "phi_c": 0.5, "sigma_phi": 0.5, "kappa": 1.0, "contrast": 0.3}
"""Typical sizes of the parameters (radii scale with the grid): the optimiser works in these units."""


@dataclass
class AlternativeFit:
    """The best fit of one alternative model.

    Attributes
    ----------
    name, label : str
        Model name (:data:`~spiralbayes.alternatives.ALTERNATIVE_MODELS`) and a readable label.
    n_params : int
        Free parameters (BIC penalty ``n_params ln N``).
    delta_chi2 : float
        ``χ²_AO − χ²`` of the best fit (positive: better than the axisymmetric model).
    theta : list of float
        Best parameters in the model's own order.
    params : dict
        The same, named, in physical units (arcsec, deg, mas).
    n_evaluations : int
        Likelihood (and gradient) evaluations over all starts.
    time_s : float
    converged : bool
        The optimiser reported success for the best start.
    """

    name: str
    label: str
    n_params: int
    delta_chi2: float
    theta: list
    params: dict
    n_evaluations: int = 0
    time_s: float = 0.0
    converged: bool = True

    def delta_bic(self, n_data: int) -> float:
        """``Δχ² − n_params ln N`` against the axisymmetric model."""
        return self.delta_chi2 - bic_threshold(n_data, self.n_params)


@dataclass(repr=False)
class AlternativesResult(ResultMixin):
    """Every alternative's best fit to one data set, with what is needed to rebuild the models.

    Attributes
    ----------
    fits : dict
        ``name -> AlternativeFit``.
    n_data : int
        Number of visibilities N.
    chi2_AO : float
        χ² of the axisymmetric model.
    geometry : DiscGeometry
        The geometry the models are placed at.
    grid : DiscGrid
        The cells of the field models.
    provenance : dict
    """

    KIND = ALTERNATIVES_KIND
    WHAT = "alternatives result"

    fits: dict
    n_data: int
    chi2_AO: float
    geometry: DiscGeometry
    grid: DiscGrid
    provenance: dict = field(default_factory=dict)

    def delta_bic(self) -> dict:
        """ΔBIC of each alternative against the axisymmetric model."""
        return {name: fit.delta_bic(self.n_data) for name, fit in self.fits.items()}

    @property
    def best(self) -> AlternativeFit:
        """The alternative with the largest ΔBIC."""
        if not self.fits:
            raise InputError("no alternative was fitted")
        return max(self.fits.values(), key=lambda f: f.delta_bic(self.n_data))

    def fitted_geometry(self) -> DiscGeometry:
        """The geometry of the ``geometry`` alternative's best fit."""
        if "geometry" not in self.fits:
            raise InputError("the geometry alternative was not fitted: include 'geometry' in models")
        return offset_geometry(self.geometry, self.fits["geometry"].theta)

    def model_visibilities(self, name: str, vis, axisymmetric, *, nthreads: int = 1) -> np.ndarray:
        """``V_model − V_A`` [Jy] of a fitted alternative at ``vis``' baselines."""
        from ...alternatives import asymmetry_visibilities

        vis = vis.standardised()
        return asymmetry_visibilities(name, self.fits[name].theta, vis.u, vis.v, axisymmetric, self.geometry,
                                      self.grid, nthreads=nthreads)

    def table(self) -> str:
        """A plain-text table: model, k, Δχ², ΔBIC and the fitted parameters."""
        rows = [f"{'model':<16}{'k':>3}{'dchi2':>11}{'dBIC':>11}  parameters"]
        for name, fit in sorted(self.fits.items(), key=lambda kv: -kv[1].delta_chi2):
            pars = ", ".join(f"{k}={v:.4g}" for k, v in fit.params.items())
            rows.append(f"{name:<16}{fit.n_params:>3}{fit.delta_chi2:>11.1f}"
                        f"{fit.delta_bic(self.n_data):>11.1f}  {pars}")
        return "\n".join(rows)

    def summary(self) -> str:
        """The best alternative in words, then :meth:`table`."""
        if not self.fits:
            return "No alternative asymmetry model was fitted."
        b = self.best
        return (f"Best competing asymmetry model: {b.label} (Delta chi2 = {b.delta_chi2:.1f}, Delta BIC = "
                f"{b.delta_bic(self.n_data):.1f} against the axisymmetric model, N = {self.n_data}).\n" + self.table())

    def to_dict(self) -> dict:
        """The fields as JSON-safe values, each fit with its ΔBIC."""
        out = fields_dict(self)
        for name, fit in self.fits.items():
            out["fits"][name]["delta_bic"] = json_safe(fit.delta_bic(self.n_data))
        return out

    def __repr__(self) -> str:
        best = f", best {self.best.name} (Delta BIC = {self.best.delta_bic(self.n_data):.1f})" if self.fits else ""
        return f"AlternativesResult({len(self.fits)} models, N = {self.n_data}, chi2_AO = {self.chi2_AO:.6g}{best})"


def _read_format_1(f) -> AlternativesResult:
    """Alternatives written before the dataclass layout (``format_version`` 1)."""
    d = json.loads(f.attrs["result"])
    prov = json.loads(f.attrs["provenance"])
    fits = {}
    for name, item in d["fits"].items():
        item.pop("delta_bic", None)
        fits[name] = AlternativeFit(**item)
    return AlternativesResult(fits, int(d["n_data"]), float(d["chi2_AO"]), DiscGeometry(**d["geometry"]),
                              DiscGrid(**d["grid"]), prov)


AlternativesResult.LEGACY_READERS = {1: _read_format_1}


# ------------------------------------------------------------------------------------------
def _emission_radius(axisymmetric, fraction: float = 0.995) -> float:
    """Radius [arcsec] enclosing ``fraction`` of the (positive) face-on flux, times 1.1."""
    r_out = float(getattr(axisymmetric, "Rmax", 3.0))
    r = np.linspace(0.0, r_out, 4001)
    I = np.clip(np.asarray(axisymmetric.brightness(r), dtype=float), 0.0, None)
    cum = np.cumsum(I * r)
    if cum[-1] <= 0:
        raise InputError("the axisymmetric profile has no positive flux: cannot place the asymmetry grid")
    return float(min(1.1 * r[np.searchsorted(cum, fraction * cum[-1])], r_out))


@dataclass
class _Problem:
    """The data side of every fit: residual, weights and the transforms."""

    vis: Visibilities
    R: np.ndarray
    weights: np.ndarray
    chi2_AO: float
    geometry: DiscGeometry
    grid: DiscGrid
    ctx: ProfileContext
    transform: FieldTransform  # single precision: the optimiser's
    exact: FieldTransform  # double precision: the reported Δχ²
    beam: float


def _setup(vis, axisymmetric, geometry, r_max, cell_factor, nthreads, grid: DiscGrid | None = None) -> _Problem:
    """The data side of the fits; ``grid`` (e.g. an earlier fit's) replaces the one made from ``r_max``."""
    V_A = np.asarray(axisymmetric.visibilities(vis.u, vis.v, geometry))
    R = vis.V - V_A
    uv_max = float(np.max(np.hypot(vis.u, vis.v)))
    if grid is None:
        r_max = _emission_radius(axisymmetric) if r_max is None else float(r_max)
        grid = DiscGrid.for_baselines(uv_max, r_max, cell_factor)
    ctx = ProfileContext.build(axisymmetric.brightness, grid)
    transform = FieldTransform(grid, vis.u, vis.v, geometry, nthreads=nthreads, single=True)
    exact = FieldTransform(grid, vis.u, vis.v, geometry, nthreads=nthreads)
    beam = 0.5 / uv_max / ARCSEC  # arcsec: half the finest fringe spacing
    return _Problem(vis, R, vis.weights, chi2(V_A, vis.V, vis.weights), geometry, grid, ctx, transform, exact, beam)


def _fit_geometry(prob: _Problem, axisymmetric) -> AlternativeFit:
    from .geometry_fit import fit_geometry_offsets

    t0 = time.perf_counter()
    vis, g = prob.vis, prob.geometry
    table = HankelTable(axisymmetric, float(np.max(np.hypot(vis.u, vis.v))), prob.grid.r_max)
    counter = {"n": 0}
    sol = fit_geometry_offsets(table, vis, prob.weights, g, np.zeros(4), max_nfev=200, counter=counter)
    fitted = offset_geometry(g, sol.x)
    dchi2 = prob.chi2_AO - chi2(axisymmetric.visibilities(vis.u, vis.v, fitted), vis.V, prob.weights)
    params = {"d_inc_deg": float(sol.x[0]), "d_PA_deg": float(sol.x[1]), "d_dRA_mas": float(sol.x[2]),
              "d_dDec_mas": float(sol.x[3])}
    return AlternativeFit("geometry", ALTERNATIVE_LABELS["geometry"], 4, float(dchi2), [float(x) for x in sol.x],
                          params, int(counter["n"]), time.perf_counter() - t0, bool(sol.success))


def _objective(model, prob: _Problem, scales, counter, project=None):
    """``(−Δχ², gradient)`` in the scaled variables ``x = theta / scales``.

    ``project(res) -> res`` removes the best fit of further linear terms from the residual (the
    nested test's spiral); by the envelope theorem the gradient is then that of the projected
    residual with the linear coefficients held fixed.
    """

    def fun(x):
        counter["n"] += 1
        theta = x * scales
        P, J = model.field_and_jacobian(theta, prob.ctx)
        dV = prob.transform.visibilities(P)
        res = prob.R - dV
        if project is not None:
            res = project(res)
        value = float(np.sum(prob.weights * (res.real ** 2 + res.imag ** 2))) - prob.chi2_AO
        g = prob.transform.gradient_map(prob.weights * res)
        grad = -2 * np.tensordot(J, g, axes=([1, 2], [0, 1]))
        return value, grad * scales

    return fun


def _fit_field(name: str, prob: _Problem, n_starts: int, max_iter: int) -> AlternativeFit:
    from scipy.optimize import minimize

    t0 = time.perf_counter()
    model = FIELD_MODELS[name]
    S = prob.transform.gradient_map(prob.weights * prob.R)
    S -= S.mean(axis=1, keepdims=True)
    starts = candidate_starts(name, S, prob.ctx, prob.transform, prob.R, prob.weights, prob.beam, n_starts)
    scales = np.array([PARAM_SCALES.get(p, 0.1 * prob.grid.r_max) for p in model.param_names])
    counter = {"n": 0}
    fun = _objective(model, prob, scales, counter)
    best = None
    for theta0 in starts:
        bounds = model.bounds(prob.ctx, theta0)
        theta0 = np.clip(theta0, [b[0] for b in bounds], [b[1] for b in bounds])
        sol = minimize(fun, theta0 / scales, jac=True, method="L-BFGS-B",
                       bounds=[(lo / s, hi / s) for (lo, hi), s in zip(bounds, scales)],
                       options={"maxiter": max_iter, "ftol": 1e-8, "gtol": 1e-3})
        if best is None or sol.fun < best.fun:
            best = sol
    if best is None:
        theta, dchi2, ok = np.zeros(model.n_params), 0.0, False
    else:
        theta, ok = model.canonical(best.x * scales), bool(best.success)
        dV = prob.exact.visibilities(model.field(theta, prob.ctx))
        dchi2 = prob.chi2_AO - chi2(prob.R, dV, prob.weights)
    return AlternativeFit(name, model.label, model.n_params, dchi2, [float(x) for x in theta],
                          model.describe(theta), int(counter["n"]), time.perf_counter() - t0, ok)


def fit_alternatives(vis, axisymmetric, geometry: DiscGeometry | None = None, *,
                     settings: AlternativesSettings | None = None, progress: bool = False,
                     **overrides) -> AlternativesResult:
    """Fit every competing asymmetry model to the data by maximum likelihood.

    Parameters
    ----------
    vis : Visibilities
        The data the scan used (same weights).
    axisymmetric : AxisymmetricModel
        The scan's axisymmetric model (anything with ``brightness(r)`` [Jy/sr] and
        ``visibilities(u, v, geometry)`` [Jy]).
    geometry : DiscGeometry, optional
        Default: the axisymmetric model's (the scan's) geometry.
    settings : AlternativesSettings, optional
        The ``models`` (a subset of :data:`~spiralbayes.alternatives.ALTERNATIVE_MODELS`; default
        all six), ``n_starts`` optimiser starts per field model (the best-correlating shapes of
        the residual image), ``max_iter`` L-BFGS-B iterations per start, the grid's outer radius
        ``r_max`` [arcsec] (default 1.1 times the radius holding 99.5 % of the profile's flux),
        its ``cell_factor`` (radial cells at most ``1 / (cell_factor uv_max)`` wide, see
        :class:`~spiralbayes.alternatives.DiscGrid`) and the NUFFTs' ``nthreads``. Default
        ``AlternativesSettings()``.
    progress : bool
        Show a progress bar over the models.
    **overrides
        Fields of :class:`AlternativesSettings` replacing those of ``settings`` (e.g. ``n_starts=4``).

    Returns
    -------
    AlternativesResult
    """
    from tqdm.auto import tqdm

    s = with_overrides(settings, AlternativesSettings, overrides, "fit_alternatives")
    models, n_starts, max_iter, r_max, cell_factor, nthreads = (s.models, s.n_starts, s.max_iter, s.r_max,
                                                                s.cell_factor, s.nthreads)

    names = list(ALTERNATIVE_MODELS if models is None else models)
    for name in names:
        n_parameters(name)
    if n_starts < 1:
        raise InputError(f"n_starts = {n_starts!r}: give at least one optimiser start per model")
    geometry = geometry or getattr(axisymmetric, "geometry", None)
    if geometry is None:
        raise InputError("geometry is needed: pass geometry=DiscGeometry(...) or an AxisymmetricModel")
    vis = vis.standardised()
    t0 = time.perf_counter()
    prob = _setup(vis, axisymmetric, geometry, r_max, cell_factor, nthreads)
    fits = {}
    for name in tqdm(names, desc="alternatives", disable=not progress):
        with blas_threads(1):  # L-BFGS-B's tiny products: 6 ms a step with spinning threads
            fit = (_fit_geometry(prob, axisymmetric) if name == "geometry"
                   else _fit_field(name, prob, n_starts, max_iter))
        log.info("alternative %s: delta chi2 = %.1f (%d evaluations, %.2f s)", name, fit.delta_chi2,
                 fit.n_evaluations, fit.time_s)
        fits[name] = fit
    prov = provenance_record(data_hash=data_hash(vis.u, vis.v, vis.V, vis.weights), n_starts=n_starts,
                             cell_factor=cell_factor, fit_time_s=time.perf_counter() - t0)
    return AlternativesResult(fits, int(vis.n), prob.chi2_AO, geometry, prob.grid, prov)


def delta_chi2_direct(result: AlternativesResult, name: str, vis, axisymmetric) -> float:
    """Δχ² of a fitted alternative with its visibilities from direct sums (the reference; slow)."""
    vis = vis.standardised()
    fit = result.fits[name]
    V_A = axisymmetric.visibilities(vis.u, vis.v, result.geometry)
    if name == "geometry":
        V = axisymmetric.visibilities(vis.u, vis.v, offset_geometry(result.geometry, fit.theta))
    else:
        ctx = ProfileContext.build(axisymmetric.brightness, result.grid)
        P = FIELD_MODELS[name].field(np.asarray(fit.theta), ctx)
        V = V_A + field_visibilities_dft(P, result.grid, vis.u, vis.v, result.geometry)
    return chi2(V_A, vis.V, vis.weights) - chi2(V, vis.V, vis.weights)

