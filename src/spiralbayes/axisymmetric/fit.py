"""Fitting the axisymmetric profile (and optionally the geometry) with frank."""

from __future__ import annotations

import contextlib
import io
import logging
import time
import warnings
from typing import Any

import numpy as np

from .._provenance import data_hash, provenance_record
from .._threads import blas_threads as _limit_blas  # the parameter is called blas_threads
from ..exceptions import ConvergenceError, DataWarning, InputError
from ..geometry import DiscGeometry
from ..io.data_checks import MIN_SEARCH_VISIBILITIES
from ..settings import with_overrides
from ..units import ARCSEC
from ..visibilities import Visibilities
from .model import DEFAULT_HYPERPARAMETERS, AxisymmetricModel, _frank_version
from .settings import GEOMETRY_FITTERS, FrankSettings

__all__ = ["GEOMETRY_FITTERS", "fit_axisymmetric"]

log = logging.getLogger(__name__)
SPARSE_MARGIN = 1.25
"""For sparse data the default N covers the longest deprojected baseline with this margin."""


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


class _IterationProgress:
    """Count frank's power-spectrum iterations on a tqdm bar (wraps the fitter's solve step)."""

    def __init__(self, fitter, enabled: bool):
        self.fitter = fitter
        self.enabled = enabled
        self.bar: Any = None  # the tqdm bar while the fit runs

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
                     settings: FrankSettings | None = None, progress: bool = True,
                     **overrides) -> AxisymmetricModel:
    """Fit an axisymmetric brightness profile to visibilities with frank.

    Parameters
    ----------
    vis : Visibilities
        The data (standardised to the frank convention first).
    geometry : DiscGeometry, optional
        Disc geometry. If given and ``settings.fit_geometry`` is None it is held fixed; if given with
        ``fit_geometry`` it is the geometry fit's starting point.
    settings : FrankSettings, optional
        frank's hyperparameters and how to fit (default ``FrankSettings()``, the paper's values).
    progress : bool
        Show a tqdm counter of frank's iterations.
    **overrides
        Fields of :class:`~spiralbayes.axisymmetric.FrankSettings` replacing those of ``settings``
        (e.g. ``N=100``):

        N : int, optional
            Number of collocation points (Fourier–Bessel terms). Default: the paper's 200, or for
            sparse data (fewer visibilities than 200) the smallest N whose last collocation frequency
            covers the longest deprojected baseline, times ``SPARSE_MARGIN`` (see Notes).
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
        tol : float
            frank's convergence tolerance: the iterations stop when no power-spectrum coefficient
            changes by more than this fraction.
        convergence_failure : {"raise", "warn", "ignore"}
            What to do when frank has not converged after ``max_iter`` iterations.
        blas_threads : int, optional
            BLAS threads during the fit (threadpoolctl); None leaves them alone.
            One is fastest for N ~ 200 (see ``blas_threads``).

    Returns
    -------
    AxisymmetricModel
        With ``fit_time_s`` the total wall-clock time [s] and the geometry-fit time, iteration
        count and a hash of the data in ``provenance``.

    Notes
    -----
    Why frank iterates hundreds of times, whatever the number of visibilities: its power-spectrum
    update (Jennings et al. 2020, eq. 17-19) moves every coefficient the data do not constrain
    towards the prior's ``p0`` by a factor of about ``exp(-(alpha - 1))`` per iteration, so with
    the paper's ``alpha = 1.05`` it takes ``~ln(p_start / p0) / 0.05 ~ 500`` iterations to settle,
    and the profile keeps moving until then. Each iteration costs O(N^3), independent of the
    number of visibilities. Measured (2 busy cores; AS 209's 196 visibilities, frank's geometry)::

        ========================== ========== ======= ================ ======================
        setting                    iterations  time    max |dI| / I_max  sqrt(sum w |dV_A|^2)
        ========================== ========== ======= ================ ======================
        N = 200 (paper)              743        64 s    (reference)      (reference)
        N = 100                      793        11 s    0.3 %            0.21
        N = 80                       764         8 s    0.8 %            0.50
        N = 200, tol = 1e-2          544        44 s    < 0.01 %         0.005
        N = 200, stopped at 200      200       ~17 s    5.6 %            2.9
        N = 200, alpha = 1.3         195        16 s    (another prior: chi2 473 instead of 456)
        ========================== ========== ======= ================ ======================

    The fiducial simulation (36k visibilities) took 561 iterations at N = 200. So for sparse
    data, whose longest baseline needs far fewer collocation points than 200, the default N is
    the data's own (about 5x faster, profile within ~1 % of N = 200); giving an N larger than the
    number of visibilities raises a DataWarning with that suggestion. Stopping early
    (``max_iter`` with ``convergence_failure="warn"``) is not a good trade: the profile has not
    settled (5.6 % at 200 iterations).

    Examples
    --------
    >>> import spiralbayes as sb
    >>> vis = sb.simulate_observation("taurus", seed=1)
    >>> disc = sb.fit_axisymmetric(vis, sb.DiscGeometry(inc=30, PA=60), progress=False, N=100)
    >>> print(f"{disc.total_flux:.3f} Jy")
    0.226 Jy

    Leave out the geometry to fit it first (``fit_geometry="gaussian"``); ``N=100`` here only makes the
    example quick (the default is the paper's 200).
    """
    from frank.radial_fitters import FrankFitter

    s = with_overrides(settings, FrankSettings, overrides, "fit_axisymmetric")
    N, Rmax, alpha, p0, weights_smooth = s.N, s.Rmax, s.alpha, s.p0, s.weights_smooth
    nonnegative, fit_geometry, method, max_iter, tol = s.nonnegative, s.fit_geometry, s.method, s.max_iter, s.tol
    if not isinstance(vis, Visibilities):
        raise TypeError(f"vis must be a spiralbayes Visibilities, got {type(vis).__name__}")
    check_enough_visibilities(vis)
    if geometry is not None and not isinstance(geometry, DiscGeometry):
        raise TypeError(f"geometry must be a DiscGeometry, got {type(geometry).__name__}")
    if geometry is None and fit_geometry is None:
        fit_geometry = "gaussian"
    vis = vis.standardised()

    t0 = time.perf_counter()
    geometry_time = 0.0
    if fit_geometry is not None:
        log.info("fitting the disc geometry with frank (%s) to %d visibilities", fit_geometry, vis.n)
        geometry = _fit_geometry(vis, fit_geometry, geometry, Rmax)
        geometry_time = time.perf_counter() - t0
        log.info("fitted geometry in %.1f s: inc = %.3f deg, PA = %.3f deg, dRA = %.2f mas, dDec = %.2f mas",
                 geometry_time, geometry.inc, geometry.PA, geometry.dRA * 1e3, geometry.dDec * 1e3)
    assert geometry is not None  # given, or fitted above (fit_geometry is set when it is not given)

    N = _collocation_count(vis, geometry, Rmax, N)
    _check_baselines(vis, geometry, N, Rmax)
    log.info("fitting frank profile: N = %d, Rmax = %g arcsec, alpha = %g, p0 = %g Jy^2, weights_smooth = %g, "
             "%d visibilities", N, Rmax, alpha, p0, weights_smooth, vis.n)
    fitter = FrankFitter(Rmax, int(N), _to_frank_geometry(geometry), alpha=alpha, p_0=p0,
                         weights_smooth=weights_smooth, method=method, max_iter=max_iter, tol=tol,
                         store_iteration_diagnostics=True, verbose=False, convergence_failure="ignore")
    with _IterationProgress(fitter, progress), _limit_blas(s.blas_threads), _frank_quiet():
        try:
            sol = fitter.fit(vis.u, vis.v, vis.V, vis.weights)
        except ValueError as exc:
            if "power spectrum" not in str(exc):
                raise
            raise InputError(_bad_power_spectrum_message(vis, N, Rmax, p0)) from None
    n_iter = int(fitter.iteration_diagnostics["num_iterations"])
    converged = n_iter <= max_iter
    if not converged:
        msg = _no_convergence_message(vis, N, Rmax, max_iter, alpha)
        if s.convergence_failure == "raise":
            raise ConvergenceError(msg + "; fit_axisymmetric(..., max_iter=..., convergence_failure='warn') keeps "
                                   "the last iterate")
        if s.convergence_failure == "warn":
            log.warning(msg)

    I_err = None
    if method == "Normal":
        I_err = np.sqrt(np.clip(np.diag(sol.covariance), 0.0, None))
    I_nonneg = np.asarray(sol.solve_non_negative(), dtype=float) if nonnegative else None
    fit_time = time.perf_counter() - t0
    log.info("frank fit done in %.2f s (%d iterations%s)", fit_time, n_iter, "" if converged else ", not converged")

    hyper = {"N": int(N), "Rmax": float(Rmax), "alpha": float(alpha), "p0": float(p0),
             "weights_smooth": float(weights_smooth), "method": method, "nonnegative": bool(nonnegative),
             "fit_geometry": fit_geometry, "max_iter": int(max_iter), "tol": float(tol),
             "assume_optically_thick": True}
    provenance = {"n_vis": int(vis.n), "data_hash": data_hash(vis.u, vis.v, vis.V, vis.weights),
                  "data_provenance": vis.provenance, "iterations": n_iter, "converged": bool(converged),
                  "geometry_fit_time_s": geometry_time, **provenance_record()}
    return AxisymmetricModel(r=np.asarray(sol.r), I=np.asarray(sol.I), geometry=geometry, Rmax=Rmax,
                             hyperparameters=hyper, I_err=I_err, I_nonneg=I_nonneg,
                             frank_version=_frank_version(), fit_time_s=fit_time, provenance=provenance,
                             frank_solution=sol,
                             power_spectrum=_power_spectrum(sol) if method == "Normal" else None)


