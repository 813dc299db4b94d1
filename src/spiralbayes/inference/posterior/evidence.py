"""Evidences of the spiral templates and of the no-planet hypothesis.

``Z = int L(theta) pi(theta) dtheta`` with the profile and the amplitude already integrated out
of ``L`` (:mod:`.likelihood`), so ``theta`` is ``(r_p, phi_p, inc, PA, dRA, dDec)`` for a template
and ``(inc, PA, dRA, dDec)`` for the disc alone. Estimators:

* **importance sampling with a defensive mixture** (the default when a chain exists;
  Hesterberg 1995, "Weighted average importance sampling and defensive mixture
  distributions"): draws from ``q = alpha q_chain + (1 - alpha) q_prior``, weights
  ``L pi / q`` ("balance heuristic": the draws of both components are pooled with the mixture
  density, which keeps the estimate unbiased). ``q_chain`` is a Student-t (5 degrees of freedom)
  fitted to the chain, periodic in ``phi_p``; ``q_prior`` draws ``(r_p, phi_p)`` from their prior
  and the geometry from the no-planet posterior. The second component is what makes the
  estimate robust where a Gaussian fit fails: on planet-free data ``(r_p, phi_p)`` are
  unconstrained and the posterior is the prior there, and a weak planet's posterior mixes a
  compact mode with that plateau. The error follows from the variance of the weights.
* **Laplace**: ``ln Z = ln(L pi)(theta*) + (d/2) ln 2 pi + (1/2) ln det Sigma`` at the optimum
  (finite-difference Hessian, eigenvalues floored so that flat directions get their prior
  width instead of an error): for templates pruned by the scan, and as a cross-check.
* **Savage–Dickey** (cross-check for the Bayes factor against no planet): the no-planet model is
  the spiral model at ``A = 0``, so ``Z_0 / Z_T = p(A = 0 | data) / pi(A = 0)``; ``A``'s
  conditional posterior is known exactly for every sample (:mod:`.likelihood`), so
  ``Z_T / Z_0 = 1 / mean_s[exp(-ln int L(A) dA / (A_max L(0)))]``. Reliable when the chain
  visits small ``A`` (weak or no planet); for strong planets it behaves like a harmonic mean and
  overestimates ``Z_T / Z_0`` — it is reported, not used.
"""

from __future__ import annotations

import logging

import numpy as np

from ...units import TWO_PI, wrap_angle
from .likelihood import log_amplitude_integral

__all__ = ["GaussianGeometry", "importance_evidence", "laplace_evidence", "savage_dickey_log_bayes"]

log = logging.getLogger(__name__)

T_DOF = 5.0


# ---------------------------------------------------------------------------------------------
# Hessians and the Laplace approximation
# ---------------------------------------------------------------------------------------------
def hessian_cov(f, x: np.ndarray, scales: np.ndarray, room: np.ndarray | None = None,
                max_var: np.ndarray | None = None) -> np.ndarray:
    """Covariance ``(-H)^-1`` of ``f`` at ``x`` from central differences (never raises).

    Steps are tuned so that ``f`` changes by ~0.5 along each axis and never go further than
    ``room`` (distance to a hard edge). Directions with curvature below ``1 / max_var`` (flat, or
    not negative definite) get variance ``max_var`` (default ``scales^2``): the prior width
    rather than a LinAlgError.
    """
    x = np.asarray(x, dtype=float)
    d = x.size
    room = np.full(d, np.inf) if room is None else np.asarray(room, dtype=float)
    max_var = np.asarray(scales, float) ** 2 if max_var is None else np.asarray(max_var, float)
    f0 = f(x)
    h = np.minimum(np.asarray(scales, float) * 1e-2, room)
    for i in range(d):
        for _ in range(10):
            e = np.zeros(d)
            e[i] = h[i]
            curv = f(x + e) + f(x - e) - 2 * f0
            if not np.isfinite(curv):
                h[i] *= 0.3
                continue
            if 0.1 < -curv < 2.0:
                break
            h[i] = min(h[i] * np.sqrt(0.5 / max(abs(curv), 1e-12)), scales[i] * 3, room[i])
    H = np.zeros((d, d))
    for i in range(d):
        for j in range(i, d):
            ei = np.zeros(d)
            ej = np.zeros(d)
            ei[i], ej[j] = h[i], h[j]
            if i == j:
                H[i, i] = (f(x + ei) + f(x - ei) - 2 * f0) / h[i] ** 2
            else:
                H[i, j] = H[j, i] = (f(x + ei + ej) - f(x + ei - ej) - f(x - ei + ej) + f(x - ei - ej)) / (
                    4 * h[i] * h[j])
    H = np.where(np.isfinite(H), H, 0.0)
    return _floored_inverse(-H, max_var)


