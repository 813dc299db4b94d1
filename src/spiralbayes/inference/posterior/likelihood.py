"""The spiral likelihood with the disc profile and the spiral amplitude integrated out.

Model (Stevenson et al. 2024, sec. 2.2, with a free amplitude ``A``)::

    V(u, v) = cos i · exp(2 pi i (u dRA + v dDec)) · [ H(q) I + A P_hat(q; r_p, phi_p) ]

``H(q) I`` is the axisymmetric disc of frank's Fourier–Bessel profile ``I`` (Jennings et al.
2020) and ``P_hat`` the transform of the spiral perturbation ``I_A delta`` (:mod:`.interpolation`).
``I`` has frank's Gaussian-process prior ``N(0, S)`` (:mod:`spiralbayes.axisymmetric.gp`) and
``A`` a uniform prior on ``[0, A_max]`` (``A = 1`` is the template as simulated, ``A = 0`` the
disc without a planet). Both enter linearly, so both integrate out exactly.

**The profile.** For fixed geometry and planet, the de-phased data ``D = conj(phase) V`` are
linear in ``I``; centring on a reference profile ``I0`` (``R0 = D - cos i H I0``, small) and
completing the square gives the linear-Gaussian marginal likelihood

    -2 ln L(A) = ||R0 - A p||^2_w + I0^T S^-1 I0 - b(A)^T K^-1 b(A) + ln det K + const,
    K = M + S^-1,   b(A) = cos i H^T w Re(R0 - A p) - S^-1 I0,   p = cos i P_hat,

(``M`` the normal matrix of frank's fit at this geometry), which is independent of ``I0``
mathematically; centring keeps every term small, so the approximate pieces below only ever
multiply noise-sized numbers. The conditional posterior mean of the profile is ``I0 + K^-1 b``
(:meth:`ProfileMarginal.conditional_profile`): that is frank's fit redone at this geometry
with frank's power spectrum held fixed.

**The spiral term — the stated approximation.** The perturbation is ``I delta``, linear in the
profile too, but its profile is held at ``I0`` (not integrated): the neglected term is
``A · transform(delta (I - I0))``, the spiral's fractional amplitude times the profile's
deviation from ``I0``. The sampler takes ``I0`` = the conditional mean at the geometry that
maximises the no-planet posterior (:func:`.sampler.sample_posterior`), so the deviation is only
the profile's posterior spread plus what the planet itself shifts; ``A`` absorbs any overall
scale. ``tests/inference/test_marginal.py`` measures the neglected term against the exact
linear model (every Fourier–Bessel column of the perturbation computed): with ``I0`` centred at
the evaluated geometry, ``ln L(A) - ln L(0)`` (~70 there) changed by 0.1–0.2 (0.2 %); with
``I0`` from a geometry 2 deg away, by 0.4–0.5.

**The amplitude.** ``ln L(A) = ln L0 + A c1 - A^2 c2 / 2`` exactly (``c2 >= 0``), so
``ln int L(A) dA / A_max`` is a truncated-Gaussian integral (:func:`log_amplitude_integral`), and
``A | rest`` is a truncated Gaussian that the sampler draws exactly for every posterior sample
(:func:`draw_amplitude`): ``A``'s posterior comes from those draws, emcee never meets the edge
at ``A = 0`` where planet-free posteriors pile up, and ``ln L0`` is the no-planet hypothesis.

**Cost** (why ~15–20 ms per call at 1e5 visibilities). Per call: the deprojected baseline lengths
and phases (O(n)); the spiral's visibilities from the Fourier-series tables (one single-precision
type-2 NUFFT, :mod:`.interpolation`); the data spread onto a grid of some hundred points in ``q``
with 4- to 10-point Lagrange weights, whichever costs least for the data
(:class:`~spiralbayes.axisymmetric.gp.QGridProjector`:
frank's deprojected binning made exact — the normal matrix to 4e-10 of its largest element,
measured), which turns the ``n x N^2`` normal matrix into an
``n_grid x N^2`` product; one Cholesky factorisation of the ``N x N`` (N = 200) precision.
``benchmarks/bench_sample.py`` prints the measured split.
:meth:`MarginalSpiralLikelihood.exact_log_likelihood` is the plain NumPy reference (dense ``H`` at
every datum, the exact type-3 perturbation).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ...axisymmetric.gp import ProfilePrior, QGridProjector
from ...exceptions import InputError
from ...geometry import DiscGeometry
from ...units import ARCSEC, TWO_PI

__all__ = ["DEFAULT_AMPLITUDE_MAX", "MarginalSpiralLikelihood", "ProfileMarginal", "draw_amplitude",
           "log_amplitude_integral"]

log = logging.getLogger(__name__)

DEFAULT_AMPLITUDE_MAX = 2.0
"""Upper end of the uniform amplitude prior: the template's contrast is trusted to a factor ~2."""


