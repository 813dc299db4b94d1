"""Precomputed tables that make the spiral likelihood fast enough for MCMC.

Fast perturbation (why it is exact to ~1e-6 and costs one small type-2 NUFFT per call)
---------------------------------------------------------------------------------------
In the scaled baseline ``sigma = r_p R(-phi_p) q`` (``r_p`` in radians, dimensionless),

    P_hat = r_p^2 T(sigma; r_p),   T(sigma; r_p) = sum_c delta_c I_A(r_p x_c) a_c exp(2 pi i sigma . x_c)

where ``x_c`` are the nodes of the product-integration rule in units of ``r_p``
(:mod:`spiralbayes.quadrature`; one set of nodes serves every ``r_p`` up to the largest table node)
and ``delta_c a_c I_A(r_p x_c)`` stands for their weights, the exact integrals of template and
profile against the rule's basis. So moving the planet in azimuth is a rotation and changing ``r_p`` a
scaling of the *points*, and ``T`` depends on ``r_p`` only through the profile in those
integrals — smooth, so ``T`` is tabulated at a few ``r_p`` nodes and interpolated (Lagrange, 6
nodes by default) between them. ``T`` is only needed for ``|sigma| <= sigma_max = r_p,max u_max``, where
it is multiplied by a smooth radial window ``W`` (1 to 1e-8 inside ``sigma_max``), so that
``T W`` has a rapidly converging Fourier series on a small uniform grid of "pseudo-pixels" ``x_k``
(spacing ``Delta = 1 / (2 oversample sigma_max)``, ``N ~ 100-200`` per side):
``T(sigma) = sum_k g_k exp(2 pi i sigma . x_k)``. The coefficients ``g_k`` of each node come from
one type-1 NUFFT of the quadrature (ducc0 ``nu2u``, single precision, ``epsilon = 1e-6``) and one
FFT; each likelihood call combines four node grids and evaluates the series at the data with one
type-2 NUFFT (ducc0 ``u2nu``, single precision, ``epsilon = 1e-5``) — about 3-4 ms for 1e5
visibilities, against 10-90 ms for the direct type-3 transform of the ~2e5-1e6 quadrature cells.
Node spacing in ``r_p`` is refined until the interpolation error at the midpoints between nodes changes
``chi2`` by less than ``rp_tolerance`` (data-weighted norm ``sqrt(sum w |dV|^2)``).

Cheap nodes: the rule's rings carry only the azimuths the baselines need
-------------------------------------------------------------------------
The product rule gives each ring the smallest multiple of the scan's azimuth count whose
angular Bessel tail at the longest baseline is below 1e-12 (:func:`spiralbayes.quadrature.angular_count`),
so the type-1 NUFFT of a node sees some 10^4-10^5 points instead of the midpoint rule's millions
(595 rings x 5760 azimuths for the fiducial data); the earlier per-ring band-limiting of the
midpoint cells is not needed.

Mirror templates share tables: ``delta_L(x, phi) = delta_R(x, -phi)`` and the quadrature is
symmetric under ``phi -> -phi``, so ``T_L(sigma_xi, sigma_eta) = T_R(sigma_xi, -sigma_eta)``;
:class:`~spiralbayes.inference.posterior.perturbation.FastPerturbation` built with ``mirror_of`` flips the sign of one
coordinate instead of building a table (checked in the tests against a table of its own).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg.blas import sgemv

from ...exceptions import InputError
from ...geometry import DiscGeometry
from ...model import make_quadrature
from ...quadrature import TemplateSpectrum
from ...units import ARCSEC, TWO_PI

__all__ = ["AxisymmetricTable", "PerturbationTable"]

WINDOW_STEEPNESS = 8.0  # erfc(4) / 2 = 8e-9: the window's departure from 1 inside sigma_max
WINDOW_MARGIN = 9.0  # Fourier-series x-range margin, in units of 1 / (window transition width)
BUILD_EPSILON = 1e-6  # the tables' type-1 NUFFT (single precision; _TableBuilder says why)


# ---------------------------------------------------------------------------------------------
def _face_on_curve(axisymmetric, q: np.ndarray) -> np.ndarray:
    """Face-on visibilities ``V_A(q)`` [Jy] (real) of the axisymmetric model."""
    if hasattr(axisymmetric, "visibilities_deprojected"):
        return np.asarray(axisymmetric.visibilities_deprojected(q, projected=False), dtype=float)
    V = axisymmetric.visibilities(q, np.zeros_like(q), DiscGeometry())
    return np.asarray(V, dtype=complex).real


def _outer_radius(axisymmetric) -> float:
    """Radius [arcsec] beyond which the profile is zero (frank's Rmax), or a safe estimate."""
    r_max = getattr(axisymmetric, "Rmax", None)
    if r_max is not None:
        return float(r_max)
    r_eff = getattr(axisymmetric, "R_eff", None)
    if r_eff is not None:
        return 2.0 * float(r_eff() if callable(r_eff) else r_eff)
    raise InputError("the axisymmetric model needs an Rmax [arcsec] or an R_eff() to size its tables")


@dataclass
class AxisymmetricTable:
    """Face-on visibility curve ``V_A(q)`` [Jy] on a uniform grid, interpolated linearly.

    Attributes
    ----------
    step : float
        Grid step [lambda].
    values : ndarray
        ``V_A(j step)``, j = 0 .. n.
    slopes : ndarray
        ``values[j + 1] - values[j]`` (the last repeated).
    """

    step: float
    values: np.ndarray
    slopes: np.ndarray

    @classmethod
    def build(cls, axisymmetric, q_max: float, *, relative_error: float = 1e-7,
              max_nodes: int = 2 ** 21) -> AxisymmetricTable:
        """Tabulate up to ``q_max`` [lambda] with linear-interpolation error ~``relative_error``.

        The curve of a profile of radius ``R`` oscillates at most like ``cos(2 pi q R)``, whose
        linear interpolation errs by ``(2 pi R h)^2 / 8``; ``h`` follows.
        """
        radius = _outer_radius(axisymmetric) * ARCSEC
        step = np.sqrt(8 * relative_error) / (TWO_PI * radius)
        n = int(np.ceil(q_max * 1.001 / step)) + 2
        if n > max_nodes:
            step = q_max * 1.001 / (max_nodes - 2)
            n = max_nodes
        values = _face_on_curve(axisymmetric, step * np.arange(n))
        slopes = np.append(np.diff(values), 0.0)
        return cls(float(step), values, slopes)

    @property
    def q_max(self) -> float:
        return self.step * (self.values.size - 2)

    def __call__(self, q) -> np.ndarray:
        """``V_A(q)`` [Jy] at deprojected baseline lengths ``q`` [lambda] (0 <= q <= q_max)."""
        return self.from_index(np.asarray(q, dtype=float) / self.step)

    def from_index(self, f) -> np.ndarray:
        """``V_A`` at fractional grid positions ``f = q / step`` (the hot path)."""
        i = f.astype(np.intp)
        t = f - i
        return np.take(self.values, i) + t * np.take(self.slopes, i)

    def max_error(self, axisymmetric, n: int = 20000, seed: int = 0) -> float:
        """Largest ``|table - exact|`` at ``n`` random q, relative to the peak ``|V_A|``."""
        q = np.random.default_rng(seed).uniform(0, self.q_max, n)
        exact = _face_on_curve(axisymmetric, q)
        return float(np.max(np.abs(self(q) - exact)) / np.max(np.abs(self.values)))

    @property
    def nbytes(self) -> int:
        return self.values.nbytes + self.slopes.nbytes


# ---------------------------------------------------------------------------------------------
# perturbation: Fourier-series grids of T(sigma; r_p) at r_p nodes
# ---------------------------------------------------------------------------------------------
class _Cells:
    """The template on the product-integration rule (:mod:`spiralbayes.quadrature`), in units of r_p.

    One set of nodes in ``x = r / r_p`` serves every ``r_p <= r_max`` (the rule stays exact as the
    radius shrinks); the exact integrals of template and profile are redone per ``r_p``. Each call
    of :meth:`fluxes` records the rule's error bound [Jy, face on] at that radius in ``bounds``
    (the likelihood reports the largest).
    """

    def __init__(self, template, r_max: float, uv_max: float, support: float | None = None, breaks=(),
                 radial_cache: dict | None = None):
        import hashlib

        self.template = template
        self.support = support  # cut per radius; the nodes cover the whole template (ProductQuadrature.at)
        self.quad = make_quadrature(template, r_max, uv_max, breaks=breaks)
        # the rule and its radial integrals depend on the template's radial grid, not on its values, so
        # templates on one grid (a family's mass nodes) can share them radius by radius
        self.radial_cache = radial_cache
        grid = hashlib.sha1(np.ascontiguousarray(self.quad.x_template, dtype=float).tobytes()).hexdigest()
        self._rule_key = (grid, float(r_max), float(uv_max), support, tuple(breaks))
        self.spectrum = TemplateSpectrum(template)
        self.positions = self.quad.positions_x()  # (n_nodes, 2), units of r_p
        self.x_max = self.quad.extent  # nodes may lie a little beyond the template (sinc basis)
        self.bounds: dict[float, float] = {}

    @classmethod
    def build(cls, template, r_max: float, uv_max: float, cell_factor: float | None = None,
              support: float | None = None, breaks=(), radial_cache: dict | None = None) -> _Cells:
        """``cell_factor`` is accepted for compatibility and unused (the product rule needs none);
        ``radial_cache`` (a dict) shares each radius's rule and radial integrals with other templates on
        the same radial grid and profile."""
        return cls(template, r_max, uv_max, support, breaks, radial_cache)

    def __getstate__(self):
        state = self.__dict__.copy()
        state["radial_cache"] = None  # shared with other tables; a copy in another process starts its own
        return state

    def fluxes(self, profile, r_p: float) -> np.ndarray:
        """T's point weights (units of r_p^2 x Jy/sr), complex, in node order."""
        quad = self.quadrature(r_p)
        self.bounds[float(r_p)] = quad.error_bound(profile, self.spectrum)["total"]
        return quad.weights(profile, self.spectrum).astype(complex)

    def quadrature(self, r_p: float):
        r_p = max(float(r_p), 0.0)
        if self.radial_cache is None:
            return self.quad.at(r_p, support=self.support)
        key = (self._rule_key, r_p)
        quad = self.radial_cache.get(key)
        if quad is None:
            quad = self.radial_cache[key] = self.quad.at(r_p, support=self.support)
        return quad


@dataclass
class PerturbationTable:
    """``T(sigma; r_p)`` as Fourier-series grids at uniform ``r_p`` nodes (see the module docs).

    Attributes
    ----------
    r_nodes : ndarray
        Node radii [arcsec], uniform.
    grids : ndarray of complex64, shape (n_nodes, N, N)
        Fourier coefficients ``g_k`` of ``W T`` at each node (pseudo-pixel ``k`` at
        ``x_k = (k - N/2) Delta``).
    delta : float
        Pseudo-pixel spacing ``Delta`` (units of r_p).
    sigma_max : float
        Largest scaled baseline represented (``r_p,max u_max``, r_p in radians).
    r_range : (float, float)
        The r_p window [arcsec] the table serves.
    order : int
        Nodes of the Lagrange interpolation in r_p (4: cubic; 6: the likelihood's default, whose
        error falls like ``h^6`` and so needs fewer nodes — and less memory — for the same accuracy).
    """

    r_nodes: np.ndarray
    grids: np.ndarray
    delta: float
    sigma_max: float
    r_range: tuple
    build_time_s: float = 0.0
    refinement: list = field(default_factory=list)
    order: int = 4

    @property
    def N(self) -> int:
        return self.grids.shape[-1]

    @property
    def nbytes(self) -> int:
        return int(self.grids.nbytes)

    @property
    def step(self) -> float:
        return float(self.r_nodes[1] - self.r_nodes[0])

    def stencil(self, r_p: float) -> tuple[int, np.ndarray]:
        """First node index and the ``order`` Lagrange weights for ``r_p``."""
        p = self.order
        h = self.step
        f = (r_p - self.r_nodes[0]) / h
        i0 = int(np.clip(np.floor(f) - (p // 2 - 1), 0, self.r_nodes.size - p))
        t = f - i0  # position in units of h relative to node i0 (central interval away from edges)
        nodes = np.arange(float(p))
        w = np.ones(p)
        for j in range(p):
            for m in range(p):
                if m != j:
                    w[j] *= (t - nodes[m]) / (nodes[j] - nodes[m])
        return i0, w

    def grid(self, r_p: float, scale: float = 1.0, out: np.ndarray | None = None) -> np.ndarray:
        """Interpolated coefficients at ``r_p`` [arcsec], times ``scale`` (complex64), added into ``out``
        when given (a C-contiguous complex64 ``(N, N)`` array; it is returned).

        The stencil's grids are consecutive in memory, so the weighted sum is one matrix-vector
        product over them read as float32 (a single pass over the grids; :meth:`grid_reference` is
        the plain sum). Adding into ``out`` lets a family sum its mass nodes without a temporary
        grid per node."""
        if out is not None and (out.dtype != np.complex64 or not out.flags.c_contiguous
                                or out.shape != self.grids.shape[1:]):
            raise InputError(f"out must be a C-contiguous complex64 array of shape {self.grids.shape[1:]}")
        i0, w = self.stencil(r_p)
        w = (w * scale).astype(np.float32)
        block = self.grids[i0:i0 + self.order]
        if block.dtype != np.complex64 or not block.flags.c_contiguous:
            g = self.grid_reference(r_p, scale)
            if out is None:
                return g
            out += g
            return out
        a = block.view(np.float32).reshape(self.order, -1)
        if out is None:
            return (w @ a).view(np.complex64).reshape(block.shape[1:])
        y = out.reshape(-1).view(np.float32)
        summed = sgemv(1.0, a.T, w, beta=1.0, y=y, overwrite_y=True)  # y += a.T @ w, in place
        if not np.shares_memory(summed, y):
            y[:] = summed
        return out

    def grid_reference(self, r_p: float, scale: float = 1.0) -> np.ndarray:
        """:meth:`grid` as the stencil's weighted sum, grid by grid."""
        i0, w = self.stencil(r_p)
        w = (w * scale).astype(np.float32)
        g = self.grids[i0] * w[0]
        for j in range(1, self.order):
            g += self.grids[i0 + j] * w[j]
        return g


def _window(N: int, delta: float, sigma_max: float) -> np.ndarray:
    """The radial window on the sigma grid ``(j - N/2) / (N delta)``."""
    from scipy.special import erfc

    s1 = 1.02 * sigma_max
    s2 = 0.98 / (2 * delta)
    j = (np.arange(N) - N // 2) / (N * delta)
    s = np.hypot(j[:, None], j[None, :])
    return 0.5 * erfc(WINDOW_STEEPNESS * ((s - s1) / (s2 - s1) - 0.5))


class _TableBuilder:
    """Computes node grids ``g(r_p)``: type-1 NUFFT of the rule's nodes, window, FFT.

    Both transforms run in single precision (:data:`BUILD_EPSILON`): the grids are stored as complex64
    and each likelihood call evaluates them with a single-precision type-2 NUFFT at ``epsilon = 1e-5``,
    so the build's error (6e-7 in L2 over a grid against a double-precision ``1e-9`` build on the
    demo observation; requested 1e-6) stays a tenth of what the call is allowed, at half the cost.
    """

    def __init__(self, cells: _Cells, profile, sigma_max: float, x_max: float, oversample: float):
        self.cells = cells
        self.profile = profile
        self.sigma_max = float(sigma_max)
        self.delta = 1.0 / (2.0 * oversample * self.sigma_max)
        transition = 0.98 / (2 * self.delta) - 1.02 * self.sigma_max
        half = x_max + WINDOW_MARGIN / transition
        self.N = int(np.ceil(half / self.delta)) * 2
        self.window = _window(self.N, self.delta, self.sigma_max)
        self.coord = np.ascontiguousarray(TWO_PI * cells.positions / (self.N * self.delta))
        self._coord32 = self.coord.astype(np.float32)
        # N is even, so fftshift(fft2(ifftshift(X))) = s fft2(s X) with s = (-1)^(j+k): the shifts become
        # sign flips folded into the window and the normalisation
        j = np.arange(self.N)
        sign = np.where((j[:, None] + j[None, :]) % 2, -1.0, 1.0)
        self._taper = (self.window * sign).astype(np.float32)
        self._unshift = (sign / self.N ** 2).astype(np.float32)

    def __call__(self, r_p: float) -> np.ndarray:
        import ducc0

        N = self.N
        T = ducc0.nufft.nu2u(points=self.cells.fluxes(self.profile, r_p).astype(np.complex64), coord=self._coord32,
                             out=np.empty((N, N), dtype=np.complex64), forward=False, epsilon=BUILD_EPSILON,
                             nthreads=1)
        T *= self._taper
        g = ducc0.fft.c2c(T, forward=True, out=T, nthreads=1)
        g *= self._unshift
        return g

    def reference(self, r_p: float) -> np.ndarray:
        """:meth:`__call__` in double precision (type-1 NUFFT at ``epsilon = 1e-9``, NumPy's FFT with
        explicit shifts), rounded to complex64."""
        import ducc0

        N = self.N
        T = ducc0.nufft.nu2u(points=self.cells.fluxes(self.profile, r_p), coord=self.coord,
                             out=np.empty((N, N), dtype=complex), forward=False, epsilon=1e-9, nthreads=1)
        g = np.fft.fftshift(np.fft.fft2(np.fft.ifftshift(T * self.window))) / N ** 2
        return g.astype(np.complex64)
