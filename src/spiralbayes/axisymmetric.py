"""Axisymmetric brightness model: a frank fit and everything computed from it.

The axisymmetric disc ``I_A(r)`` of Stevenson et al. (2024, sec. 2.1) is fitted to the
visibilities with frank (Jennings et al. 2020), a Gaussian-process Fourier–Bessel fit of the
deprojected visibilities. The paper's hyperparameters are the defaults here: ``N = 200``
collocation points, ``Rmax = 1.2 arcsec``, ``alpha = 1.05``, ``p0 = 1e-15 Jy^2`` and
``weights_smooth = 0.1`` (frank's JSON parameter file calls them ``n``, ``rout``, ``alpha``,
``p0``, ``wsmooth``; this module uses frank's Python names).

Conventions
-----------
* ``r`` in arcsec, brightness ``I`` in Jy/sr, baselines in wavelengths, angles in degrees.
* frank's brightness is a Fourier–Bessel series: ``I`` holds its values at the ``N``
  collocation radii ``r_k = Rmax j_{0,k} / j_{0,N+1}``. Between them the brightness is
  frank's band-limited interpolant (:meth:`AxisymmetricModel.brightness`); it is zero at and
  beyond ``Rmax``. Its visibilities at any baseline are the exact discrete Hankel transform
  (frank's ``DiscreteHankelTransform``).
* Optically thick, geometrically thin disc (frank's default and the paper's choice): an
  inclined disc has sky brightness ``I(r_disc)``, so its flux, and every visibility, is the
  face-on value times ``cos i``.
* Sky images follow :mod:`spiralbayes.fourier`: the disc is drawn with its major axis to the
  north and centred on the image; ``PA`` and the offset ``(dRA, dDec)`` are applied in the uv
  plane when the image is sampled, as frank and galario do.
"""

from __future__ import annotations

import contextlib
import json
import logging
import time
import warnings
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Callable

import numpy as np

from ._provenance import atomic_path, data_hash, json_default, provenance_record
from .geometry import ARCSEC, DiscGeometry
from .visibilities import Visibilities

__all__ = [
    "AxisymmetricModel",
    "DEFAULT_HYPERPARAMETERS",
    "fit_axisymmetric",
    "run_axisym",
]

log = logging.getLogger(__name__)

DEFAULT_HYPERPARAMETERS = {
    "N": 200,
    "Rmax": 1.2,
    "alpha": 1.05,
    "p0": 1e-15,
    "weights_smooth": 0.1,
}
"""frank hyperparameters of Stevenson et al. (2024): N, Rmax [arcsec], alpha, p0 [Jy^2], weights_smooth."""

GEOMETRY_FITTERS = ("gaussian", "nonparametric")
"""frank's geometry fitters: a Gaussian fitted in uv space, or a Fourier–Bessel profile (N = 20)."""

_HDF5_KIND = "spiralbayes.AxisymmetricModel"
_CHUNK_ELEMENTS = 2_000_000  # largest (points x N) matrix built at once (16 MB)


def _frank_version() -> str:
    import frank

    return str(getattr(frank, "__version__", "unknown"))