def check_enough_visibilities(vis, minimum: int = MIN_SEARCH_VISIBILITIES) -> None:
    """Refuse fewer than ``minimum`` visibilities for a frank fit, saying why.

    The profile feeds a search, which needs :data:`~spiralbayes.io.data_checks.MIN_SEARCH_VISIBILITIES`;
    below that the fit itself is not a measurement: on random subsets of the AS 209 sample, 2-5
    visibilities gave a negative or zero total flux in 5 of 12 fits, 8-15 gave 0.17-1.6 Jy
    (all 196: 0.25 Jy).
    """
    n = int(getattr(vis, "n", 0))
    if n < minimum:
        raise InputError(f"only {n} visibilities: frank's profile needs at least {minimum} (MIN_SEARCH_VISIBILITIES; "
                         "with fewer, the profile is set by its prior, not the data, and its flux can come out "
                         "negative) — use the full, unbinned data")


@contextlib.contextmanager
def _frank_quiet():
    """frank's own output off: its messages name frank's options and source lines, not ours.

    frank 1.2 hands scipy's spsolve a non-CSC matrix at every iteration (a harmless warning);
    when its power spectrum overflows it warns from ``np.exp(tau)`` (printed with that source
    line), prints the whole spectrum and raises naming its own options (``rout``, ``n``): the
    caller turns that into one line naming ours (:func:`_bad_power_spectrum_message`).
    """
    with warnings.catch_warnings(), np.errstate(over="ignore", invalid="ignore", divide="ignore"), \
            contextlib.redirect_stdout(io.StringIO()):
        warnings.filterwarnings("ignore", message="spsolve requires A be CSC or CSR")
        yield


