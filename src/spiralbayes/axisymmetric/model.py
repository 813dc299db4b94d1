"""The :class:`AxisymmetricModel`: a frank brightness profile and everything computed from it.

See :mod:`spiralbayes.axisymmetric` for the conventions.
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from collections.abc import Callable
from typing import Any

import numpy as np

from .._hdf5 import checked_dataset, open_file, write_file
from .._provenance import provenance_record, to_json
from ..exceptions import InputError
from ..geometry import DiscGeometry
from ..units import ARCSEC

__all__ = ["AXISYMMETRIC_KIND", "DEFAULT_HYPERPARAMETERS", "AxisymmetricModel"]

log = logging.getLogger(__name__)

# values of mixed types (N an int, the others floats), read by name
DEFAULT_HYPERPARAMETERS: dict[str, Any] = {
    "N": 200,
    "Rmax": 1.2,
    "alpha": 1.05,
    "p0": 1e-15,
    "weights_smooth": 0.1,
}
"""frank hyperparameters of Stevenson et al. (2024): N, Rmax [arcsec], alpha, p0 [Jy^2], weights_smooth."""


AXISYMMETRIC_KIND = "spiralbayes.AxisymmetricModel"
_CHUNK_ELEMENTS = 2_000_000  # largest (points x N) matrix built at once (16 MB)


def _frank_version() -> str:
    import frank

    return str(getattr(frank, "__version__", "unknown"))


def _check_hyperparameters(N, Rmax, alpha, p0, weights_smooth) -> None:
    if isinstance(N, bool) or not isinstance(N, (int, np.integer)) or N < 2:
        raise InputError(f"N = {N!r}: the number of collocation points must be an integer >= 2 "
                         f"(the paper uses N = {DEFAULT_HYPERPARAMETERS['N']})")
    if not (np.isfinite(Rmax) and Rmax > 0):
        raise InputError(f"Rmax = {Rmax!r} arcsec: the outer radius of the fit must be positive "
                         f"(the paper uses Rmax = {DEFAULT_HYPERPARAMETERS['Rmax']} arcsec)")
    if not (np.isfinite(alpha) and alpha >= 1):
        raise InputError(f"alpha = {alpha!r}: frank's power-spectrum prior needs alpha >= 1 "
                         f"(the paper uses {DEFAULT_HYPERPARAMETERS['alpha']})")
    if not (np.isfinite(p0) and p0 > 0):
        raise InputError(f"p0 = {p0!r} Jy^2 must be positive (the paper uses {DEFAULT_HYPERPARAMETERS['p0']})")
    if not (np.isfinite(weights_smooth) and weights_smooth >= 0):
        raise InputError(f"weights_smooth = {weights_smooth!r} must be >= 0 "
                         f"(the paper uses {DEFAULT_HYPERPARAMETERS['weights_smooth']})")


# ---------------------------------------------------------------------------------------------
@dataclass
class AxisymmetricModel:
    """An axisymmetric disc: a frank brightness profile and the geometry it is seen under.

    Parameters
    ----------
    r : ndarray, shape (N,)
        frank's collocation radii [arcsec] for ``(Rmax, N)``.
    I : ndarray, shape (N,)
        Brightness at ``r`` [Jy/sr] (frank's posterior mean for ``method="Normal"``).
    geometry : DiscGeometry
        Inclination, position angle and offset of the disc (given or fitted).
    Rmax : float
        Outer radius of the Fourier–Bessel series [arcsec]. frank takes the brightness to be
        zero beyond it (:meth:`brightness`); its visibilities are those of the band-limited
        series, whose small continuation beyond ``Rmax`` :meth:`image` keeps.
    hyperparameters : dict
        What the fit used: ``N``, ``Rmax``, ``alpha``, ``p0``, ``weights_smooth``, ``method``,
        ``nonnegative``, ``fit_geometry``, ...
    I_err : ndarray, optional
        frank's 1-sigma posterior uncertainty of ``I`` [Jy/sr] (``method="Normal"`` only;
        it neglects the uncertainty of the power spectrum and of the geometry).
    I_nonneg : ndarray, optional
        The best fit constrained to ``I >= 0`` [Jy/sr] (frank's ``solve_non_negative``), when
        requested. Use :meth:`nonnegative` for a model that uses it.
    frank_version : str, optional
        frank's version that made the fit.
    fit_time_s : float, optional
        Wall-clock time of the fit [s] (geometry fit included).
    provenance : dict
        Data hash, number of visibilities, package versions, geometry-fit time, iterations.
    """

    r: np.ndarray
    I: np.ndarray
    geometry: DiscGeometry
    Rmax: float
    hyperparameters: dict = field(default_factory=dict)
    I_err: np.ndarray | None = None
    I_nonneg: np.ndarray | None = None
    frank_version: str | None = None
    fit_time_s: float | None = None
    provenance: dict = field(default_factory=dict)
    frank_solution: object = field(default=None, repr=False, compare=False)
    """frank's solution object of the fit (not saved; ``None`` after :meth:`load`)."""
    power_spectrum: np.ndarray | None = field(default=None, repr=False, compare=False)
    """frank's MAP power spectrum [Jy^2] at the collocation frequencies (saved): the profile's
    Gaussian-process prior, used to integrate the profile out (:mod:`spiralbayes.axisymmetric.gp`)."""

    def __post_init__(self):
        self.r = np.asarray(self.r, dtype=float).ravel()
        self.I = np.asarray(self.I, dtype=float).ravel()
        self.Rmax = float(self.Rmax)
        _check_hyperparameters(self.r.size, self.Rmax, 1.0, 1.0, 0.0)
        for name in ("I", "I_err", "I_nonneg", "power_spectrum"):
            arr = getattr(self, name)
            if arr is None:
                continue
            arr = np.asarray(arr, dtype=float).ravel()
            if arr.shape != self.r.shape:
                raise InputError(f"AxisymmetricModel.{name} has {arr.size} values for {self.r.size} radii")
            if not np.all(np.isfinite(arr)):
                raise InputError(f"AxisymmetricModel.{name} has NaN/inf values")
            setattr(self, name, arr)
        if not isinstance(self.geometry, DiscGeometry):
            raise TypeError(f"geometry must be a spiralbayes.geometry.DiscGeometry, got {type(self.geometry).__name__}")
        expected = self._dht.r / ARCSEC
        if not np.allclose(self.r, expected, rtol=1e-9, atol=0):
            raise InputError("r must be frank's collocation radii for (Rmax, N): build models with "
                             "fit_axisymmetric or AxisymmetricModel.from_profile")

    # --- construction --------------------------------------------------------------------
    @classmethod
    def from_profile(cls, profile: Callable[[np.ndarray], np.ndarray], geometry: DiscGeometry | None = None,
                     *, N: int = DEFAULT_HYPERPARAMETERS["N"], Rmax: float = DEFAULT_HYPERPARAMETERS["Rmax"],
                     ) -> AxisymmetricModel:
        """A model of a known brightness profile (no fit), e.g. for simulations and tests.

        Parameters
        ----------
        profile : callable
            ``I(r)`` [Jy/sr] of the disc-plane radius ``r`` [arcsec]; evaluated at frank's
            collocation radii. Choose ``Rmax`` so that the profile is ~0 there.
        geometry : DiscGeometry, optional
            Default: face on, centred.
        N, Rmax : int, float
            Collocation points and outer radius [arcsec] of the Fourier–Bessel series.
        """
        _check_hyperparameters(N, Rmax, 1.0, 1.0, 0.0)
        from frank.hankel import DiscreteHankelTransform

        r = DiscreteHankelTransform(Rmax * ARCSEC, int(N)).r / ARCSEC
        I = np.asarray(profile(r), dtype=float)
        return cls(r=r, I=I, geometry=geometry or DiscGeometry(), Rmax=Rmax,
                   hyperparameters={"N": int(N), "Rmax": float(Rmax), "source": "profile"},
                   frank_version=_frank_version())

    def nonnegative(self) -> AxisymmetricModel:
        """The same model with the non-negative profile ``I_nonneg`` as its brightness."""
        if self.I_nonneg is None:
            raise InputError("this model has no non-negative profile: fit with nonnegative=True")
        return replace(self, I=self.I_nonneg, I_err=None,
                       hyperparameters={**self.hyperparameters, "profile": "nonnegative"})

    def with_geometry(self, geometry: DiscGeometry) -> AxisymmetricModel:
        """The same profile seen under another geometry."""
        return replace(self, geometry=geometry)

    # --- frank's transform -------------------------------------------------------------------
    @property
    def N(self) -> int:
        """Number of collocation points."""
        return self.r.size

    @cached_property
    def _dht(self):
        from frank.hankel import DiscreteHankelTransform

        return DiscreteHankelTransform(self.Rmax * ARCSEC, self.r.size)

    @property
    def Qmax(self) -> float:
        """Largest baseline the series represents [lambda]; data must lie below it."""
        return float(self._dht.Qmax)

    def _hankel(self, q) -> np.ndarray:
        """Face-on visibilities ``2 pi int I(r) J0(2 pi q r) r dr`` [Jy] at ``q`` [lambda]."""
        q = np.asarray(q, dtype=float)
        flat = q.ravel()
        out = np.empty(flat.size)
        step = max(1, _CHUNK_ELEMENTS // self.N)
        for start in range(0, flat.size, step):
            sl = slice(start, start + step)
            out[sl] = self._dht.coefficients(flat[sl], direction="forward") @ self.I
        return out.reshape(q.shape)

    def visibilities(self, u, v, geometry: DiscGeometry | None = None) -> np.ndarray:
        """Model visibilities [Jy] at baselines ``(u, v)`` [lambda], exactly as frank predicts.

        ``V(u, v) = cos i · H[I](q') · exp(+2 pi i (u dRA + v dDec))`` with ``q'`` the deprojected
        baseline length and ``H`` frank's discrete Hankel transform; equal to frank's
        ``sol.predict(u, v)`` for the same geometry.

        Parameters
        ----------
        u, v : array_like
            Baselines [lambda].
        geometry : DiscGeometry, optional
            Default: the model's own.
        """
        geometry = geometry or self.geometry
        up, vp = geometry.deproject_uv(u, v)
        V = geometry.cos_inc * self._hankel(np.hypot(up, vp))
        return V * geometry.phase_factor(u, v)

    def visibilities_deprojected(self, q, *, projected: bool = True) -> np.ndarray:
        """Real visibilities [Jy] against deprojected baseline length ``q`` [lambda].

        ``projected=True`` (default) includes the factor ``cos i`` of the model's geometry, so
        the curve overlays deprojected, re-centred data (frank's ``predict_deprojected`` and
        uvplot's convention); ``projected=False`` gives the face-on Hankel transform.
        """
        V = self._hankel(q)
        return V * self.geometry.cos_inc if projected else V

    # --- brightness --------------------------------------------------------------------------
    def brightness(self, r, *, truncate: bool = True) -> np.ndarray:
        """Brightness [Jy/sr] at disc radii ``r`` [arcsec]: frank's Fourier–Bessel interpolation.

        ``I(r) = sum_k I_k 2 j_k J0(x) / (J1(j_k) (j_k^2 - x^2))`` with ``x = 2 pi Qmax r`` and
        ``j_k`` the zeros of J0 (frank's ``DiscreteHankelTransform.interpolation_coefficients``):
        exact at the collocation radii, band-limited to ``Qmax`` in between.

        Parameters
        ----------
        r : array_like
            Disc-plane radii [arcsec], >= 0.
        truncate : bool
            Zero at and beyond ``Rmax`` (frank's convention, default). With ``False`` the
            band-limited series continues beyond ``Rmax``: that is the function whose Fourier
            transform :meth:`visibilities` returns, so images meant to reproduce those
            visibilities use it (:meth:`image`).
        """
        r = np.asarray(r, dtype=float)
        if np.any(r < 0) or not np.all(np.isfinite(r)):
            raise InputError("radii must be finite and >= 0 arcsec")
        flat = r.ravel()
        out = np.zeros(flat.size)
        todo = np.flatnonzero(flat < self.Rmax) if truncate else np.arange(flat.size)
        step = max(1, _CHUNK_ELEMENTS // self.N)
        for start in range(0, todo.size, step):
            idx = todo[start:start + step]
            out[idx] = self._interpolation_matrix(flat[idx]) @ self.I
        return out.reshape(r.shape)

    @cached_property
    def _bessel_zeros(self) -> np.ndarray:
        """``j_k``, the first N zeros of J0 (x of the collocation radii)."""
        return 2 * np.pi * self.Qmax * self._dht.r

    def _interpolation_matrix(self, r) -> np.ndarray:
        """Fourier–Bessel interpolation coefficients at radii ``r`` [arcsec], shape (len(r), N)."""
        from scipy.special import j0, j1

        jk = self._bessel_zeros
        x = 2 * np.pi * self.Qmax * (np.asarray(r, dtype=float) * ARCSEC)
        denom = jk[None, :] ** 2 - x[:, None] ** 2
        # At x = j_k the basis function is 1 and the others 0; the formula reads 0/0 there.
        hit = np.abs(denom) < 1e-8 * jk[None, :]
        with np.errstate(divide="ignore", invalid="ignore"):
            Y = np.outer(j0(x), 2 * jk / j1(jk)) / denom
        rows = np.flatnonzero(hit.any(axis=1))
        if rows.size:
            Y[rows] = hit[rows].astype(float)
        return Y

    @property
    def total_flux(self) -> float:
        """Face-on flux ``int 2 pi r I dr`` [Jy] (the Hankel transform at q = 0).

        The flux seen on the sky is ``total_flux * geometry.cos_inc``.
        """
        return float(self._hankel(np.zeros(1))[0])

    def cumulative_flux(self, n: int | None = None):
        """Face-on flux within radius ``r``: ``(r [arcsec], F(<r) [Jy])`` on a fine grid."""
        n = n or max(20 * self.N, 4000)
        r = np.linspace(0.0, self.Rmax, n + 1)
        integrand = 2 * np.pi * r * ARCSEC ** 2 * self.brightness(r)
        F = np.concatenate([[0.0], np.cumsum(0.5 * (integrand[1:] + integrand[:-1]) * np.diff(r))])
        return r, F

    def R_eff(self, fraction: float = 0.95) -> float:
        """Radius [arcsec] containing ``fraction`` of the face-on flux (first crossing)."""
        if not 0 < fraction < 1:
            raise InputError(f"fraction = {fraction!r} must lie in (0, 1)")
        r, F = self.cumulative_flux()
        if F[-1] <= 0:
            raise InputError("the profile has no positive total flux: R_eff is undefined")
        frac = F / F[-1]
        k = int(np.argmax(frac >= fraction))
        if k == 0:
            return 0.0
        t = (fraction - frac[k - 1]) / (frac[k] - frac[k - 1])
        return float(r[k - 1] + t * (r[k] - r[k - 1]))

    # --- images ---------------------------------------------------------------------------------
    def image(self, shape, pixel_size: float, geometry: DiscGeometry | None = None, *,
              oversample: int = 1, truncate: bool = False) -> np.ndarray:
        """Inclined sky image [Jy/pixel] in the frame of :mod:`spiralbayes.fourier`.

        The disc is centred on pixel ``(ny // 2, nx // 2)`` with its major axis to the north;
        pixel ``(iy, ix)`` holds ``I(r) * pixel_size^2`` [Jy] with ``r`` the disc-plane radius of
        its centre (``DiscGeometry(inc).sky_to_disc(l, m)``), so the image's flux is
        ``total_flux * cos i`` (optically thick). Sample it with
        ``fourier.sample_image(image, pixel_size, u, v, PA=g.PA, dRA=g.dRA, dDec=g.dDec)``;
        that reproduces :meth:`visibilities` (measured: ~1e-6 relative RMS at 5 mas pixels for
        N = 200, Rmax = 1.2").

        Parameters
        ----------
        shape : int or (ny, nx)
            Image size [pixels]. To hold the whole disc it should span ``2 Rmax`` along the
            north-south axis and ``2 Rmax cos i`` east-west.
        pixel_size : float
            Pixel size [arcsec].
        geometry : DiscGeometry, optional
            Only ``inc`` is used. Default: the model's geometry.
        oversample : int
            Average the brightness over ``oversample x oversample`` points per pixel. The default,
            1, samples pixel centres: frank's profile is band-limited to ``Qmax``, so point
            samples reproduce its visibilities once ``pixel_size <~ cos i / (2 Qmax)``, and no
            smaller pixel helps. Averaging multiplies the visibilities by the pixel's sinc
            response instead (measured 6e-5 relative at 5 mas, ``oversample=3``).
        truncate : bool
            Cut the brightness at ``Rmax`` (see :meth:`brightness`). The default keeps the
            band-limited series' small tail beyond ``Rmax``, which frank's visibilities include:
            cutting it costs ~1e-4 relative for a profile still at 1 % of its peak at ``Rmax``.
        """
        scalar = isinstance(shape, (int, float, np.number))
        ny, nx = (int(shape), int(shape)) if scalar else (int(shape[0]), int(shape[1]))
        if ny < 1 or nx < 1:
            raise InputError(f"image shape {shape!r} must be positive")
        if not (np.isfinite(pixel_size) and pixel_size > 0):
            raise InputError(f"pixel_size = {pixel_size!r} arcsec must be positive")
        if isinstance(oversample, bool) or int(oversample) != oversample or oversample < 1:
            raise InputError(f"oversample = {oversample!r} must be an integer >= 1")
        s = int(oversample)
        frame = DiscGeometry((geometry or self.geometry).inc, 0.0, 0.0, 0.0)
        self._warn_if_cropped(ny, nx, pixel_size, frame.cos_inc)
        sub = (np.arange(s) - (s - 1) / 2) / s * pixel_size  # sub-pixel offsets, symmetric about 0
        l = (-(np.arange(nx) - nx // 2)[:, None] * pixel_size + sub[None, :]).ravel()
        m = ((np.arange(ny) - ny // 2)[:, None] * pixel_size + sub[None, :]).ravel()
        # The image is symmetric in l and in m: evaluate the profile on |l| x |m| only.
        l_abs, l_idx = np.unique(np.abs(l), return_inverse=True)
        m_abs, m_idx = np.unique(np.abs(m), return_inverse=True)
        r_disc, _ = frame.sky_to_disc(l_abs[None, :], m_abs[:, None])
        values = self.brightness(r_disc, truncate=truncate)[np.ix_(m_idx, l_idx)]
        return values.reshape(ny, s, nx, s).mean(axis=(1, 3)) * (pixel_size * ARCSEC) ** 2

    def image_grid(self, geometry: DiscGeometry | None = None) -> tuple[int, float]:
        """An image grid ``(n, pixel_size [arcsec])`` on which :meth:`image` is exact.

        ``pixel_size = cos i / (2 Qmax)`` (the Nyquist pixel of the inclined, band-limited
        profile) and ``n`` even, spanning ``2 Rmax`` plus a pixel.
        """
        cos_inc = (geometry or self.geometry).cos_inc
        pixel = cos_inc / (2 * self.Qmax) / ARCSEC
        n = int(np.ceil(2 * self.Rmax / pixel)) + 2
        return n + n % 2, pixel

    def _warn_if_cropped(self, ny: int, nx: int, pixel_size: float, cos_inc: float) -> None:
        half_ns = (ny // 2 - (1 - ny % 2)) * pixel_size  # smallest half-extent north/south
        half_ew = (nx // 2 - (1 - nx % 2)) * pixel_size
        if half_ns < self.Rmax or half_ew < self.Rmax * cos_inc:
            log.warning("image of %d x %d pixels of %.4g arcsec does not hold the disc out to Rmax = %g arcsec "
                        "(needs half-extents %.3g N-S, %.3g E-W arcsec): its flux and visibilities fall short",
                        ny, nx, pixel_size, self.Rmax, self.Rmax, self.Rmax * cos_inc)

    # --- persistence ------------------------------------------------------------------------------
    def save(self, path) -> Path:
        """Write the model to HDF5 (atomically), with hyperparameters and provenance."""
        with write_file(path, AXISYMMETRIC_KIND) as f:
            f.attrs["Rmax"] = self.Rmax
            f.attrs["frank_version"] = self.frank_version or ""
            f.attrs["fit_time_s"] = np.nan if self.fit_time_s is None else float(self.fit_time_s)
            f.attrs["hyperparameters"] = to_json(self.hyperparameters)
            f.attrs["provenance"] = to_json(self.provenance)
            f.attrs["saved_by"] = to_json(provenance_record())
            g = f.create_group("geometry")
            for key, value in self.geometry.to_dict().items():
                g.attrs[key] = value
            units = {"r": "arcsec", "I": "Jy/sr", "I_err": "Jy/sr", "I_nonneg": "Jy/sr", "power_spectrum": "Jy^2"}
            for name, unit in units.items():
                arr = getattr(self, name)
                if arr is not None:
                    checked_dataset(f, name, arr).attrs["unit"] = unit
        log.info("saved axisymmetric model to %s", path)
        return Path(path)

    def __repr__(self) -> str:
        g = self.geometry
        hp = {k: self.hyperparameters[k] for k in ("alpha", "p0", "weights_smooth") if k in self.hyperparameters}
        settings = ", ".join(f"{k}={v:g}" for k, v in hp.items())
        return (f"AxisymmetricModel(N={self.N}, Rmax={self.Rmax:g} arcsec{', ' + settings if settings else ''}; "
                f"inc={g.inc:.3f} deg, PA={g.PA:.3f} deg, dRA={g.dRA * 1e3:.2f} mas, dDec={g.dDec * 1e3:.2f} mas; "
                f"face-on flux {self.total_flux:.4g} Jy, sky flux {self.total_flux * g.cos_inc:.4g} Jy)")

    @classmethod
    def load(cls, path) -> AxisymmetricModel:
        """Read a model written by :meth:`save`.

        A missing, truncated or corrupt file raises :class:`~spiralbayes.exceptions.MissingFileError`
        or :class:`~spiralbayes.exceptions.DataFileError` naming it.
        """
        with open_file(path, AXISYMMETRIC_KIND, "axisymmetric model") as f:
            geometry = DiscGeometry(**{k: float(f["geometry"].attrs[k]) for k in ("inc", "PA", "dRA", "dDec")})
            arrays: dict[str, Any] = {name: (f[name][()] if name in f else None)
                      for name in ("r", "I", "I_err", "I_nonneg", "power_spectrum")}
            fit_time = float(f.attrs["fit_time_s"])
            return cls(geometry=geometry, Rmax=float(f.attrs["Rmax"]),
                       hyperparameters=json.loads(f.attrs["hyperparameters"]),
                       frank_version=str(f.attrs["frank_version"]) or None,
                       fit_time_s=None if np.isnan(fit_time) else fit_time,
                       provenance=json.loads(f.attrs["provenance"]), **arrays)
