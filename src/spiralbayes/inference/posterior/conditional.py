"""The spiral model's visibility likelihood, fast enough for MCMC.

Parameters (``theta``, in this order, units at the API): planet radius ``r_p`` [arcsec], planet
azimuth ``phi_p`` [rad] (disc azimuth, :mod:`spiralbayes.geometry`), inclination ``inc`` [deg],
position angle ``PA`` [deg], phase-centre offsets ``dRA``, ``dDec`` [arcsec]. The template is
fixed per likelihood object (the sampler treats it as a discrete choice, :mod:`.sampler`).

Model (Stevenson et al. 2024, sec. 2.2)::

    V(u, v) = cos i · exp(2 pi i (u dRA + v dDec)) · [ V_A(|q|) + P_hat(q; r_p, phi_p) ]

with ``q = (xi, eta)`` the baseline in the disc frame (:meth:`.DiscGeometry.disc_frame_uv`),
``V_A`` the face-on visibility curve of the axisymmetric profile and ``P_hat`` the transform of
the perturbation ``I_A delta`` on the product-integration rule of :mod:`spiralbayes.quadrature`
(exact to ~1e-11 of its L1 norm; :attr:`SpiralLikelihood.quadrature_error` reports its bound).

This is the *conditional* likelihood: **the axisymmetric profile is held fixed** (the frank fit),
exact and fast, and kept as the reference of the fast path. The sampler uses the
profile-marginalised likelihood of :mod:`spiralbayes.inference.posterior.likelihood`, which integrates the
profile (and a free spiral amplitude) out. Here the profile's visibilities are
re-evaluated under each sampled geometry: ``V_A`` is precomputed once, on a fine uniform grid of
deprojected baseline length, from the model's exact (Hankel) visibilities, and interpolated
linearly (grid step chosen so that the interpolation error is below ~1e-7 of the peak;
:meth:`.AxisymmetricTable.max_error` measures it against the exact curve). No Hankel transform is
done per call. Re-fitting the profile for each geometry is not done.

The tables and why they are exact: :mod:`spiralbayes.inference.posterior.interpolation`.

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

import numpy as np

from ...exceptions import InputError
from ...fourier import sample_image
from ...geometry import DiscGeometry
from ...model import (
    DEFAULT_CELL_FACTOR,
    perturbation_visibilities,
    render_perturbation_image,
)
from ...units import ARCSEC, TWO_PI
from .perturbation import FastPerturbation
from .interpolation import AxisymmetricTable, _outer_radius

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
    progress : bool
        Show a progress bar of the table's node builds (each refinement round is logged).
    mirror_of : SpiralLikelihood, optional
        The likelihood of this template's mirror image on the same data and r_p range: its
        tables are shared (see :mod:`spiralbayes.inference.posterior.interpolation`), nothing is built.
    """

    perturbation: FastPerturbation  # declared because a mirror reads its partner's (``mirror_of``) while building

    def __init__(self, vis, axisymmetric, template, r_range, *, reference_geometry: DiscGeometry | None = None,
                 epsilon: float = 1e-5, oversample: float = 1.5, rp_tolerance: float = 0.01,
                 rp_step: float | None = None, cell_factor: float = DEFAULT_CELL_FACTOR, progress: bool = False,
                 mirror_of: SpiralLikelihood | None = None):
        vis = vis.standardised()
        self.template = template
        self.axisymmetric = axisymmetric
        self.profile = axisymmetric.brightness
        self.epsilon = float(epsilon)
        self.reference_geometry = reference_geometry or getattr(axisymmetric, "geometry", None) or DiscGeometry()
        self.u, self.v = vis.u.copy(), vis.v.copy()
        self.weights = vis.weights.copy()
        self.V = vis.V.copy()
        self._uv2 = self.u ** 2 + self.v ** 2
        self._sqrt_w = np.sqrt(self.weights)
        self._sqrt_w32 = self._sqrt_w.astype(np.float32)
        self._V_sqrt_w = self.V * self._sqrt_w
        self.uv_max = float(np.max(np.hypot(self.u, self.v)))
        self.axis_table = AxisymmetricTable.build(axisymmetric, self.uv_max)
        self.perturbation = FastPerturbation(
            self.u, self.v, self.weights, self.profile, template, r_range, self.reference_geometry, epsilon=epsilon,
            oversample=oversample, rp_tolerance=rp_tolerance, rp_step=rp_step, cell_factor=cell_factor,
            progress=progress, mirror_of=None if mirror_of is None else mirror_of.perturbation)
        self.r_range = self.perturbation.r_range
        self.chi2_ref = 0.0
        self.chi2_ref = -2.0 * self.log_likelihood_axisymmetric(self.reference_geometry)
        log.info("likelihood for %s: %d r_p nodes, %d x %d grids, %.1f MB, built in %.1f s",
                 getattr(template, "name", "template"), self.table.r_nodes.size, self.table.N, self.table.N,
                 self.nbytes / 2 ** 20, self.perturbation.build_time_s)

    @property
    def table(self):
        """The perturbation's :class:`~spiralbayes.inference.posterior.interpolation.PerturbationTable`."""
        return self.perturbation.table

    @property
    def _cells(self):
        return self.perturbation._cells

    @property
    def quadrature_error(self) -> float:
        """Bound on the quadrature's error in the norm of ``rp_tolerance``, ``sqrt(sum w |dV|^2)``,
        over the table's radii; an :class:`~spiralbayes.exceptions.AccuracyWarning` was raised at
        build time if it exceeds ``rp_tolerance``."""
        return self.perturbation.quadrature_error

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
        M = self.perturbation.disc_frame(r_p, phi_p, inc, PA)
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
                                       quad=self.perturbation.quadrature(r_p), epsilon=1e-10)
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
        """Memory of the precomputed tables [bytes] (a mirror template shares its partner's)."""
        return self.perturbation.nbytes + self.axis_table.nbytes

    def describe(self) -> dict:
        """JSON-able summary of the tables (for provenance and logs)."""
        return {**self.perturbation.describe(), "axisymmetric_step_lambda": self.axis_table.step,
                "table_bytes": int(self.nbytes)}
