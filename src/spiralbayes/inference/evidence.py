"""Evidence of one template's posterior: Laplace approximation and importance sampling.

* ``laplace``: Gaussian approximation at the optimum, ``ln Z = ln(L pi)(theta*) + (d/2) ln 2 pi +
  (1/2) ln det Sigma`` with ``Sigma`` from a finite-difference Hessian;
* ``importance`` (used when a chain exists): importance sampling of ``L pi`` with a multivariate
  Student-t (5 degrees of freedom) proposal fitted to the chain, ``Z = E_q[L pi / q]``; its error
  comes from the weights' variance.
"""

from __future__ import annotations

import logging

import numpy as np

from ..units import TWO_PI
from .priors import N_DIM, Priors

__all__ = []

log = logging.getLogger(__name__)


def _inside(theta: np.ndarray, priors: Priors) -> tuple[np.ndarray, np.ndarray]:
    """Move ``theta`` off the hard prior edges (r_p range, inc in [0, 90)); room to each edge."""
    theta = theta.copy()
    lo, hi = priors.r_p
    span = hi - lo
    theta[0] = np.clip(theta[0], lo + 1e-3 * span, hi - 1e-3 * span)
    theta[2] = np.clip(theta[2], 1e-3, 90 - 1e-3)
    room = np.full(N_DIM, np.inf)
    room[0] = min(theta[0] - lo, hi - theta[0])
    room[2] = min(theta[2], 90 - theta[2])
    return theta, 0.9 * room


def _hessian_cov(logpost, theta: np.ndarray, scales: np.ndarray, priors: Priors) -> np.ndarray:
    """Laplace covariance ``(-H)^-1`` from central differences with steps tuned to d ln p ~ 0.5.

    Steps never cross the hard prior edges (an optimum on an edge is moved just inside; the
    Gaussian approximation is then rough, which only matters for templates far from the best).
    """
    theta, room = _inside(theta, priors)
    f0 = logpost(theta)
    h = np.minimum(scales * 1e-2, room)
    for i in range(N_DIM):
        for _ in range(10):
            e = np.zeros(N_DIM)
            e[i] = h[i]
            curv = logpost(theta + e) + logpost(theta - e) - 2 * f0
            if not np.isfinite(curv):
                h[i] *= 0.3
                continue
            if 0.1 < -curv < 2.0:
                break
            h[i] = min(h[i] * np.sqrt(0.5 / max(abs(curv), 1e-12)), scales[i] * 3, room[i])
    H = np.zeros((N_DIM, N_DIM))
    for i in range(N_DIM):
        for j in range(i, N_DIM):
            ei = np.zeros(N_DIM)
            ej = np.zeros(N_DIM)
            ei[i], ej[j] = h[i], h[j]
            if i == j:
                H[i, i] = (logpost(theta + ei) + logpost(theta - ei) - 2 * f0) / h[i] ** 2
            else:
                H[i, j] = H[j, i] = (logpost(theta + ei + ej) - logpost(theta + ei - ej) - logpost(theta - ei + ej)
                                     + logpost(theta - ei - ej)) / (4 * h[i] * h[j])
    H = np.where(np.isfinite(H), H, 0.0)
    try:
        cov = np.linalg.inv(-H)
        np.linalg.cholesky(cov)
        return cov
    except np.linalg.LinAlgError:
        diag = -np.diag(H)
        log.warning("Hessian not negative definite at the optimum; using its diagonal")
        return np.diag(1.0 / np.where(diag > 0, diag, 1.0 / scales ** 2))


def _laplace_evidence(lp_max: float, cov: np.ndarray) -> float:
    sign, logdet = np.linalg.slogdet(cov)
    return float(lp_max + 0.5 * N_DIM * np.log(TWO_PI) + 0.5 * logdet) if sign > 0 else float("nan")


def _importance_evidence(logpost, samples: np.ndarray, n_draws: int, rng, mapper=map) -> tuple[float, float, float]:
    """``ln Z`` by importance sampling with a Student-t proposal fitted to ``samples``.

    Returns ``(ln Z, its standard error, effective sample size of the weights)``.
    """
    from scipy import stats
    from scipy.special import logsumexp

    nu = 5.0
    mean = samples.mean(axis=0)
    cov = np.cov(samples, rowvar=False) * 1.2 ** 2
    proposal = stats.multivariate_t(loc=mean, shape=cov * (nu - 2) / nu, df=nu, seed=rng)
    draws = proposal.rvs(n_draws)
    lp = np.array(list(mapper(logpost, list(draws))))
    lw = lp - proposal.logpdf(draws)
    lw = np.where(np.isfinite(lw), lw, -np.inf)
    lnz = float(logsumexp(lw) - np.log(n_draws))
    w = np.exp(lw - np.max(lw))
    ess = float(w.sum() ** 2 / np.sum(w ** 2))
    err = float(np.sqrt(np.var(w) / n_draws) / np.mean(w))
    return lnz, err, ess