def _bad_power_spectrum_message(vis: Visibilities, N: int, Rmax: float, p0: float) -> str:
    return (f"frank's power spectrum became NaN/inf fitting {vis.n} visibilities: check the data's units and "
            "weights (V in Jy, weights 1/sigma^2 in Jy^-2; [data] estimate_weights = true re-estimates them), "
            "the geometry and phase centre ([geometry] inc, PA, dRA, dDec), residual antenna gain errors "
            "(self-calibrate; sb.diagnose_calibration measures them), and [frank] Rmax = "
            f"{Rmax:g} arcsec (larger than the disc), N = {N}, p0 = {p0:g} Jy^2 (default 1e-15)")


def _no_convergence_message(vis: Visibilities, N: int, Rmax: float, max_iter: int, alpha: float) -> str:
    return (f"frank did not converge within max_iter = {max_iter} iterations fitting {vis.n} visibilities: most "
            "often the data's units or weights (V in Jy, weights 1/sigma^2 in Jy^-2; [data] estimate_weights = true "
            "re-estimates them), the geometry ([geometry] inc, PA, dRA, dDec) or residual antenna gain errors "
            "(self-calibrate; sb.diagnose_calibration measures them); else [frank] Rmax = "
            f"{Rmax:g} arcsec, N = {N}, alpha = {alpha:g} (convergence is slow for alpha close to 1)")


