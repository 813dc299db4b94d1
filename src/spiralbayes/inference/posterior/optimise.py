"""Finding the posterior's modes before sampling: the disc's geometry first, then the planet.

1. **The no-planet mode** (:func:`fit_null_geometry`): the geometry ``(inc, PA, dRA, dDec)`` that
   maximises the profile-marginalised disc likelihood times the geometry prior. The profile is
   refitted at every trial geometry inside the likelihood, so a frank fit made at a wrong
   geometry (3 deg off in inclination, the case of Stevenson et al. 2024, appendix A) does not
   pin the geometry to itself.
2. **The planet** (:func:`find_map`): at that geometry, the scan's best ``(r_p, phi_p)`` (when a
   scan is given) and a coarse grid over the prior are ranked by the spiral posterior; the best
   few distinct ones are optimised, first in ``(r_p, phi_p)`` alone, then jointly with the
   geometry. Starting from the disc's own geometry avoids the local modes where a planet absorbs
   a geometry error (appendix A).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ...units import TWO_PI, wrap_angle
from .evidence import _call, hessian_cov
from .priors import Priors

__all__ = ["find_map", "fit_null_geometry"]

log = logging.getLogger(__name__)


def _value(out) -> float:
    return float(out[0] if isinstance(out, tuple) else out)


def _nelder_mead(f, x0: np.ndarray, steps: np.ndarray, max_evals: int, restarts: int = 3) -> np.ndarray:
    """Maximise ``f`` by Nelder–Mead in units of ``steps``, restarting with a smaller simplex.

    Converged when the simplex has shrunk below 1e-3 step and ``f`` varies by < 1e-3 over it.
    """
    from scipy.optimize import minimize

    x = np.array(x0, dtype=float)
    scale = np.asarray(steps, dtype=float)

    def neg(z):
        v = f(x_ref + z * scale)
        return -v if np.isfinite(v) else 1e300

    size = 1.0
    for _ in range(restarts):
        x_ref = x.copy()
        simplex = np.vstack([np.zeros(x.size), size * np.eye(x.size)])
        res = minimize(neg, np.zeros(x.size), method="Nelder-Mead",
                       options={"initial_simplex": simplex, "maxfev": max_evals, "xatol": 1e-3, "fatol": 1e-3})
        x = x_ref + res.x * scale
        if np.all(np.abs(res.x) < 0.05 * size):
            break
        size *= 0.3
    return x


def fit_null_geometry(null_log_likelihood, priors: Priors, *, max_evals: int = 1500):
    """The no-planet posterior's mode and Laplace covariance.

    Parameters
    ----------
    null_log_likelihood : callable
        ``ln L(inc, PA, dRA, dDec)`` of the disc alone (profile marginalised).
    priors : Priors

    Returns
    -------
    (g_map, covariance, ln_posterior_at_map)
    """
    def lp(g):
        prior = priors.log_prior_geometry(g)
        return prior + null_log_likelihood(g) if np.isfinite(prior) else -np.inf

    g = _nelder_mead(lp, priors.geometry_centre, priors.geometry_widths * 0.2, max_evals)
    room = np.array([min(g[0], 90.0 - g[0]) * 0.9, np.inf, np.inf, np.inf])
    cov = hessian_cov(lp, g, priors.geometry_widths * 0.01, room=room, max_var=priors.geometry_widths ** 2)
    return g, cov, lp(g)


def _start_points(priors: Priors, scan, template_name: str, geometry: np.ndarray, n_scan: int = 8):
    """The scan's best ``(r_p, phi_p)`` instances, then a coarse grid, all at ``geometry``."""
    cands = []
    if scan is not None:
        try:
            k = scan.template_index(template_name)
        except (KeyError, IndexError):
            k = None
        if k is not None:
            dchi2 = scan.delta_chi2()[k]
            order = np.argsort(np.nan_to_num(dchi2, nan=-np.inf), axis=None)[::-1]
            lo, hi = priors.r_p
            for flat in order:
                i, j = np.unravel_index(flat, dchi2.shape)
                if lo <= scan.r_p[i] <= hi:
                    cands.append((float(scan.r_p[i]), float(wrap_angle(scan.phi_p[j], 0.0))))
                if len(cands) >= n_scan:
                    break
    lo, hi = priors.r_p
    for r in np.linspace(lo, hi, 14)[1:-1]:
        for phi in np.linspace(0, TWO_PI, 36, endpoint=False):
            cands.append((float(r), float(phi)))
    return [np.concatenate([[r, phi], geometry]) for r, phi in cands]


