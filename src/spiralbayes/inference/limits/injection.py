"""Injected planets: their Δχ² at every scanned instance without re-scanning (the algebra and engine).

Injection–recovery plants a template instance ``a = (template, r_a, phi_a)`` into the data and
asks whether the scan would find it. Re-scanning every injected dataset is not needed. With
residual ``R = V_O - V_A`` (the axisymmetric model ``V_A`` is kept: a spiral ``I_A delta`` has zero
azimuthal mean, so it leaves the axisymmetric fit unchanged to first order) and an injected
``A_inj ΔV_a``, every scanned instance ``b`` keeps its ``power`` and gains a cross term:

    cross_inj(b) = Re sum_k w_k (R_k + A_inj ΔV_a,k)* ΔV_b,k = cross(b) + A_inj X(a, b),
    X(a, b)      = Re sum_k w_k ΔV_a,k* ΔV_b,k,
    Δχ²_inj(b)   = 2 cross_inj(b) - power(b) = Δχ²(b) + 2 A_inj X(a, b).

``X`` is evaluated with the scan's own machinery (:mod:`spiralbayes.inference.scan.engine`): the
perturbation spectrum ``P_hat`` of each template at each radius on the polar uv grid (the same
single-precision type-3 NUFFT the power term uses) and the angular Fourier coefficients
``W[j, m]`` of the data weights. With the ring weight density
``w_j(theta_n) = (1/N) sum_m W[j, m] exp(-i m theta_n)`` (so that ``sum_n w_j(theta_n) h(theta_n)
= sum_k w_k L_j(rho_k) h(theta_k)`` for every ``h`` band-limited below ``N / 2``, ``L_j`` the cubic
Lagrange weights of the radial nodes),

    X(a, b; phi_b) = cos^2 i Re sum_j sum_n H_a,j(theta_n) P_hat_b(rho_j, theta_n - phi_b),
    H_a,j(theta_n) = w_j(theta_n) conj(P_hat_a(rho_j, theta_n - phi_a)),

a circular correlation along theta: with ``H_check = N ifft(H)`` and ``B = fft(P_hat_b)``,
``X(phi_b = 2 pi s / N) = cos^2 i Re sum_m [sum_j H_check_j[m] B_j[m] / N] exp(-2 pi i m s / N)``.
The sum over rings ``j`` is one matrix product per angular frequency ``m`` for all injections and
all scanned (template, r_p) pairs at once; only the ``m`` where ``B`` has power are kept (a
template of outer radius ``R_b`` has angular bandwidth ``~ 2 pi rho R_b``). The scan's ``phi_p``
grid needs ``X`` only at ``s = k N / n_phi``, i.e. the ``m`` folded modulo ``n_phi`` and one FFT
of length ``n_phi``.

The error is that of the scan's power term (single precision, cubic interpolation in rho):
~1e-5 of ``sqrt(power_a power_b)``. :func:`injected_cross_reference` is the plain reference (ΔV
of both instances at every baseline and the direct sum), and :func:`brute_force_injection`
re-scans an injected dataset.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ..._threads import blas_threads
from ...exceptions import InputError
from ...model import perturbation_flux, perturbation_visibilities
from ...units import ARCSEC
from ..scan.engine import RHO_OVERSAMPLE, ScanContext, perturbation_spectrum

__all__ = ["Injection", "InjectionEngine", "brute_force_injection", "injected_cross_reference"]

log = logging.getLogger(__name__)

BAND_TOLERANCE = 1e-12
"""Angular frequencies are kept until the left-out spectral energy of ``B`` is below this fraction."""


@dataclass(frozen=True)
class Injection:
    """One planted planet: ``template`` (a template object) at ``r_p`` [arcsec], ``phi_p`` [rad].

    ``amplitude`` multiplies its perturbation (1: the template as it is, the scan's A = 1).
    """

    template: object
    r_p: float
    phi_p: float
    amplitude: float = 1.0


def _full_circle(p_half: np.ndarray) -> np.ndarray:
    """``P_hat`` on all ``theta``: the second half is the conjugate of the first (P is real)."""
    return np.concatenate([p_half, np.conj(p_half)], axis=1)


class InjectionEngine:
    """``X(a, b)`` for many injections ``a`` against every scanned instance ``b`` of a template list.

    Parameters
    ----------
    context : ScanContext
        The scan's context (data points, weights, polar uv grid, ``r_p`` and ``n_phi_p`` grids).
    templates : sequence of SpiralTemplate
        The scanned templates, in the order of the scan's arrays.
    keep : sequence of SpiralTemplate
        Scanned templates that will be injected: their spectra are kept while the engine is
        built (complex64, ``n_rho x n_theta`` per radius) instead of being computed again.
    progress : bool
        tqdm bar over the scanned radii while the spectra are built.

    Notes
    -----
    Building the engine costs one ``P_hat`` per template and radius (what the scan's power term
    costs) and keeps, per radius, the angular spectra ``B`` of the templates restricted to the
    angular frequencies where they have power (complex64).
    """

    def __init__(self, context: ScanContext, templates, *, keep=(), progress: bool = False):
        context = context.with_full_grid()  # one unbanded uv grid: the weights' full coefficients
        self.context = context
        self.templates = list(templates)
        self._keep = {id(t) for t in keep}
        n_rho, n_theta = context.uv_weights_hat.shape
        if n_theta % context.n_phi_p:
            raise InputError(f"the uv grid's {n_theta} azimuths are not a multiple of n_phi_p = {context.n_phi_p}")
        self.n_rho, self.n_theta = n_rho, n_theta
        # ring weight density w_j(theta_n), real up to rounding (W[j, -m] = conj W[j, m]); single
        # precision like the spectra it multiplies
        self.density = (np.fft.fft(context.uv_weights_hat, axis=1).real / n_theta).astype(np.float32)
        self._spectra_cache: dict = {}
        self._build_bands(progress)

    # -- spectra of the scanned templates ----------------------------------------------------------
    def spectrum(self, template, r_p: float) -> np.ndarray:
        """``P_hat`` of ``template`` at ``r_p`` on the full polar uv grid (n_rho, n_theta), complex64."""
        key = (id(template), float(r_p))
        if key not in self._spectra_cache:
            ctx = self.context
            self._check_extent(template, r_p)
            quad = ctx.quadrature(template, r_p)
            flux = perturbation_flux(ctx.profile, template, quad)
            self._spectra_cache[key] = _full_circle(perturbation_spectrum(ctx, flux, quad))
        return self._spectra_cache[key]

    def _check_extent(self, template, r_p: float) -> None:
        """The uv grid resolves sources out to the scan's outer radius (``max r_p x 2.2``) only."""
        outer = float(r_p) * float(np.max(template.x))
        limit = 1.0 / (RHO_OVERSAMPLE * 4 * self.context.d_rho) / ARCSEC  # the grid's r_out [arcsec]
        if outer > limit * (1 + 1e-9):
            raise InputError(
                f"an injection of {getattr(template, 'name', 'a template')} at r_p = {r_p:.3g} arcsec reaches "
                f"{outer:.3g} arcsec, beyond the scan's grid ({limit:.3g} arcsec = max r_p x 2.2): inject at "
                f"r_p <= {limit / float(np.max(template.x)):.3g} arcsec or scan larger radii")

    def _build_bands(self, progress: bool) -> None:
        from tqdm.auto import tqdm

        ctx = self.context
        n_t = len(self.templates)
        per_m: list[list] = [[] for _ in range(self.n_theta)]  # per m: (radius index, B[:, :, m])
        for i, r_p in enumerate(tqdm(ctx.r_p, desc="template spectra", unit="radius", disable=not progress)):
            B = np.empty((n_t, self.n_rho, self.n_theta), dtype=np.complex64)
            for t, template in enumerate(self.templates):
                quad = ctx.quadrature(template, r_p)
                flux = perturbation_flux(ctx.profile, template, quad)
                full = _full_circle(perturbation_spectrum(ctx, flux, quad))
                if id(template) in self._keep:
                    self._spectra_cache[(id(template), float(r_p))] = full
                B[t] = np.fft.fft(full, axis=1)
            for m in _band(B, self.n_theta):
                per_m[m].append((i, np.ascontiguousarray(B[:, :, m].T)))  # (n_rho, n_t)
            ctx._plan_cache.clear()  # one radius at a time: plans are 10-30 MB each
        self._columns = []
        self._matrices = []
        for m in range(self.n_theta):
            if per_m[m]:
                self._columns.append((m, np.array([i for i, _ in per_m[m]])))
                self._matrices.append(np.concatenate([b for _, b in per_m[m]], axis=1))
        kept = sum(mat.size for mat in self._matrices)
        log.info("injection engine: %d of %d angular frequencies used, %.0f MB of template spectra",
                 len(self._matrices), self.n_theta, kept * 8 / 1e6)

    # -- the cross terms ---------------------------------------------------------------------------
    def _h_check(self, injections) -> np.ndarray:
        """``ifft(H_a)`` of each injection, shape (n_theta, n_inj, n_rho) (m first, for the products)."""
        out = np.empty((self.n_theta, len(injections), self.n_rho), dtype=np.complex64)
        step = 2 * np.pi / self.n_theta
        for a, inj in enumerate(injections):
            shift = inj.phi_p / step
            s = int(round(shift))
            p = self.spectrum(inj.template, inj.r_p)
            if abs(shift - s) > 1e-6:  # an azimuth between uv-grid nodes: rotate by a phase ramp
                m = np.fft.fftfreq(self.n_theta, 1.0 / self.n_theta)
                ramp = np.exp(-1j * m * inj.phi_p).astype(np.complex64)
                rotated = np.fft.ifft(np.fft.fft(p, axis=1) * ramp, axis=1)
            else:
                rotated = np.roll(p, s, axis=1)
            h = np.conj(rotated)
            h *= self.density * np.float32(inj.amplitude)
            out[:, a, :] = np.fft.ifft(h, axis=1).T
        return out

    def cross(self, injections, *, chunk: int = 128) -> np.ndarray:
        """``A_inj X(a, b)`` for each injection: array (n_inj, n_templates, n_rp, n_phi_p).

        Added to the scan's ``cross`` it gives the cross term of the injected dataset.
        """
        injections = list(injections)
        for inj in injections:
            if not inj.r_p > 0:
                raise InputError(f"injection radius must be positive [arcsec], got {inj.r_p}")
        ctx = self.context
        n_t, n_rp, n_phi = len(self.templates), ctx.r_p.size, ctx.n_phi_p
        out = np.empty((len(injections), n_t, n_rp, n_phi))
        for start in range(0, len(injections), chunk):
            part = injections[start:start + chunk]
            h_check = self._h_check(part)
            folded = np.zeros((n_phi, len(part), n_rp, n_t), dtype=np.complex128)
            # many small products: one BLAS thread each (threads spinning for them cost more than they save)
            with blas_threads(1):
                for (m, radii), mat in zip(self._columns, self._matrices):
                    view = folded[m % n_phi]
                    view[:, radii, :] += (h_check[m] @ mat).reshape(len(part), radii.size, n_t)
            values = ctx.geometry.cos_inc ** 2 * np.fft.fft(folded, axis=0).real
            out[start:start + len(part)] = values.transpose(1, 3, 2, 0)
        return out


def _band(B: np.ndarray, n_theta: int) -> np.ndarray:
    """Angular frequencies (FFT order) holding all but ``BAND_TOLERANCE`` of the spectral energy."""
    energy = np.asarray(np.sum(B.real ** 2 + B.imag ** 2, axis=(0, 1), dtype=np.float64))
    total = energy.sum()
    if total <= 0:
        return np.zeros(0, dtype=int)
    m = np.fft.fftfreq(n_theta, 1.0 / n_theta).astype(int)
    order = np.argsort(np.abs(m), kind="stable")
    left = total - np.cumsum(energy[order])
    n_keep = int(np.searchsorted(-left, -BAND_TOLERANCE * total)) + 1
    # keep both signs of every |m| kept
    top = np.abs(m[order[min(n_keep, n_theta) - 1]])
    return np.flatnonzero(np.abs(m) <= top)


def injected_cross_reference(context: ScanContext, injection: Injection, template, r_p: float,
                             phi_p: float) -> float:
    """``A_inj X(a, b)`` by building both perturbations at every baseline (the plain reference).

    Both use the context's quadratures, so the comparison tests the algebra, not the quadrature.
    """
    ctx = context
    dv_a = perturbation_visibilities(ctx.u, ctx.v, ctx.geometry, ctx.profile, injection.template,
                                     injection.r_p, injection.phi_p,
                                     quad=ctx.quadrature(injection.template, injection.r_p))
    dv_b = perturbation_visibilities(ctx.u, ctx.v, ctx.geometry, ctx.profile, template, r_p, phi_p,
                                     quad=ctx.quadrature(template, r_p))
    return float(injection.amplitude * np.sum(ctx.weights * (np.conj(dv_a) * dv_b).real))


def injected_visibilities(vis, axisymmetric, injection: Injection, geometry, *, cell_factor=None,
                          phi_multiple: int = 90):
    """``vis`` (standardised) with the injected planet's perturbation visibilities added.

    The perturbation is summed on the quadrature a scan with ``n_phi_p = phi_multiple`` uses.
    """
    from dataclasses import replace

    from ...model import DEFAULT_CELL_FACTOR, make_quadrature
    from ..scan.engine import profile_and_model_vis

    vis = vis.standardised()
    profile, _ = profile_and_model_vis(axisymmetric, vis, geometry)
    quad = make_quadrature(injection.template, injection.r_p, float(np.max(np.hypot(vis.u, vis.v))),
                           cell_factor=cell_factor or DEFAULT_CELL_FACTOR, phi_multiple=phi_multiple)
    dv = perturbation_visibilities(vis.u, vis.v, geometry, profile, injection.template, injection.r_p,
                                   injection.phi_p, quad=quad)
    provenance = {**vis.provenance, "injected": {"template": getattr(injection.template, "name", "?"),
                                                 "r_p": injection.r_p, "phi_p": injection.phi_p,
                                                 "amplitude": injection.amplitude}}
    return replace(vis, V=vis.V + injection.amplitude * dv, provenance=provenance)


def brute_force_injection(vis, axisymmetric, templates, injection: Injection, geometry=None, *, refit=None,
                          **scan_kwargs):
    """Scan the injected dataset from scratch (the reference for :class:`InjectionEngine`).

    The axisymmetric model is kept (as in the fast path) unless ``refit`` is a
    ``callable(vis) -> model`` run on the injected data (e.g. a frank fit); ``scan_kwargs`` go to
    :func:`spiralbayes.inference.scan.scan`.
    """
    from ..scan.run import scan

    geometry = geometry or axisymmetric.geometry
    injected = injected_visibilities(vis, axisymmetric, injection, geometry, cell_factor=scan_kwargs.get("cell_factor"),
                                     phi_multiple=scan_kwargs.get("n_phi_p", 90))
    model = axisymmetric if refit is None else refit(injected)
    return scan(injected, model, templates, geometry, allow_other_data=refit is None, **scan_kwargs)