# ---------------------------------------------------------------------------------------------
# the amplitude integral
# ---------------------------------------------------------------------------------------------
def _log_diff_ndtr(a, b):
    """``ln(Phi(b) - Phi(a))`` for ``a < b``, accurate in both tails."""
    from scipy.special import log_ndtr

    a, b = np.asarray(a, float), np.asarray(b, float)
    flip = a > 0  # use the upper tail: Phi(b) - Phi(a) = Phi(-a) - Phi(-b)
    lo = np.where(flip, -b, a)
    hi = np.where(flip, -a, b)
    lhi, llo = log_ndtr(hi), log_ndtr(lo)
    with np.errstate(divide="ignore", invalid="ignore"):
        return lhi + np.log1p(-np.exp(np.minimum(llo - lhi, 0.0)))


def _log_mean_exp_linear(x):
    """``ln((e^x - 1) / x)``: the mean of ``exp(x t)`` over ``t`` in [0, 1], stable for all x."""
    x = np.asarray(x, float)
    ax = np.maximum(np.abs(x), 1e-300)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        val = np.log(-np.expm1(-ax)) - np.log(ax) + np.maximum(x, 0.0)
    return np.where(np.abs(x) < 1e-8, 0.5 * x, val)


def log_amplitude_integral(c1, c2, a_max: float):
    """``ln (1/a_max) int_0^a_max exp(A c1 - A^2 c2 / 2) dA`` (elementwise; c2 >= 0).

    For ``c2 -> 0`` the integrand is ``exp(A c1)``; tiny ``c2`` (no spiral signal at all) is
    handled by that limit.
    """
    c1 = np.asarray(c1, float)
    c2 = np.maximum(np.asarray(c2, float), 0.0)
    out = np.empty(np.broadcast(c1, c2).shape)
    c1, c2 = np.broadcast_arrays(c1, c2)
    small = c2 * a_max ** 2 < 1e-6  # then exp(-A^2 c2 / 2) = 1 to < 5e-7 over the prior
    if np.any(small):
        out[small] = _log_mean_exp_linear(c1[small] * a_max)
    big = ~small
    if np.any(big):
        s = 1.0 / np.sqrt(c2[big])
        m = c1[big] / c2[big]
        logz = _log_diff_ndtr(-m / s, (a_max - m) / s)
        out[big] = 0.5 * c1[big] * m + np.log(s * np.sqrt(TWO_PI) / a_max) + logz
    return out if out.ndim else float(out)