def _check_hyperparameters(N, Rmax, alpha, p0, weights_smooth) -> None:
    if isinstance(N, bool) or not isinstance(N, (int, np.integer)) or N < 2:
        raise ValueError(f"N = {N!r}: the number of collocation points must be an integer >= 2 "
                         f"(the paper uses N = {DEFAULT_HYPERPARAMETERS['N']})")
    if not (np.isfinite(Rmax) and Rmax > 0):
        raise ValueError(f"Rmax = {Rmax!r} arcsec: the outer radius of the fit must be positive "
                         f"(the paper uses Rmax = {DEFAULT_HYPERPARAMETERS['Rmax']} arcsec)")
    if not (np.isfinite(alpha) and alpha >= 1):
        raise ValueError(f"alpha = {alpha!r}: frank's power-spectrum prior needs alpha >= 1 "
                         f"(the paper uses {DEFAULT_HYPERPARAMETERS['alpha']})")
    if not (np.isfinite(p0) and p0 > 0):
        raise ValueError(f"p0 = {p0!r} Jy^2 must be positive (the paper uses {DEFAULT_HYPERPARAMETERS['p0']})")
    if not (np.isfinite(weights_smooth) and weights_smooth >= 0):
        raise ValueError(f"weights_smooth = {weights_smooth!r} must be >= 0 "
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

    def __post_init__(self):
        self.r = np.asarray(self.r, dtype=float).ravel()
        self.I = np.asarray(self.I, dtype=float).ravel()
        self.Rmax = float(self.Rmax)
        _check_hyperparameters(self.r.size, self.Rmax, 1.0, 1.0, 0.0)
        for name in ("I", "I_err", "I_nonneg"):
            arr = getattr(self, name)
            if arr is None:
                continue
            arr = np.asarray(arr, dtype=float).ravel()
            if arr.shape != self.r.shape:
                raise ValueError(f"AxisymmetricModel.{name} has {arr.size} values for {self.r.size} radii")
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"AxisymmetricModel.{name} has NaN/inf values")
            setattr(self, name, arr)
        if not isinstance(self.geometry, DiscGeometry):
            raise TypeError(f"geometry must be a spiralbayes.geometry.DiscGeometry, got {type(self.geometry).__name__}")
        expected = self._dht.r / ARCSEC
        if not np.allclose(self.r, expected, rtol=1e-9, atol=0):
            raise ValueError("r must be frank's collocation radii for (Rmax, N): build models with "
                             "fit_axisymmetric or AxisymmetricModel.from_profile")

    # --- construction --------------------------------------------------------------------
    @classmethod
    def from_profile(cls, profile: Callable[[np.ndarray], np.ndarray], geometry: DiscGeometry | None = None,
                     *, N: int = DEFAULT_HYPERPARAMETERS["N"], Rmax: float = DEFAULT_HYPERPARAMETERS["Rmax"],
                     ) -> "AxisymmetricModel":
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

    def nonnegative(self) -> "AxisymmetricModel":
        """The same model with the non-negative profile ``I_nonneg`` as its brightness."""
        if self.I_nonneg is None:
            raise ValueError("this model has no non-negative profile: fit with nonnegative=True")
        return replace(self, I=self.I_nonneg, I_err=None,
                       hyperparameters={**self.hyperparameters, "profile": "nonnegative"})

    def with_geometry(self, geometry: DiscGeometry) -> "AxisymmetricModel":
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
            raise ValueError("radii must be finite and >= 0 arcsec")
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
            raise ValueError(f"fraction = {fraction!r} must lie in (0, 1)")
        r, F = self.cumulative_flux()
        if F[-1] <= 0:
            raise ValueError("the profile has no positive total flux: R_eff is undefined")
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
        ny, nx = (int(shape), int(shape)) if np.isscalar(shape) else (int(shape[0]), int(shape[1]))
        if ny < 1 or nx < 1:
            raise ValueError(f"image shape {shape!r} must be positive")
        if not (np.isfinite(pixel_size) and pixel_size > 0):
            raise ValueError(f"pixel_size = {pixel_size!r} arcsec must be positive")
        if isinstance(oversample, bool) or int(oversample) != oversample or oversample < 1:
            raise ValueError(f"oversample = {oversample!r} must be an integer >= 1")
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
        import h5py

        path = Path(path)
        with atomic_path(path) as tmp:
            with h5py.File(tmp, "w") as f:
                f.attrs["kind"] = _HDF5_KIND
                f.attrs["Rmax"] = self.Rmax
                f.attrs["frank_version"] = self.frank_version or ""
                f.attrs["fit_time_s"] = np.nan if self.fit_time_s is None else float(self.fit_time_s)
                f.attrs["hyperparameters"] = json.dumps(self.hyperparameters, default=json_default)
                f.attrs["provenance"] = json.dumps(self.provenance, default=json_default)
                f.attrs["saved_by"] = json.dumps(provenance_record(), default=json_default)
                g = f.create_group("geometry")
                for key, value in self.geometry.to_dict().items():
                    g.attrs[key] = value
                units = {"r": "arcsec", "I": "Jy/sr", "I_err": "Jy/sr", "I_nonneg": "Jy/sr"}
                for name, unit in units.items():
                    arr = getattr(self, name)
                    if arr is not None:
                        f.create_dataset(name, data=arr).attrs["unit"] = unit
        log.info("saved axisymmetric model to %s", path)
        return path

    @classmethod
    def load(cls, path) -> "AxisymmetricModel":
        """Read a model written by :meth:`save`."""
        import h5py

        path = Path(path)
        if not path.exists():
            raise FileNotFoundError(f"no axisymmetric model file at {path}")
        with h5py.File(path, "r") as f:
            kind = f.attrs.get("kind", "")
            if kind != _HDF5_KIND:
                raise ValueError(f"{path} is not a spiralbayes axisymmetric model (kind = {kind!r})")
            geometry = DiscGeometry(**{k: float(f["geometry"].attrs[k]) for k in ("inc", "PA", "dRA", "dDec")})
            arrays = {name: (f[name][()] if name in f else None) for name in ("r", "I", "I_err", "I_nonneg")}
            fit_time = float(f.attrs["fit_time_s"])
            return cls(geometry=geometry, Rmax=float(f.attrs["Rmax"]),
                       hyperparameters=json.loads(f.attrs["hyperparameters"]),
                       frank_version=str(f.attrs["frank_version"]) or None,
                       fit_time_s=None if np.isnan(fit_time) else fit_time,
                       provenance=json.loads(f.attrs["provenance"]), **arrays)