def _floored_inverse(precision: np.ndarray, max_var: np.ndarray) -> np.ndarray:
    """Inverse of a symmetric precision whose eigenvalues are floored (in units of ``max_var``)."""
    s = np.sqrt(max_var)
    P = precision * s[:, None] * s[None, :]  # dimensionless: eigenvalue 1 = the prior width
    P = 0.5 * (P + P.T)
    try:
        vals, vecs = np.linalg.eigh(P)
    except np.linalg.LinAlgError:  # pragma: no cover - NaN-free input makes this unreachable
        return np.diag(max_var)
    floored = np.maximum(vals, 1.0)
    if np.any(vals < 1.0):
        log.debug("Hessian: %d flat or non-negative-definite direction(s) set to the prior width",
                  int(np.sum(vals < 1.0)))
    cov = (vecs / floored) @ vecs.T
    return cov * s[:, None] * s[None, :]


def laplace_evidence(lp_max: float, cov: np.ndarray) -> float:
    """``ln Z`` of a Gaussian approximation with peak ``lp_max`` and covariance ``cov``."""
    sign, logdet = np.linalg.slogdet(cov)
    d = cov.shape[0]
    return float(lp_max + 0.5 * d * np.log(TWO_PI) + 0.5 * logdet) if sign > 0 else float("nan")


# ---------------------------------------------------------------------------------------------
# proposal components
# ---------------------------------------------------------------------------------------------
def _regularised(cov: np.ndarray, scales: np.ndarray) -> np.ndarray:
    """A positive-definite covariance near ``cov`` (eigenvalues floored at 1e-6 of ``scales^2``)."""
    cov = np.where(np.isfinite(cov), cov, 0.0)
    cov = 0.5 * (cov + cov.T)
    s = np.asarray(scales, float)
    P = cov / s[:, None] / s[None, :]
    vals, vecs = np.linalg.eigh(P)
    vals = np.clip(vals, 1e-12, 1e4)
    return ((vecs * vals) @ vecs.T) * s[:, None] * s[None, :]


class StudentT:
    """Multivariate t proposal; coordinates in ``periodic`` wrapped onto ``[0, 2 pi)``."""

    def __init__(self, mean, cov, scales, periodic=(), df: float = T_DOF):
        from scipy import stats

        self.mean = np.asarray(mean, dtype=float)
        self.shape = _regularised(np.asarray(cov, float), scales) * (df - 2) / df
        self.periodic = list(periodic)
        self.dist = stats.multivariate_t(loc=self.mean, shape=self.shape, df=df)
        self.images = 0
        for k in self.periodic:  # enough 2 pi images to hold the density's tails
            self.images = max(self.images, int(np.ceil(6 * np.sqrt(self.shape[k, k]) / TWO_PI)))

    def draw(self, n: int, rng) -> np.ndarray:
        x = np.asarray(self.dist.rvs(size=n, random_state=rng), dtype=float).reshape(n, self.mean.size)
        for k in self.periodic:
            x[:, k] = wrap_angle(x[:, k], 0.0)
        return x

    def logpdf(self, x: np.ndarray) -> np.ndarray:
        from scipy.special import logsumexp

        x = np.asarray(x, dtype=float).reshape(-1, self.mean.size)
        if not self.periodic:
            return np.atleast_1d(self.dist.logpdf(x))
        terms = []
        for m in range(-self.images - 1, self.images + 2):
            shifted = x.copy()
            for k in self.periodic:
                shifted[:, k] += TWO_PI * m
            terms.append(np.atleast_1d(self.dist.logpdf(shifted)))
        return logsumexp(np.stack(terms), axis=0)