def draw_amplitude(c1, c2, a_max: float, rng) -> np.ndarray:
    """Exact draws of ``A`` from ``exp(A c1 - A^2 c2 / 2)`` on ``[0, a_max]`` (one per element).

    Inverse-CDF sampling of the truncated Gaussian in log space (``log_ndtr``/``ndtri_exp``), on
    the tail that keeps precision, so that posteriors piled against ``A = 0`` or ``a_max`` are
    drawn correctly too.
    """
    from scipy.special import log_ndtr, ndtri_exp

    c1 = np.atleast_1d(np.asarray(c1, float))
    c2 = np.maximum(np.atleast_1d(np.asarray(c2, float)), 0.0)
    u = rng.uniform(size=c1.size)
    out = np.empty(c1.size)
    flat = c2 * a_max ** 2 < 1e-6  # density ~ exp(c1 A): invert its CDF directly
    if np.any(flat):
        k = c1[flat] * a_max
        uf = u[flat]
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            t = np.where(k > 0, 1.0 + np.log(uf + (1 - uf) * np.exp(-k)) / k, np.log1p(uf * np.expm1(k)) / k)
        out[flat] = a_max * np.where(np.abs(k) < 1e-8, uf, t)
    rest = ~flat
    s = 1.0 / np.sqrt(np.where(rest, c2, 1.0))
    m = np.where(rest, c1, 0.0) * s * s
    a, b = (0.0 - m) / s, (a_max - m) / s
    z = np.empty(c1.size)
    low = rest & (a <= 0)  # the mean lies above the lower bound: invert the lower CDF
    if np.any(low):
        la, lb = log_ndtr(a[low]), log_ndtr(b[low])
        z[low] = ndtri_exp(lb + np.log(u[low] + (1 - u[low]) * np.exp(la - lb)))
    high = rest & (a > 0)  # both bounds above the mean: invert the upper tail
    if np.any(high):
        la, lb = log_ndtr(-a[high]), log_ndtr(-b[high])
        z[high] = -ndtri_exp(la + np.log1p(u[high] * np.expm1(lb - la)))
    out[rest] = m[rest] + s[rest] * z[rest]
    A = np.clip(out, 0.0, a_max)
    return np.where(np.isfinite(A), A, rng.uniform(0.0, a_max, size=c1.size))


# ---------------------------------------------------------------------------------------------
# the axisymmetric (no-planet) part
# ---------------------------------------------------------------------------------------------
@dataclass
class GeometryTerms:
    """Everything one geometry contributes; reused by the spiral term (see the module docs)."""

    cos_inc: float
    first: np.ndarray
    weights: np.ndarray
    residual: np.ndarray  # R0 = conj(phase) V - cos i H I0, complex
    factor: tuple  # Cholesky factor of K (scipy cho_factor)
    b0: np.ndarray
    Kinv_b0: np.ndarray
    log_like: float  # ln L0 relative to the reference