# ---------------------------------------------------------------------------------------------
def _to_frank_geometry(geometry: DiscGeometry):
    from frank.geometry import FixedGeometry

    return FixedGeometry(geometry.inc, geometry.PA, geometry.dRA, geometry.dDec)


def _from_frank_geometry(frank_geometry) -> DiscGeometry:
    return DiscGeometry(float(frank_geometry.inc), float(frank_geometry.PA) % 180.0,
                        float(frank_geometry.dRA), float(frank_geometry.dDec))


def _fit_geometry(vis: Visibilities, method: str, guess: DiscGeometry | None, Rmax: float) -> DiscGeometry:
    """Fit ``(inc, PA, dRA, dDec)`` with one of frank's geometry fitters."""
    from frank.geometry import FitGeometryFourierBessel, FitGeometryGaussian

    if method == "nonparametric" and guess is None:
        # From frank's default start (inc = PA = 10 deg) the Fourier-Bessel fit often stalls
        # at inc ~ 0; the Gaussian fit is a cheap, reliable starting point.
        guess = _fit_geometry(vis, "gaussian", None, Rmax)
        log.info("nonparametric geometry fit starts from the Gaussian fit's geometry")
    guess_list = None if guess is None else [guess.inc, guess.PA, guess.dRA, guess.dDec]
    if method == "gaussian":
        fitter = FitGeometryGaussian(guess=guess_list)
    else:
        fitter = FitGeometryFourierBessel(Rmax, 20, guess=guess_list)
    fitter.fit(vis.u, vis.v, vis.V, vis.weights)
    try:
        return _from_frank_geometry(fitter)
    except ValueError as exc:
        raise RuntimeError(f"frank's {method} geometry fit gave an unusable geometry "
                           f"(inc={fitter.inc}, PA={fitter.PA}): {exc}; give the geometry instead") from None


def _blas_threads(n: int | None):
    """Limit BLAS threads to ``n`` during frank's iterations (needs threadpoolctl; else no-op).

    frank's iterations multiply N x N matrices a few hundred times; BLAS threads buy nothing
    at N = 200 and, on a busy machine, spin-waiting threads made a fit 6-8x slower (measured on
    2 cores with other work running: 36-50 s instead of 6 s).
    """
    if n is None:
        return contextlib.nullcontext()
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        log.debug("threadpoolctl not installed: BLAS threads not limited")
        return contextlib.nullcontext()
    return threadpool_limits(limits=int(n), user_api="blas")


class _IterationProgress:
    """Count frank's power-spectrum iterations on a tqdm bar (wraps the fitter's solve step)."""

    def __init__(self, fitter, enabled: bool):
        self.fitter = fitter
        self.enabled = enabled
        self.bar = None

    def __enter__(self):
        from tqdm.auto import tqdm

        self.bar = tqdm(desc="frank iterations", unit="it", disable=not self.enabled, leave=False,
                        mininterval=0.5)
        original = getattr(self.fitter, "_perform_fit", None)
        if original is not None:
            def counted(*args, **kwargs):
                self.bar.update(1)
                return original(*args, **kwargs)

            self.fitter._perform_fit = counted
        return self

    def __exit__(self, *exc):
        self.bar.close()
        self.fitter.__dict__.pop("_perform_fit", None)
        return False