def _power_spectrum(sol):
    """frank's MAP power spectrum [Jy^2] of the brightness (None when frank has none)."""
    p = getattr(sol, "power_spectrum", None)
    return None if p is None else np.asarray(p, dtype=float).ravel()


def _minimum_collocation_count(vis: Visibilities, geometry: DiscGeometry, Rmax: float) -> int:
    """The smallest N whose last collocation frequency ``j_N / (2 pi Rmax)`` covers the longest
    deprojected baseline (``j_N ~ pi (N - 1/4)``, the N-th zero of J0)."""
    up, vp = geometry.deproject_uv(vis.u, vis.v)
    q_max = float(np.max(np.hypot(up, vp)))
    return int(np.ceil(2 * Rmax * ARCSEC * q_max + 0.25)) + 1


def _collocation_count(vis: Visibilities, geometry: DiscGeometry, Rmax: float, N: int | None) -> int:
    """N as given (with a warning when it exceeds the number of visibilities), or the default."""
    default = DEFAULT_HYPERPARAMETERS["N"]
    needed = _minimum_collocation_count(vis, geometry, Rmax)
    sparse = min(default, max(int(np.ceil(SPARSE_MARGIN * needed)), 10))
    if N is None:
        if vis.n >= default:
            return default
        log.info("sparse data (%d visibilities < %d): frank N = %d covers the longest baseline (see "
                 "fit_axisymmetric's notes)", vis.n, default, sparse)
        return sparse
    if vis.n < N and sparse < N:
        warnings.warn(f"frank's N = {N} exceeds the {vis.n} visibilities: the extra coefficients are set by the "
                      f"prior alone while each of frank's ~500-800 iterations costs O(N^3); N = {sparse} covers the "
                      "longest baseline and fits ~5x faster with the profile within ~1 % "
                      "(leave N unset, or N = 0 in [frank], for that)",
                      DataWarning, stacklevel=3)
    return int(N)


def _check_baselines(vis: Visibilities, geometry: DiscGeometry, N: int, Rmax: float) -> None:
    """frank needs its largest collocation frequency above the longest deprojected baseline."""
    from frank.hankel import DiscreteHankelTransform

    up, vp = geometry.deproject_uv(vis.u, vis.v)
    q_max = float(np.max(np.hypot(up, vp)))
    q_last = float(DiscreteHankelTransform(Rmax * ARCSEC, int(N)).q[-1])
    if q_last < q_max:
        n_needed = int(np.ceil(N * q_max / q_last)) + 1
        raise InputError(f"the longest deprojected baseline ({q_max:.4g} lambda) lies beyond frank's last "
                         f"collocation frequency ({q_last:.4g} lambda) for N = {N}, Rmax = {Rmax} arcsec: "
                         f"increase N to about {n_needed}, or cut the long baselines")
