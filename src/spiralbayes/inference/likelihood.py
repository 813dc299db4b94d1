"""The spiral model's visibility likelihood, fast enough for MCMC.

Parameters (``theta``, in this order, units at the API): planet radius ``r_p`` [arcsec], planet
azimuth ``phi_p`` [rad] (disc azimuth, :mod:`spiralbayes.geometry`), inclination ``inc`` [deg],
position angle ``PA`` [deg], phase-centre offsets ``dRA``, ``dDec`` [arcsec]. The template is
fixed per likelihood object (the sampler treats it as a discrete choice, :mod:`.sampler`).

Model (Stevenson et al. 2024, sec. 2.2)::

    V(u, v) = cos i · exp(2 pi i (u dRA + v dDec)) · [ V_A(|q|) + P_hat(q; r_p, phi_p) ]

with ``q = (xi, eta)`` the baseline in the disc frame (:meth:`DiscGeometry.disc_frame_uv`),
``V_A`` the face-on visibility curve of the axisymmetric profile and ``P_hat`` the transform of
the perturbation ``I_A delta`` on the product-integration rule of :mod:`spiralbayes.quadrature`
(exact to ~1e-11 of its L1 norm; ``SpiralLikelihood.quadrature_error`` reports its bound).

**The axisymmetric profile is held fixed** (the frank fit) while its visibilities are
re-evaluated under each sampled geometry: ``V_A`` is precomputed once, on a fine uniform grid of
deprojected baseline length, from the model's exact (Hankel) visibilities, and interpolated
linearly (grid step chosen so that the interpolation error is below ~1e-7 of the peak;
:meth:`AxisymmetricTable.max_error` measures it against the exact curve). No Hankel transform is
done per call. Re-fitting the profile for each geometry is not done.

The tables and why they are exact: :mod:`spiralbayes.inference.tables`.

:meth:`SpiralLikelihood.exact_log_likelihood` is the reference (type-3 NUFFT of the full
quadrature at double precision plus the exact Hankel visibilities);
:meth:`SpiralLikelihood.naive_log_likelihood` renders images and samples them
(:func:`spiralbayes.fourier.sample_image`), as the authors' galario loop.

``log L`` is returned relative to the axisymmetric model at the reference geometry:
``ln L(theta) = -(chi2(theta) - chi2_ref) / 2``; the constant is the same for every template, so
posterior odds between templates are unaffected.
"""

from __future__ import annotations

import logging
import time
import warnings

import numpy as np

from ..exceptions import AccuracyWarning, InputError
from ..fourier import sample_image
from ..geometry import DiscGeometry
from ..model import (
    DEFAULT_CELL_FACTOR,
    perturbation_visibilities,
    profile_support,
    render_perturbation_image,
)
from ..units import ARCSEC, TWO_PI
from .tables import (
    AxisymmetricTable,
    PerturbationTable,
    _Cells,
    _nodes,
    _outer_radius,
    _TableBuilder,
)

__all__ = ["PARAMETER_LABELS", "PARAMETER_NAMES", "SpiralLikelihood", "geometry_from_theta"]

log = logging.getLogger(__name__)

PARAMETER_NAMES = ("r_p", "phi_p", "inc", "PA", "dRA", "dDec")
"""Order of the continuous parameters."""
PARAMETER_LABELS = (r"$r_p$ [arcsec]", r"$\phi_p$ [rad]", r"$i$ [deg]", r"PA [deg]",
                    r"$\Delta$RA [arcsec]", r"$\Delta$Dec [arcsec]")


def geometry_from_theta(theta) -> DiscGeometry:
    """The :class:`DiscGeometry` of a parameter vector ``(r_p, phi_p, inc, PA, dRA, dDec)``."""
    return DiscGeometry(float(theta[2]), float(theta[3]), float(theta[4]), float(theta[5]))