def fit_axisymmetric(vis: Visibilities, geometry: DiscGeometry | None = None, *,
                     N: int = DEFAULT_HYPERPARAMETERS["N"], Rmax: float = DEFAULT_HYPERPARAMETERS["Rmax"],
                     alpha: float = DEFAULT_HYPERPARAMETERS["alpha"], p0: float = DEFAULT_HYPERPARAMETERS["p0"],
                     weights_smooth: float = DEFAULT_HYPERPARAMETERS["weights_smooth"],
                     nonnegative: bool = False, fit_geometry: str | None = None, method: str = "Normal",
                     max_iter: int = 2000, convergence_failure: str = "raise",
                     progress: bool = True, blas_threads: int | None = 1) -> AxisymmetricModel:
    """Fit an axisymmetric brightness profile to visibilities with frank.

    Parameters
    ----------
    vis : Visibilities
        The data (standardised to the frank convention first).
    geometry : DiscGeometry, optional
        Disc geometry. If given and ``fit_geometry`` is None it is held fixed; if given with
        ``fit_geometry`` it is the geometry fit's starting point.
    N : int
        Number of collocation points (Fourier–Bessel terms).
    Rmax : float
        Outer radius of the fit [arcsec]; the brightness is zero beyond it.
    alpha, p0, weights_smooth : float
        frank's power-spectrum prior: inverse-gamma order and scale [Jy^2], and the spectral
        smoothness weight.
    nonnegative : bool
        Also compute frank's non-negative best fit (``I_nonneg``).
    fit_geometry : {"gaussian", "nonparametric"}, optional
        Fit ``(inc, PA, dRA, dDec)`` with frank's ``FitGeometryGaussian`` or
        ``FitGeometryFourierBessel`` (N = 20, as frank's own pipeline) before the profile.
        Default: "gaussian" when no ``geometry`` is given, else none. Measured on a synthetic
        core + ring disc (1e4 random baselines, 4 noise seeds): the Gaussian fit's PA was off by
        up to 1.4 deg (its profile does not match a ringed disc); the nonparametric fit, started
        from the Gaussian one, by <= 0.65 deg, with offsets within 1.3 mas.
    method : {"Normal", "LogNormal"}
        frank's brightness model.
    max_iter : int
        Maximum number of power-spectrum iterations.
    convergence_failure : {"raise", "warn", "ignore"}
        What to do when frank has not converged after ``max_iter`` iterations.
    progress : bool
        Show a tqdm counter of frank's iterations.
    blas_threads : int, optional
        BLAS threads during the fit (via threadpoolctl when installed); None leaves them alone.
        One is fastest for N ~ 200 (see ``_blas_threads``).

    Returns
    -------
    AxisymmetricModel
        With ``fit_time_s`` the total wall-clock time [s] and the geometry-fit time, iteration
        count and a hash of the data in ``provenance``.
    """
    from frank.radial_fitters import FrankFitter

    if not isinstance(vis, Visibilities):
        raise TypeError(f"vis must be a spiralbayes Visibilities, got {type(vis).__name__}")
    _check_hyperparameters(N, Rmax, alpha, p0, weights_smooth)
    if method not in ("Normal", "LogNormal"):
        raise ValueError(f"method = {method!r}: frank's brightness models are 'Normal' and 'LogNormal'")
    if convergence_failure not in ("raise", "warn", "ignore"):
        raise ValueError(f"convergence_failure = {convergence_failure!r} must be 'raise', 'warn' or 'ignore'")
    if geometry is not None and not isinstance(geometry, DiscGeometry):
        raise TypeError(f"geometry must be a DiscGeometry, got {type(geometry).__name__}")
    if geometry is None and fit_geometry is None:
        fit_geometry = "gaussian"
    if fit_geometry is not None and fit_geometry not in GEOMETRY_FITTERS:
        raise ValueError(f"fit_geometry = {fit_geometry!r} must be one of {GEOMETRY_FITTERS} or None")
    vis = vis.standardised()

    t0 = time.perf_counter()
    geometry_time = 0.0
    if fit_geometry is not None:
        log.info("fitting the disc geometry with frank (%s) to %d visibilities", fit_geometry, vis.n)
        geometry = _fit_geometry(vis, fit_geometry, geometry, Rmax)
        geometry_time = time.perf_counter() - t0
        log.info("fitted geometry in %.1f s: inc = %.3f deg, PA = %.3f deg, dRA = %.2f mas, dDec = %.2f mas",
                 geometry_time, geometry.inc, geometry.PA, geometry.dRA * 1e3, geometry.dDec * 1e3)

    _check_baselines(vis, geometry, N, Rmax)
    log.info("fitting frank profile: N = %d, Rmax = %g arcsec, alpha = %g, p0 = %g Jy^2, weights_smooth = %g, "
             "%d visibilities", N, Rmax, alpha, p0, weights_smooth, vis.n)
    fitter = FrankFitter(Rmax, int(N), _to_frank_geometry(geometry), alpha=alpha, p_0=p0,
                         weights_smooth=weights_smooth, method=method, max_iter=max_iter,
                         store_iteration_diagnostics=True, verbose=False, convergence_failure="ignore")
    with _IterationProgress(fitter, progress), _blas_threads(blas_threads), warnings.catch_warnings():
        # frank 1.2 hands scipy's spsolve a non-CSC matrix at every iteration: harmless, noisy
        warnings.filterwarnings("ignore", message="spsolve requires A be CSC or CSR")
        sol = fitter.fit(vis.u, vis.v, vis.V, vis.weights)
    n_iter = int(fitter.iteration_diagnostics["num_iterations"])
    converged = n_iter <= max_iter
    if not converged:
        msg = (f"frank did not converge within max_iter = {max_iter} iterations; increase max_iter, "
               "or alpha (convergence is slow for alpha close to 1)")
        if convergence_failure == "raise":
            raise RuntimeError(msg + "; or pass convergence_failure='warn' to keep the last iterate")
        if convergence_failure == "warn":
            log.warning(msg)

    I_err = None
    if method == "Normal":
        I_err = np.sqrt(np.clip(np.diag(sol.covariance), 0.0, None))
    I_nonneg = np.asarray(sol.solve_non_negative(), dtype=float) if nonnegative else None
    fit_time = time.perf_counter() - t0
    log.info("frank fit done in %.2f s (%d iterations%s)", fit_time, n_iter, "" if converged else ", not converged")

    hyper = {"N": int(N), "Rmax": float(Rmax), "alpha": float(alpha), "p0": float(p0),
             "weights_smooth": float(weights_smooth), "method": method, "nonnegative": bool(nonnegative),
             "fit_geometry": fit_geometry, "max_iter": int(max_iter), "assume_optically_thick": True}
    provenance = {"n_vis": int(vis.n), "data_hash": data_hash(vis.u, vis.v, vis.V, vis.weights),
                  "data_provenance": vis.provenance, "iterations": n_iter, "converged": bool(converged),
                  "geometry_fit_time_s": geometry_time, **provenance_record()}
    return AxisymmetricModel(r=np.asarray(sol.r), I=np.asarray(sol.I), geometry=geometry, Rmax=Rmax,
                             hyperparameters=hyper, I_err=I_err, I_nonneg=I_nonneg,
                             frank_version=_frank_version(), fit_time_s=fit_time, provenance=provenance,
                             frank_solution=sol)