@dataclass(frozen=True)
class _LocalOptimum:
    """One start's optimum: ``(r_p, phi_p)`` alone at the start's geometry, then all six jointly.

    A picklable task (pools send it to their workers); ``log_prob`` is what the pool evaluates.
    """

    log_prob: Callable
    span: float
    geometry_sigma: tuple

    def __call__(self, start: np.ndarray) -> np.ndarray:
        f = lambda t: _value(self.log_prob(t))  # noqa: E731
        planet = _nelder_mead(lambda p: f(np.concatenate([p, start[2:]])), start[:2],
                              np.array([0.02 * self.span, 0.05]), 120, restarts=1)
        x = np.concatenate([planet, start[2:]])
        steps = np.concatenate([[0.01 * self.span, 0.02], 3.0 * np.asarray(self.geometry_sigma, float)])
        return _nelder_mead(f, x, steps, 500, restarts=2)


def find_map(logpost, priors: Priors, scan, name: str, geometry: np.ndarray, geometry_sigma: np.ndarray,
             n_starts: int = 2, *, pool_map=None, pool_log_prob=None) -> np.ndarray:
    """The best optimum of the spiral posterior over ``(r_p, phi_p, inc, PA, dRA, dDec)``.

    Parameters
    ----------
    logpost : callable
        ``ln(L pi)`` (may return ``(value, blob)``).
    geometry, geometry_sigma : ndarray
        The no-planet mode and its posterior widths (start and simplex scale of the geometry).
    pool_map, pool_log_prob : callable, optional
        A pool's ``map(fn, iterable)`` and the function its workers evaluate for ``logpost``
        (:class:`.chain_runner.WalkerPool`): the start points are ranked, and the ``n_starts``
        optimisations run, in the pool. The optimum is the same as without one.
    """
    f = lambda t: _value(logpost(t))  # noqa: E731
    mapper = pool_map or map
    worker_fn = pool_log_prob or logpost
    starts = _start_points(priors, scan, name, geometry)
    values = np.array(list(mapper(_call, [(worker_fn, s) for s in starts])), dtype=float)
    order = np.argsort(np.where(np.isfinite(values), values, -np.inf))[::-1]
    span = priors.r_p[1] - priors.r_p[0]
    chosen: list = []
    for i in order:
        s = starts[i]
        if all(abs(s[0] - c[0]) > 0.05 * span or abs(wrap_angle(s[1] - c[1])) > 0.3 for c in chosen):
            chosen.append(s)
        if len(chosen) >= n_starts:
            break
    optima = list(mapper(_LocalOptimum(worker_fn, float(span), tuple(np.asarray(geometry_sigma, float))), chosen))
    lps = [f(o) for o in optima]
    best = int(np.argmax(lps))
    log.info("%s: optima from %d starts, ln p = %s", name, len(optima), np.round(lps, 2).tolist())
    out = optima[best].copy()
    out[1] = wrap_angle(out[1], 0.0)
    return out


def _scales(priors: Priors, null):
    """Optimiser/Hessian scales and flat-direction variances of ``(r_p, phi_p, inc, PA, dRA, dDec)``."""
    g_sigma = np.sqrt(np.clip(np.diag(null.covariance), 1e-30, None))
    span = priors.r_p[1] - priors.r_p[0]
    scales = np.concatenate([[span / np.sqrt(12.0), np.pi / np.sqrt(3.0)], g_sigma * 10])
    max_var = np.concatenate([[span ** 2 / 12.0, np.pi ** 2 / 3.0], priors.geometry_widths ** 2])
    return g_sigma, scales, max_var