class ProfileMarginal:
    """The no-planet likelihood with frank's profile integrated out, for any geometry.

    Parameters
    ----------
    vis : Visibilities
    axisymmetric : AxisymmetricModel
        Its profile is the centring profile ``I0`` (its geometry is not used).
    prior : ProfilePrior, optional
        Default :meth:`.ProfilePrior.from_model` (frank's power spectrum).
    reference_geometry : DiscGeometry, optional
        ``ln L`` is reported relative to its value there (default: the model's geometry).
    tolerance, order : float, int
        Accuracy and stencil of the ``q`` grid (:class:`QGridProjector`; ``order`` None: the
        cheapest for these data, :meth:`QGridProjector.cheapest_order`).
    ln_ref : float, optional
        Use this constant instead (so that re-centred copies report the same numbers).
    projector : QGridProjector, optional
        Reuse a q grid built for the same prior and baselines.
    """

    def __init__(self, vis, axisymmetric, *, prior: ProfilePrior | None = None,
                 reference_geometry: DiscGeometry | None = None, tolerance: float = 1e-7, order: int | None = None,
                 ln_ref: float | None = None, projector: QGridProjector | None = None):
        vis = vis.standardised()
        self.axisymmetric = axisymmetric
        self.prior = prior or ProfilePrior.from_model(axisymmetric)
        if self.prior.N != axisymmetric.N or not np.isclose(self.prior.Rmax, axisymmetric.Rmax):
            raise InputError(f"the profile prior (N = {self.prior.N}, Rmax = {self.prior.Rmax}) does not match the "
                             f"axisymmetric model (N = {axisymmetric.N}, Rmax = {axisymmetric.Rmax})")
        self.u, self.v = vis.u.copy(), vis.v.copy()
        self.weights = vis.weights.copy()
        self.V = vis.V.copy()
        self._Vr, self._Vi = self.V.real.copy(), self.V.imag.copy()
        self.n = vis.n
        self.uv_max = float(np.max(np.hypot(self.u, self.v)))
        self.projector = projector or QGridProjector.build(self.prior, self.uv_max, tolerance=tolerance, order=order,
                                                           n_data=self.n)
        self.I0 = np.asarray(axisymmetric.I, dtype=float)
        self._curve0 = self.projector.H @ self.I0  # face-on V_A at the grid nodes
        self._Sinv = self.prior.precision
        self._Sinv_I0 = self._Sinv @ self.I0
        self._I0_Sinv_I0 = float(self.I0 @ self._Sinv_I0)
        self.reference_geometry = reference_geometry or axisymmetric.geometry
        self.ln_ref = 0.0
        self.ln_ref = self.raw_terms(self.reference_geometry).log_like if ln_ref is None else float(ln_ref)

    # -- per call ------------------------------------------------------------------------------
    def _deprojected(self, inc, PA):
        ci = np.cos(np.radians(inc))
        pa = np.radians(PA)
        a = self.u * np.cos(pa)
        a -= self.v * np.sin(pa)
        a *= a
        a *= -(1.0 - ci * ci)
        a += self.u * self.u + self.v * self.v
        np.sqrt(a, out=a)
        return ci, a

    def _dephased(self, dRA, dDec):
        """``conj(phase) V``: the data re-centred on ``(dRA, dDec)`` (double precision)."""
        alpha = self.u * (-TWO_PI * dRA * ARCSEC)
        alpha += self.v * (-TWO_PI * dDec * ARCSEC)
        c, s = np.cos(alpha), np.sin(alpha)
        out = np.empty(self.n, dtype=complex)
        out.real = self._Vr * c - self._Vi * s
        out.imag = self._Vr * s + self._Vi * c
        return out

    def raw_terms(self, geometry) -> GeometryTerms:
        """:class:`GeometryTerms` at ``geometry`` (a DiscGeometry or ``(inc, PA, dRA, dDec)``)."""
        from scipy.linalg import cho_solve

        inc, PA, dRA, dDec = _geometry_tuple(geometry)
        ci, q = self._deprojected(inc, PA)
        P = self.projector
        first, W = P.stencil(q)
        R0 = self._dephased(dRA, dDec)
        R0.real -= ci * P.interpolate(first, W, self._curve0)
        w = self.weights
        wr = w * R0.real
        M = P.normal_matrix(P.spread(first, W, w))
        M *= ci * ci
        b0 = ci * P.project(P.spread(first, W, wr)) - self._Sinv_I0
        K = M + self._Sinv
        factor = _cholesky(K)
        Kinv_b0 = cho_solve(factor, b0)
        logdet = 2.0 * float(np.sum(np.log(np.abs(np.diag(factor[0])))))
        chi2 = float(np.dot(wr, R0.real) + np.dot(w * R0.imag, R0.imag))
        log_like = -0.5 * (chi2 + self._I0_Sinv_I0 - float(b0 @ Kinv_b0) + logdet)
        return GeometryTerms(ci, first, W, R0, factor, b0, Kinv_b0, log_like - self.ln_ref)

    def log_likelihood(self, geometry) -> float:
        """``ln L`` of the no-planet hypothesis at ``geometry`` (relative; profile marginalised)."""
        return self.raw_terms(geometry).log_like

    __call__ = log_likelihood

    def conditional_profile(self, geometry):
        """frank's profile refitted at ``geometry`` (posterior mean, power spectrum fixed)."""
        from dataclasses import replace
        from scipy.linalg import cho_solve

        g = _as_geometry(geometry)
        terms = self.raw_terms(g)
        I = self.I0 + terms.Kinv_b0
        err = np.sqrt(np.clip(np.diag(cho_solve(terms.factor, np.eye(self.prior.N))), 0.0, None))
        hyper = {**self.axisymmetric.hyperparameters, "profile": "conditional mean (profile-marginalised likelihood)"}
        return replace(self.axisymmetric, I=I, I_err=err, I_nonneg=None, geometry=g, hyperparameters=hyper,
                       frank_solution=None)

    def centred_at(self, geometry) -> ProfileMarginal:
        """A copy centred on the conditional profile at ``geometry`` (same numbers, smaller terms)."""
        model = self.conditional_profile(geometry)
        other = ProfileMarginal.__new__(ProfileMarginal)
        other.__dict__.update(self.__dict__)
        other.axisymmetric = model
        other.I0 = np.asarray(model.I, dtype=float)
        other._curve0 = other.projector.H @ other.I0
        other._Sinv_I0 = other._Sinv @ other.I0
        other._I0_Sinv_I0 = float(other.I0 @ other._Sinv_I0)
        return other

    # -- reference ---------------------------------------------------------------------------------
    def dense_design(self, geometry) -> tuple[float, np.ndarray, np.ndarray]:
        """``(cos i, H(q_k) (n, N), conj(phase) V)``: the reference's exact pieces (memory n x N)."""
        g = _as_geometry(geometry)
        up, vp = g.deproject_uv(self.u, self.v)
        H = self.prior.coefficients(np.hypot(up, vp))
        return g.cos_inc, H, self.V * np.conj(g.phase_factor(self.u, self.v))

    def exact_log_likelihood(self, geometry, perturbation=None) -> float:
        """Plain NumPy reference of ``ln L`` (dense normal equations, no centring, no grid).

        ``perturbation``: de-phased spiral visibilities ``A p`` to subtract (default none).
        """
        ci, H, D = self.dense_design(geometry)
        if perturbation is not None:
            D = D - perturbation
        w = self.weights
        X = ci * H
        M = X.T @ (w[:, None] * X)
        j = X.T @ (w * D.real)
        K = M + self._Sinv
        sign, logdet = np.linalg.slogdet(K)
        chi2 = float(np.sum(w * np.abs(D) ** 2))
        return -0.5 * (chi2 - float(j @ np.linalg.solve(K, j)) + logdet) - self.ln_ref


