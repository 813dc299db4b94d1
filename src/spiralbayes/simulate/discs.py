"""Model discs for synthetic observations: power-law discs, rendering and exact visibilities."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..exceptions import InputError
from ..fourier import ImageSampler
from ..geometry import DiscGeometry
from ..settings import DEFAULT_DISTANCE_PC
from ..templates.radiative import planck_nu
from ..units import ARCSEC, JY

__all__ = [
    "DiscModel",
    "disc_visibilities",
    "hankel_visibilities",
    "image_visibilities",
    "planck",
    "render_disc_image",
]


def planck(T, wavelength: float) -> np.ndarray:
    """Planck function B_nu(T) [Jy/sr] at ``wavelength`` [m] (:func:`~spiralbayes.templates.radiative.planck_nu`)."""
    with np.errstate(over="ignore", divide="ignore"):
        return planck_nu(T, wavelength) / JY


@dataclass(frozen=True)
class DiscModel:
    """Axisymmetric power-law disc (Stevenson et al. 2024, sec. 3).

    ``Sigma ~ r^-sigma_index``, ``T = T_ref (r / r_ref)^-temperature_index`` and
    ``tau = tau_ref (r / r_ref)^-sigma_index`` between ``r_in`` and ``r_out``; the brightness
    ``I = B_nu(T) (1 - exp(-tau))`` [Jy/sr], zero outside the edges. With ``flux`` [Jy] set, the
    profile is rescaled to that face-on total flux ``2 pi int I r dr`` (the observed flux of an
    inclined disc is ``flux cos i``).

    Parameters
    ----------
    r_in, r_out, r_ref : float
        Inner edge, outer edge and reference radius [au].
    distance : float
        [pc].
    sigma_index, temperature_index : float
        Power-law indices p and q (defaults 1 and 1/2).
    T_ref : float
        Temperature at ``r_ref`` [K].
    tau_ref : float
        Optical depth at ``r_ref`` at the observing wavelength.
    flux : float, optional
        Face-on total flux [Jy]; None keeps the physical brightness.
    """

    r_in: float = 10.0
    r_out: float = 110.0
    distance: float = DEFAULT_DISTANCE_PC
    sigma_index: float = 1.0
    temperature_index: float = 0.5
    r_ref: float = 50.0
    T_ref: float = 20.0
    tau_ref: float = 0.3
    flux: float | None = None

    def __post_init__(self):
        if not 0 <= self.r_in < self.r_out:
            raise InputError(f"DiscModel needs 0 <= r_in < r_out [au], got {self.r_in}, {self.r_out}")
        for name in ("distance", "r_ref", "T_ref", "tau_ref"):
            if not getattr(self, name) > 0:
                raise InputError(f"DiscModel.{name} must be positive, got {getattr(self, name)}")

    @property
    def r_min(self) -> float:
        """Inner edge [arcsec]."""
        return self.r_in / self.distance

    @property
    def r_max(self) -> float:
        """Outer edge [arcsec]."""
        return self.r_out / self.distance

    def to_dict(self) -> dict:
        return asdict(self)

    def optical_depth(self, x) -> np.ndarray:
        """Optical depth at ``x = r / r_ref`` (a subclass may reshape the surface density here)."""
        return self.tau_ref * np.asarray(x, dtype=float) ** -self.sigma_index

    def _unscaled(self, r, wavelength):
        r_au = np.asarray(r, dtype=float) * self.distance
        inside = (r_au >= self.r_in) & (r_au <= self.r_out)
        x = np.where(inside, r_au, self.r_ref) / self.r_ref
        temp = self.T_ref * x**-self.temperature_index
        return np.where(inside, planck(temp, wavelength) * -np.expm1(-self.optical_depth(x)), 0.0)

    def face_on_flux(self, wavelength: float) -> float:
        """``2 pi int I r dr`` [Jy] of the profile at ``wavelength`` [m]."""
        if self.flux is not None:
            return float(self.flux)
        return self._raw_flux(wavelength)

    def _raw_flux(self, wavelength):
        from scipy.special import roots_legendre

        x, wq = roots_legendre(400)
        r = 0.5 * (self.r_max - self.r_min) * (x + 1) + self.r_min
        integrand = self._unscaled(r, wavelength) * r * ARCSEC**2
        return float(2 * np.pi * 0.5 * (self.r_max - self.r_min) * np.sum(wq * integrand))

    def brightness(self, r, wavelength: float) -> np.ndarray:
        """Face-on brightness [Jy/sr] at disc radius ``r`` [arcsec]."""
        I = self._unscaled(r, wavelength)
        if self.flux is not None:
            I = I * (self.flux / self._raw_flux(wavelength))
        return I

    def profile(self, wavelength: float):
        """``I(r [arcsec]) -> Jy/sr`` at ``wavelength``: the callable the renderers take."""
        return lambda r: self.brightness(r, wavelength)


def _perturbation_function(perturbation, r_p, phi_p):
    """``delta(r, phi)`` from a callable or a template object with ``evaluate(r, phi, r_p, phi_p)``."""
    if perturbation is None:
        return None
    if hasattr(perturbation, "evaluate"):
        if r_p is None or phi_p is None:
            raise InputError(
                "a template perturbation needs the planet position r_p [arcsec] and phi_p [rad]"
            )
        return lambda r, phi: perturbation.evaluate(r, phi, r_p, phi_p)
    if callable(perturbation):
        return perturbation
    raise TypeError(
        "perturbation must be a callable delta(r [arcsec], phi [rad]) or an object with "
        f"evaluate(r, phi, r_p, phi_p), got {type(perturbation).__name__}"
    )


def _describe_perturbation(perturbation):
    """A short, JSON-friendly label of a perturbation for provenance records."""
    if perturbation is None:
        return None
    name = getattr(perturbation, "name", "") or getattr(perturbation, "__name__", "")
    return str(name) or type(perturbation).__name__


def render_disc_image(profile, geometry: DiscGeometry, r_max: float, *, pixel_size: float = 0.004,
                      supersample: int = 3, perturbation=None, r_p: float | None = None,
                      phi_p: float | None = None, axisymmetric: bool = True):
    """Inclined disc image [Jy/pixel] in the unrotated frame of :func:`.fourier.sample_image`.

    The major axis points north (image ``y``), east is left; only ``geometry.inc`` is used
    (``PA``, ``dRA``, ``dDec`` are applied when sampling). Each pixel is the mean of
    ``supersample^2`` point samples of ``I(r) (1 + delta(r, phi))`` (or of ``I delta`` with
    ``axisymmetric=False``) at the disc-plane position of the sub-sample, times the pixel's solid
    angle, so the total is ``cos i`` times the face-on flux.

    Parameters
    ----------
    profile : callable
        ``I(r [arcsec]) -> Jy/sr`` (e.g. ``DiscModel.profile(wavelength)``), zero beyond ``r_max``.
    r_max : float
        Outer radius of the emission [arcsec]; the image covers ``+-1.02 r_max`` along the major
        axis and ``+-1.02 r_max cos i`` across it.
    pixel_size : float
        [arcsec]; 4 mas by default (see the module docstring).
    supersample : int
        Sub-samples per pixel and axis.
    perturbation, r_p, phi_p
        ``delta(r [arcsec], phi [rad])`` or a template with ``evaluate(r, phi, r_p, phi_p)``.

    Returns
    -------
    image : ndarray (ny, nx)
    pixel_size : float
    """
    delta = _perturbation_function(perturbation, r_p, phi_p)
    if not axisymmetric and delta is None:
        raise InputError("axisymmetric=False renders only the perturbation: give one")
    K = int(supersample)
    if K < 1:
        raise InputError(f"supersample must be a positive integer, got {supersample}")
    ci = geometry.cos_inc
    half = 1.02 * r_max
    ny = 2 * int(np.ceil(half / pixel_size)) + 1
    nx = 2 * int(np.ceil(half * ci / pixel_size)) + 1
    sub = ((np.arange(K) + 0.5) / K - 0.5) * pixel_size
    l = (-(np.arange(nx) - nx // 2) * pixel_size)[:, None] + sub[None, :]
    m = ((np.arange(ny) - ny // 2) * pixel_size)[:, None] + sub[None, :]
    ll, mm = np.meshgrid(l.ravel(), m.ravel())
    r, phi = DiscGeometry(geometry.inc, 0.0, 0.0, 0.0).sky_to_disc(ll, mm)
    fine = np.asarray(profile(r), dtype=float)
    if delta is not None:
        d = np.asarray(delta(r, phi), dtype=float)
        fine = fine * (1.0 + d) if axisymmetric else fine * d
    image = fine.reshape(ny, K, nx, K).mean(axis=(1, 3)) * (pixel_size * ARCSEC) ** 2
    return image, pixel_size


def _dirichlet(x, K):
    """``sin(x) / (K sin(x / K))``, 1 at x = 0."""
    if K == 1:
        return np.ones_like(x)
    x = np.asarray(x, dtype=float)
    small = np.abs(x) < 1e-8
    xs = np.where(small, 1.0, x)
    return np.where(small, 1.0, np.sin(xs) / (K * np.sin(xs / K)))


def image_visibilities(image, pixel_size: float, u, v, geometry: DiscGeometry, *, supersample: int = 3,
                       pixel_window_correction: bool = True, nthreads: int = 1) -> np.ndarray:
    """Visibilities [Jy] of an image from :func:`render_disc_image` under ``geometry``.

    Samples with :class:`spiralbayes.fourier.ImageSampler` (PA, dRA, dDec) and divides by the
    supersampling kernel (module docstring) unless ``pixel_window_correction`` is False.
    """
    sampler = ImageSampler(u, v, image.shape, pixel_size, geometry, nthreads=nthreads)
    V = sampler.sample(image)
    if pixel_window_correction:
        ur, vr = geometry.rotate_uv(u, v)
        a = np.pi * pixel_size * ARCSEC
        V = V / (_dirichlet(a * ur, supersample) * _dirichlet(a * vr, supersample))
    return V


def hankel_visibilities(profile, u, v, geometry: DiscGeometry, r_min: float, r_max: float, *,
                        n_nodes: int | None = None, points_per_period: float = 40.0) -> np.ndarray:
    """Exact visibilities [Jy] of an axisymmetric, inclined, optically thick disc.

    ``V = cos i 2 pi int_{r_min}^{r_max} I(r) J0(2 pi q r) r dr exp(2 pi i (u dRA + v dDec))`` with
    ``q`` the deprojected baseline, by Gauss-Legendre quadrature between ``r_min`` and ``r_max``
    [arcsec] (put the profile's discontinuities there). For many baselines ``V(q)`` is computed on
    a grid of ``points_per_period`` points per ``1 / r_max`` and interpolated with a cubic spline
    (relative error ~1e-7).
    """
    from scipy.interpolate import CubicSpline
    from scipy.special import j0, roots_legendre

    up, vp = geometry.deproject_uv(u, v)
    q = np.hypot(up, vp)
    a, b = r_min * ARCSEC, r_max * ARCSEC
    q_max = float(q.max()) if q.size else 0.0
    cycles = q_max * (b - a)
    if n_nodes is None:
        n_nodes = int(4 * cycles) + 200
    x, wq = roots_legendre(n_nodes)
    r = 0.5 * (b - a) * (x + 1) + a
    weight = 2 * np.pi * 0.5 * (b - a) * wq * np.asarray(profile(r / ARCSEC), dtype=float) * r

    def transform(qs):
        out = np.empty(qs.size)
        for s in range(0, qs.size, 4096):
            out[s:s + 4096] = j0(2 * np.pi * np.outer(qs[s:s + 4096], r)) @ weight
        return out

    n_grid = int(np.ceil(q_max * b * points_per_period)) + 4
    if q.size > 2 * n_grid:
        grid = np.linspace(0.0, q_max, n_grid)
        Vq = CubicSpline(grid, transform(grid))(q)
    else:
        Vq = transform(q)
    return geometry.cos_inc * Vq * geometry.phase_factor(u, v)


def disc_visibilities(u, v, profile, geometry: DiscGeometry, r_max: float, *, r_min: float = 0.0,
                      perturbation=None, r_p: float | None = None, phi_p: float | None = None,
                      method: str = "hankel", pixel_size: float = 0.004, supersample: int = 3,
                      pixel_window_correction: bool = True) -> np.ndarray:
    """Visibilities [Jy] of ``I(r) (1 + delta(r, phi))`` under ``geometry``.

    ``method="hankel"`` (default): the axisymmetric part by :func:`hankel_visibilities` (exact)
    and only ``I delta`` rendered and sampled. ``method="image"``: everything rendered.
    """
    if method not in ("hankel", "image"):
        raise InputError(f"method must be 'hankel' or 'image', got {method!r}")
    has_delta = perturbation is not None
    V = np.zeros(np.size(u), dtype=complex)
    if method == "hankel":
        V += hankel_visibilities(profile, u, v, geometry, r_min, r_max)
    if method == "image" or has_delta:
        image, pix = render_disc_image(profile, geometry, r_max, pixel_size=pixel_size,
                                       supersample=supersample, perturbation=perturbation, r_p=r_p,
                                       phi_p=phi_p, axisymmetric=method == "image")
        V += image_visibilities(image, pix, u, v, geometry, supersample=supersample,
                                pixel_window_correction=pixel_window_correction)
    return V