# ---------------------------------------------------------------------------------------------
class SpiralLikelihood:
    """Gaussian visibility log-likelihood of the spiral model for one template.

    Parameters
    ----------
    vis : Visibilities
        The data (used in the frank/galario convention).
    axisymmetric : AxisymmetricModel
        The axisymmetric model (frank fit): ``brightness(r)`` [Jy/sr] and exact visibilities
        (``visibilities_deprojected`` or ``visibilities``); held fixed.
    template : SpiralTemplate
    r_range : (float, float)
        The planet radii [arcsec] the likelihood must serve (the prior's r_p window).
    reference_geometry : DiscGeometry, optional
        Geometry of the constant ``chi2_ref`` (default: the axisymmetric model's).
    epsilon : float
        Accuracy of the per-call type-2 NUFFT (single precision above 1e-6; double below).
    oversample : float
        Fourier-series oversampling (>= 1.3).
    rp_tolerance : float
        Target of the r_p-node refinement: ``sqrt(sum w |dV|^2)`` of the interpolation error at
        node midpoints (so ``|d ln L|`` is of order ``rp_tolerance``).
    rp_step : float, optional
        Fix the node spacing [arcsec] instead of refining.
    cell_factor : float
        Unused (the product rule needs no cell size); kept for compatibility.

    Attributes
    ----------
    quadrature_error : float
        Bound on the quadrature's error in the norm of ``rp_tolerance``, ``sqrt(sum w |δV|^2)``,
        over the table's radii (``cos i`` times the rule's bound on ``|δΔV|`` times
        ``sqrt(sum w)``); an :class:`~spiralbayes.exceptions.AccuracyWarning` is raised when it
        exceeds ``rp_tolerance``.
    """

    def __init__(self, vis, axisymmetric, template, r_range, *, reference_geometry: DiscGeometry | None = None,
                 epsilon: float = 1e-5, oversample: float = 1.5, rp_tolerance: float = 0.01,
                 rp_step: float | None = None, cell_factor: float = DEFAULT_CELL_FACTOR, progress: bool = False):
        t0 = time.perf_counter()
        vis = vis.standardised()
        r_lo, r_hi = float(r_range[0]), float(r_range[1])
        if not (0 < r_lo < r_hi):
            raise InputError(f"r_range = {r_range!r}: need 0 < r_min < r_max [arcsec]")
        self.template = template
        self.axisymmetric = axisymmetric
        self.profile = axisymmetric.brightness
        self.r_range = (r_lo, r_hi)
        self.epsilon = float(epsilon)
        self.reference_geometry = reference_geometry or getattr(axisymmetric, "geometry", None) or DiscGeometry()
        self.u, self.v = vis.u.copy(), vis.v.copy()
        self.weights = vis.weights.copy()
        self.V = vis.V.copy()
        self._u32, self._v32 = self.u.astype(np.float32), self.v.astype(np.float32)
        self._uv2 = self.u ** 2 + self.v ** 2
        self._sqrt_w = np.sqrt(self.weights)
        self._sqrt_w32 = self._sqrt_w.astype(np.float32)
        self._V_sqrt_w = self.V * self._sqrt_w
        self.uv_max = float(np.max(np.hypot(self.u, self.v)))
        self.axis_table = AxisymmetricTable.build(axisymmetric, self.uv_max)
        r_cells = r_hi + 2.0 * (float(rp_step) if rp_step is not None else (r_hi - r_lo) / 8.0)  # last table node
        self._cells = _Cells.build(template, r_cells, self.uv_max, support=profile_support(self.profile))
        x_max = self._cells.x_max
        self._builder = _TableBuilder(self._cells, self.profile, r_hi * ARCSEC * self.uv_max, x_max, oversample)
        self._delta = self._builder.delta
        self._complex = np.complex64 if self.epsilon >= 1e-6 else np.complex128
        self.table = self._build_table(rp_step, rp_tolerance, progress)
        self.table.build_time_s = time.perf_counter() - t0
        self.quadrature_error = self._quadrature_error(rp_tolerance)
        self.chi2_ref = 0.0
        self.chi2_ref = -2.0 * self.log_likelihood_axisymmetric(self.reference_geometry)
        log.info("likelihood for %s: %d r_p nodes, %d x %d grids, %.1f MB, built in %.1f s",
                 getattr(template, "name", "template"), self.table.r_nodes.size, self.table.N, self.table.N,
                 self.nbytes / 2 ** 20, self.table.build_time_s)

    # -- table ----------------------------------------------------------------------------
    def _build_table(self, rp_step, tol, progress) -> PerturbationTable:
        r_lo, r_hi = self.r_range
        b = self._builder
        span = r_hi - r_lo
        h = float(rp_step) if rp_step is not None else span / 8.0
        cache: dict = {}

        def node(r):
            key = round(r, 12)
            if key not in cache:
                cache[key] = b(r)
            return cache[key]

        history = []
        while True:
            nodes = _nodes(r_lo, r_hi, h)
            grids = np.stack([node(r) for r in nodes])
            table = PerturbationTable(nodes, grids, b.delta, b.sigma_max, self.r_range, refinement=history)
            if rp_step is not None:
                return table
            err = self._midpoint_error(table, node)
            history.append({"step_arcsec": h, "n_nodes": int(nodes.size), "max_midpoint_error": err})
            if progress:
                log.info("r_p step %.4g arcsec: %d nodes, midpoint error %.3g", h, nodes.size, err)
            if err <= tol or h < 1e-4:
                if err > tol:
                    log.warning("r_p nodes refined to %.2g arcsec, error %.3g > tolerance %.3g", h, err, tol)
                return table
            h /= 2.0

    def _quadrature_error(self, tolerance: float) -> float:
        """The rule's bound over the radii the table was built from, as ``sqrt(sum w |δV|^2)``."""
        bound = max(self._cells.bounds.values(), default=0.0)
        error = self.reference_geometry.cos_inc * bound * float(np.sqrt(np.sum(self.weights)))
        if error > tolerance:
            msg = (f"the quadrature's error bound sqrt(sum w |dV|^2) <= {error:.3g} exceeds rp_tolerance = "
                   f"{tolerance:.3g} for {getattr(self.template, 'name', 'the template')}: the profile may jump "
                   "inside the disc (give a smooth one)")
            log.warning(msg)
            warnings.warn(msg, AccuracyWarning, stacklevel=3)
        return error

    def _midpoint_error(self, table: PerturbationTable, node) -> float:
        """Largest data-weighted norm of the r_p-interpolation error at node midpoints."""
        r_lo, r_hi = self.r_range
        mids = 0.5 * (table.r_nodes[1:] + table.r_nodes[:-1])
        mids = mids[(mids >= r_lo) & (mids <= r_hi)]
        worst = 0.0
        g0 = self.reference_geometry
        for r in mids:
            diff = table.grid(r) - node(r)
            scale = g0.cos_inc * (r * ARCSEC) ** 2
            for phi_p in (0.0, 0.5 * np.pi, np.pi, 1.5 * np.pi):
                coord, _ = self._coords(r, phi_p, g0.inc, g0.PA)
                dV = self._u2nu(diff, coord) * scale
                worst = max(worst, float(np.sqrt(np.sum(self.weights * np.abs(dV) ** 2))))
        return worst

    # -- evaluation -----------------------------------------------------------------------------
    # The hot path avoids BLAS (numpy's matmul/vdot call OpenBLAS, which on a loaded machine with
    # several threads was measured 100x slower for these sizes, emcee #199): plain ufuncs only.
    def _matrix(self, r_p, phi_p, inc, PA):
        """``2 pi Delta r_p R(-phi_p) D(inc, PA)``: (u, v) -> ducc0 coordinates, and its scale."""
        ci = np.cos(np.radians(inc))
        cp, sp = np.cos(np.radians(PA)), np.sin(np.radians(PA))
        D = np.array([[-ci * cp, ci * sp], [sp, cp]])  # (u, v) -> (xi, eta)
        c, s = np.cos(phi_p), np.sin(phi_p)
        R = np.array([[c, s], [-s, c]])  # rotation by -phi_p
        k = TWO_PI * self._delta * r_p * ARCSEC
        return k * (R @ D), k

    def _coords(self, r_p, phi_p, inc, PA):
        """ducc0 coordinates ``2 pi Delta sigma`` of the data (n, 2), float32 or float64."""
        L, _ = self._matrix(r_p, phi_p, inc, PA)
        u, v = (self._u32, self._v32) if self._complex is np.complex64 else (self.u, self.v)
        L = L.astype(u.dtype)
        coord = np.empty((u.size, 2), dtype=u.dtype)
        for j in range(2):
            col = coord[:, j]
            np.multiply(u, L[j, 0], out=col)
            col += v * L[j, 1]
        return coord, None

    def _u2nu(self, grid, coord):
        import ducc0

        grid = grid.astype(self._complex, copy=False)
        coord = coord.astype(np.float32 if self._complex is np.complex64 else np.float64, copy=False)
        return ducc0.nufft.u2nu(grid=grid, coord=coord, forward=False, epsilon=self.epsilon, nthreads=1)

    def _check_theta(self, theta):
        r_p, phi_p, inc, PA, dRA, dDec = (float(t) for t in theta)
        r_lo, r_hi = self.r_range
        if not (r_lo <= r_p <= r_hi):
            raise InputError(f"r_p = {r_p} arcsec is outside the likelihood's range {self.r_range}")
        if not (0.0 <= inc < 90.0):
            raise InputError(f"inc = {inc} deg is outside [0, 90)")
        return r_p, phi_p, inc, PA, dRA, dDec

    def model_visibilities(self, theta) -> np.ndarray:
        """Spiral-model visibilities [Jy] at the data's baselines (fast path), complex128."""
        r_p, phi_p, inc, PA, dRA, dDec = self._check_theta(theta)
        M = self._model_disc_frame(r_p, phi_p, inc, PA).astype(complex)
        return M * self._phase(dRA, dDec, scale=None)

    def _model_disc_frame(self, r_p, phi_p, inc, PA):
        """``cos i [V_A(|q|) + P_hat(q)]`` at the data (no phase factor)."""
        ci = np.cos(np.radians(inc))
        coord, _ = self._coords(r_p, phi_p, inc, PA)
        grid = self.table.grid(r_p, scale=ci * (r_p * ARCSEC) ** 2)
        M = self._u2nu(grid, coord)
        # |q|^2 = |uv|^2 - sin^2 i (u cos PA - v sin PA)^2
        pa = np.radians(PA)
        a = self.u * np.cos(pa)
        a -= self.v * np.sin(pa)
        a *= a
        a *= -(1.0 - ci * ci)
        a += self._uv2
        np.sqrt(a, out=a)
        a *= 1.0 / self.axis_table.step
        VA = self.axis_table.from_index(a)
        VA *= ci
        M.real += VA
        return M

    def _phase(self, dRA, dDec, scale):
        """``exp(2 pi i (u dRA + v dDec))`` (times ``scale`` if given), complex64."""
        alpha = self.u * (TWO_PI * dRA * ARCSEC)
        alpha += self.v * (TWO_PI * dDec * ARCSEC)
        alpha -= TWO_PI * np.rint(alpha * (1.0 / TWO_PI))
        a32 = alpha.astype(np.float32)
        phase = np.empty(a32.size, dtype=np.complex64)
        if scale is None:
            phase.real = np.cos(a32)
            phase.imag = np.sin(a32)
        else:
            phase.real = np.cos(a32) * scale
            phase.imag = np.sin(a32) * scale
        return phase

    def __call__(self, theta) -> float:
        """``ln L(theta) = -(chi2(theta) - chi2_ref) / 2`` (fast path)."""
        r_p, phi_p, inc, PA, dRA, dDec = self._check_theta(theta)
        M = self._model_disc_frame(r_p, phi_p, inc, PA)
        M *= self._phase(dRA, dDec, scale=self._sqrt_w32)
        resid = M - self._V_sqrt_w  # complex128
        flat = resid.view(np.float64)
        return -0.5 * (float(np.einsum("i,i->", flat, flat)) - self.chi2_ref)

    log_likelihood = __call__

    def log_likelihood_axisymmetric(self, geometry: DiscGeometry) -> float:
        """``-(chi2_AO - chi2_ref) / 2`` of the axisymmetric model alone under ``geometry``."""
        up, vp = geometry.deproject_uv(self.u, self.v)
        V = geometry.cos_inc * self.axis_table(np.hypot(up, vp)) * geometry.phase_factor(self.u, self.v)
        return -0.5 * (float(np.sum(self.weights * np.abs(V - self.V) ** 2)) - self.chi2_ref)

    # -- references ---------------------------------------------------------------------------------
    def exact_model_visibilities(self, theta) -> np.ndarray:
        """The same model by the exact path: Hankel ``V_A`` plus the type-3 NUFFT of the quadrature."""
        r_p, phi_p = float(theta[0]), float(theta[1])
        geometry = geometry_from_theta(theta)
        V_A = self.axisymmetric.visibilities(self.u, self.v, geometry)
        dV = perturbation_visibilities(self.u, self.v, geometry, self.profile, self.template, r_p, phi_p,
                                       quad=self._cells.quadrature(r_p), epsilon=1e-10)
        return V_A + dV

    def exact_log_likelihood(self, theta) -> float:
        """Reference ``ln L`` from :meth:`exact_model_visibilities` (same constant)."""
        V = self.exact_model_visibilities(theta)
        return -0.5 * (float(np.sum(self.weights * np.abs(V - self.V) ** 2)) - self.chi2_ref)

    def naive_log_likelihood(self, theta, *, pixel_size: float | None = None, shape: int | None = None) -> float:
        """``ln L`` by rendering the perturbation and disc images and sampling them with a NUFFT.

        The path the issue compares against (the authors' loop): default pixels of
        ``1 / (4 u_max)`` and a field of view of ``2.2 Rmax``.
        """
        r_p, phi_p = float(theta[0]), float(theta[1])
        geometry = geometry_from_theta(theta)
        pixel_size = pixel_size or 1.0 / (4.0 * self.uv_max) / ARCSEC
        if shape is None:
            shape = int(np.ceil(2.2 * _outer_radius(self.axisymmetric) / pixel_size / 2)) * 2
        image = render_perturbation_image(self.profile, self.template, r_p, phi_p, geometry.inc, (shape, shape),
                                          pixel_size)
        image += self.axisymmetric.image((shape, shape), pixel_size, geometry)
        V = sample_image(image, pixel_size, self.u, self.v, geometry, epsilon=1e-7)
        return -0.5 * (float(np.sum(self.weights * np.abs(V - self.V) ** 2)) - self.chi2_ref)

    # -- bookkeeping -------------------------------------------------------------------------------
    @property
    def nbytes(self) -> int:
        """Memory of the precomputed tables [bytes]."""
        return self.table.nbytes + self.axis_table.nbytes

    def describe(self) -> dict:
        """JSON-able summary of the tables (for provenance and logs)."""
        return {
            "template": getattr(self.template, "name", ""),
            "r_range_arcsec": list(self.r_range),
            "n_rp_nodes": int(self.table.r_nodes.size),
            "rp_step_arcsec": self.table.step,
            "grid_N": int(self.table.N),
            "pseudo_pixel": self.table.delta,
            "sigma_max": self.table.sigma_max,
            "epsilon": self.epsilon,
            "axisymmetric_step_lambda": self.axis_table.step,
            "table_bytes": int(self.nbytes),
            "build_time_s": self.table.build_time_s,
            "refinement": self.table.refinement,
            "n_cells": int(self._cells.positions.shape[0]),
            "quadrature_error": float(getattr(self, "quadrature_error", float("nan"))),
        }

    def __getstate__(self):
        state = self.__dict__.copy()
        state.pop("_builder", None)  # large, only needed to build
        return state