def _cholesky(K):
    """Cholesky factor of the (symmetric) precision; a tiny diagonal load if roundoff broke it."""
    from scipy.linalg import LinAlgError, cho_factor

    try:
        return cho_factor(K, lower=False, check_finite=False)
    except LinAlgError:
        jitter = 1e-12 * float(np.max(np.abs(np.diag(K))))
        log.debug("precision matrix not positive definite to roundoff; loading its diagonal by %g", jitter)
        return cho_factor(K + jitter * np.eye(K.shape[0]), lower=False, check_finite=False)


def _geometry_tuple(geometry):
    if isinstance(geometry, DiscGeometry):
        return geometry.inc, geometry.PA, geometry.dRA, geometry.dDec
    inc, PA, dRA, dDec = (float(x) for x in geometry)
    return inc, PA, dRA, dDec


def _as_geometry(geometry) -> DiscGeometry:
    return geometry if isinstance(geometry, DiscGeometry) else DiscGeometry(*_geometry_tuple(geometry))


# ---------------------------------------------------------------------------------------------
# the spiral hypothesis
# ---------------------------------------------------------------------------------------------
class MarginalSpiralLikelihood:
    """``ln L(r_p, phi_p, inc, PA, dRA, dDec)`` with the profile and the amplitude integrated out.

    Parameters
    ----------
    base : ProfileMarginal
        The profile-marginalised disc (shared by all templates; its centring profile is the
        spiral's profile ``I0``).
    perturbation : FastPerturbation
        The spiral's visibilities from tables (:mod:`.interpolation`), built with ``base``'s profile.
    amplitude_max : float
        The uniform amplitude prior ``[0, amplitude_max]``; ``None``: fixed ``A = 1`` (the paper).
    """

    def __init__(self, base: ProfileMarginal, perturbation, *, amplitude_max: float | None = DEFAULT_AMPLITUDE_MAX):
        if amplitude_max is not None and not (np.isfinite(amplitude_max) and amplitude_max > 0):
            raise InputError(f"amplitude_max = {amplitude_max!r} must be positive (or None for A = 1 fixed)")
        self.base = base
        self.perturbation = perturbation
        self.template = perturbation.template
        self.r_range = perturbation.r_range
        self.amplitude_max = None if amplitude_max is None else float(amplitude_max)

    def amplitude_terms(self, theta) -> tuple[float, float, float]:
        """``(ln L0, c1, c2)``: ``ln L(A) = ln L0 + A c1 - A^2 c2 / 2`` at ``theta`` (6 values)."""
        from scipy.linalg import cho_solve

        r_p, _, inc, PA, dRA, dDec = (float(t) for t in theta[:6])
        self.perturbation.check_r_p(r_p)
        if not 0.0 <= inc < 90.0:
            raise InputError(f"inc = {inc} deg is outside [0, 90)")
        g = self.base.raw_terms((inc, PA, dRA, dDec))
        p = self.spiral_visibilities(theta).astype(np.complex128)
        w = self.base.weights
        wp = w * p.real
        j_p = g.cos_inc * self.base.projector.project(self.base.projector.spread(g.first, g.weights, wp))
        Kinv_jp = cho_solve(g.factor, j_p)
        cross = float(np.dot(wp, g.residual.real) + np.dot(w * p.imag, g.residual.imag))
        power = float(np.dot(wp, p.real) + np.dot(w * p.imag, p.imag))
        c1 = cross - float(j_p @ g.Kinv_b0)
        c2 = max(power - float(j_p @ Kinv_jp), 0.0)
        return g.log_like, c1, c2

    def spiral_visibilities(self, theta) -> np.ndarray:
        """``cos i P_hat`` at the data [Jy] for ``theta`` (de-phased; from the tables)."""
        r_p, phi_p, inc, PA = (float(t) for t in theta[:4])
        return self.perturbation.disc_frame(r_p, phi_p, inc, PA)

    def log_likelihood_at(self, theta, amplitude: float) -> float:
        """``ln L`` at a given amplitude ``A`` (``theta``: the six continuous parameters)."""
        l0, c1, c2 = self.amplitude_terms(theta)
        return l0 + amplitude * c1 - 0.5 * amplitude ** 2 * c2

    def marginal(self, terms) -> float:
        l0, c1, c2 = terms
        if self.amplitude_max is None:
            return l0 + c1 - 0.5 * c2
        return l0 + log_amplitude_integral(c1, c2, self.amplitude_max)

    def __call__(self, theta) -> float:
        """``ln L`` with ``A`` integrated over its prior (or at ``A = 1`` when fixed)."""
        return self.marginal(self.amplitude_terms(theta))

    log_likelihood = __call__

    @property
    def quadrature_error(self) -> float:
        """The perturbation quadrature's error bound, ``sqrt(sum w |dV|^2)`` (:class:`.FastPerturbation`)."""
        return self.perturbation.quadrature_error

    def null_log_likelihood(self, geometry) -> float:
        """The no-planet hypothesis at ``geometry`` (same constant as ``__call__``)."""
        return self.base.log_likelihood(geometry)

    def exact_log_likelihood(self, theta, amplitude):
        """Reference at amplitude ``A`` (a number or a sequence): dense normal equations and the exact
        type-3 perturbation of the same quadrature (:func:`spiralbayes.model.perturbation_visibilities`)."""
        from ...model import perturbation_visibilities

        r_p, phi_p = float(theta[0]), float(theta[1])
        g = DiscGeometry(*(float(t) for t in theta[2:6]))
        dV = perturbation_visibilities(self.base.u, self.base.v, g, self.base.axisymmetric.brightness, self.template,
                                       r_p, phi_p, quad=self.perturbation.quadrature(r_p), epsilon=1e-10)
        p = dV * np.conj(g.phase_factor(self.base.u, self.base.v))
        values = [self.base.exact_log_likelihood(g, a * p) for a in np.atleast_1d(amplitude)]
        return values[0] if np.ndim(amplitude) == 0 else np.array(values)

    def describe(self) -> dict:
        return {**self.perturbation.describe(), "amplitude_max": self.amplitude_max,
                "profile_prior": self.base.prior.source, "q_grid_points": int(self.base.projector.n_grid),
                "q_grid_step_lambda": self.base.projector.step, "q_grid_order": self.base.projector.order}