class GaussianGeometry:
    """The no-planet geometry posterior as a t distribution, with ``(r_p, phi_p)`` from their prior.

    Parameters
    ----------
    mean, cov : ndarray
        Mode and covariance of ``(inc, PA, dRA, dDec)`` (Laplace, inflated by the caller).
    r_range : (float, float)
        The uniform r_p prior; ``None`` for the geometry alone (the null hypothesis).
    """

    def __init__(self, mean, cov, scales, r_range=None):
        self.t = StudentT(mean, cov, scales)
        self.r_range = r_range

    def draw(self, n: int, rng) -> np.ndarray:
        g = self.t.draw(n, rng)
        if self.r_range is None:
            return g
        rp = rng.uniform(*self.r_range, n)
        phi = rng.uniform(0.0, TWO_PI, n)
        return np.column_stack([rp, phi, g])

    def logpdf(self, x: np.ndarray) -> np.ndarray:
        if self.r_range is None:
            return self.t.logpdf(x)
        lo, hi = self.r_range
        inside = (x[:, 0] >= lo) & (x[:, 0] <= hi)
        base = self.t.logpdf(x[:, 2:]) - np.log(hi - lo) - np.log(TWO_PI)
        return np.where(inside, base, -np.inf)


# ---------------------------------------------------------------------------------------------
# importance sampling
# ---------------------------------------------------------------------------------------------
def importance_evidence(logpost, components, fractions, n_draws: int, rng, mapper=map, *,
                        with_draws: bool = False) -> dict:
    """``ln Z`` by importance sampling from a mixture of ``components`` (see the module docs).

    Parameters
    ----------
    logpost : callable
        ``ln(L pi)`` of one parameter vector (``-inf`` outside the prior).
    components : list
        Objects with ``draw(n, rng)`` and ``logpdf(x)``.
    fractions : list of float
        Share of the draws from each component (the mixture weights).
    mapper : callable
        ``map(fn, iterable)`` of a pool that evaluates ``logpost`` (default the built-in map).
    with_draws : bool
        Also return ``draws`` and their ``log_weights`` (``ln(L pi / q)``), e.g. to resample them.

    Returns
    -------
    dict
        ``ln_evidence``, ``ln_evidence_err`` (standard error of ln Z), ``ess`` (effective sample
        size of the weights), ``n_draws``.
    """
    from scipy.special import logsumexp

    fractions = np.asarray(fractions, dtype=float) / np.sum(fractions)
    counts = np.floor(fractions * n_draws).astype(int)
    counts[0] += n_draws - counts.sum()
    draws = np.concatenate([c.draw(int(k), rng) for c, k in zip(components, counts) if k > 0])
    logq = logsumexp(np.stack([c.logpdf(draws) + np.log(f) for c, f in zip(components, fractions) if f > 0]), axis=0)
    lp = np.array(list(mapper(_call, [(logpost, d) for d in draws])), dtype=float)
    lw = np.where(np.isfinite(lp) & np.isfinite(logq), lp - logq, -np.inf)
    n = lw.size
    lnz = float(logsumexp(lw) - np.log(n))
    extra = {"draws": draws, "log_weights": lw} if with_draws else {}
    if not np.isfinite(lnz):
        return {"ln_evidence": -np.inf, "ln_evidence_err": np.inf, "ess": 0.0, "n_draws": int(n), **extra}
    w = np.exp(lw - np.max(lw))
    ess = float(w.sum() ** 2 / np.sum(w ** 2))
    err = float(np.sqrt(np.var(w) / n) / np.mean(w))
    return {"ln_evidence": lnz, "ln_evidence_err": err, "ess": ess, "n_draws": int(n), **extra}


def _call(item):
    fn, x = item
    out = fn(x)
    return out[0] if isinstance(out, tuple) else out


def savage_dickey_log_bayes(c1: np.ndarray, c2: np.ndarray, amplitude_max: float) -> float:
    """``ln(Z_T / Z_0)`` from the conditional amplitude terms of posterior samples (cross-check)."""
    from scipy.special import logsumexp

    lai = np.asarray(log_amplitude_integral(np.asarray(c1, float), np.asarray(c2, float), amplitude_max))
    lai = lai[np.isfinite(lai)]
    if lai.size == 0:
        return float("nan")
    return float(-(logsumexp(-lai) - np.log(lai.size)))