def _check_baselines(vis: Visibilities, geometry: DiscGeometry, N: int, Rmax: float) -> None:
    """frank needs its largest collocation frequency above the longest deprojected baseline."""
    from frank.hankel import DiscreteHankelTransform

    up, vp = geometry.deproject_uv(vis.u, vis.v)
    q_max = float(np.max(np.hypot(up, vp)))
    q_last = float(DiscreteHankelTransform(Rmax * ARCSEC, int(N)).q[-1])
    if q_last < q_max:
        n_needed = int(np.ceil(N * q_max / q_last)) + 1
        raise ValueError(f"the longest deprojected baseline ({q_max:.4g} lambda) lies beyond frank's last "
                         f"collocation frequency ({q_last:.4g} lambda) for N = {N}, Rmax = {Rmax} arcsec: "
                         f"increase N to about {n_needed}, or cut the long baselines")


# ---------------------------------------------------------------------------------------------
def run_axisym(vis: Visibilities, out_dir, geometry: DiscGeometry | None = None, *,
               distance: float | None = None, bin_width: float = 20e3, prefix: str = "axisym",
               **fit_kwargs) -> AxisymmetricModel:
    """Fit, then write the model (HDF5) and plots of the profile and binned visibilities.

    Parameters
    ----------
    vis : Visibilities
        The data.
    out_dir : path
        Output folder (created if missing).
    geometry : DiscGeometry, optional
        Passed to :func:`fit_axisymmetric`.
    distance : float, optional
        Source distance [pc], for an au axis on the profile plot.
    bin_width : float
        Width of the uv-distance bins in the visibility plot [lambda].
    prefix : str
        Stem of the output file names: ``{prefix}_model.h5``, ``{prefix}_profile.png``,
        ``{prefix}_visibilities.png``.
    **fit_kwargs
        Passed to :func:`fit_axisymmetric`.
    """
    import matplotlib.pyplot as plt

    from .plotting.axisymmetric import plot_binned_visibilities, plot_profile

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    model = fit_axisymmetric(vis, geometry, **fit_kwargs)
    written = [model.save(out_dir / f"{prefix}_model.h5")]
    figures = {
        f"{prefix}_profile.png": plot_profile(model, distance=distance),
        f"{prefix}_visibilities.png": plot_binned_visibilities(vis, model, bin_width=bin_width),
    }
    for name, fig in figures.items():
        path = out_dir / name
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format="png", dpi=150)
        plt.close(fig)
        written.append(path)
    for path in written:
        log.info("wrote %s", path)
    return model
