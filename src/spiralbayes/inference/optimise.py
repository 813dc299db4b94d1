"""Finding the posterior's mode before sampling: geometry first, then the planet, then jointly.

With the geometry off (the frank geometry may be off by tens of mas), the best planet positions
at that geometry are often the ones that absorb the geometry error (Stevenson et al. 2024,
appendix A), a local mode of the joint posterior; fitting the geometry of the axisymmetric model
first, then starting from the scan's best instances and a coarse grid, avoids it.
"""

from __future__ import annotations

import logging

import numpy as np

from ..geometry import DiscGeometry
from ..units import TWO_PI
from .likelihood import SpiralLikelihood
from .priors import N_DIM, Priors

__all__ = ["find_map"]

log = logging.getLogger(__name__)


def _optimise(logpost, start: np.ndarray, scales: np.ndarray, max_evals: int = 3000) -> np.ndarray:
    """Nelder-Mead on the log posterior (with restarts), from ``start``."""
    from scipy.optimize import minimize

    x = np.array(start, dtype=float)
    for _ in range(3):
        simplex = x + np.vstack([np.zeros(N_DIM), np.diag(scales)])
        res = minimize(lambda t: -logpost(t) if np.isfinite(logpost(t)) else 1e300, x, method="Nelder-Mead",
                       options={"initial_simplex": simplex, "maxfev": max_evals, "xatol": 1e-9, "fatol": 1e-4})
        moved = np.abs(res.x - x) / scales
        x = res.x
        scales = np.maximum(scales * 0.2, np.abs(moved) * scales * 0.5 + 1e-9)
        if np.all(moved < 1e-2):
            break
    return x

def _fit_geometry(likelihood: SpiralLikelihood, priors: Priors) -> np.ndarray:
    """MAP geometry (inc, PA, dRA, dDec) of the axisymmetric model alone.

    Done before searching for the planet: with the geometry off (the frank geometry may be off by
    tens of mas), the best planet positions at that geometry are often the ones that absorb the
    geometry error (Stevenson et al. 2024, appendix A), a local mode of the joint posterior.
    """
    from scipy.optimize import minimize

    centre = priors.centre

    def neg(g):
        theta = np.concatenate([centre[:2], g])
        lp = priors.log_prior(theta)
        if not np.isfinite(lp):
            return 1e300
        return -(lp + likelihood.log_likelihood_axisymmetric(DiscGeometry(*g)))

    x = centre[2:].copy()
    step = priors.widths[2:] * 0.2
    for _ in range(3):
        res = minimize(neg, x, method="Nelder-Mead",
                       options={"initial_simplex": x + np.vstack([np.zeros(4), np.diag(step)]), "maxfev": 2000,
                                "xatol": 1e-9, "fatol": 1e-4})
        if np.all(np.abs(res.x - x) < 0.01 * step):
            x = res.x
            break
        x, step = res.x, step * 0.2
    return x


def _start_points(likelihood: SpiralLikelihood, priors: Priors, scan, template_name: str, geometry: np.ndarray,
                  n: int = 8):
    """Candidate starts: the scan's best (r_p, phi_p) instances plus a coarse grid, at ``geometry``."""
    cands = []
    if scan is not None:
        try:
            k = scan.template_index(template_name)
        except (KeyError, IndexError):
            k = None
        if k is not None:
            dchi2 = scan.delta_chi2()[k]
            order = np.argsort(np.nan_to_num(dchi2, nan=-np.inf), axis=None)[::-1]
            for flat in order[:n]:
                i, j = np.unravel_index(flat, dchi2.shape)
                cands.append((float(np.clip(scan.r_p[i], *priors.r_p)), float(scan.phi_p[j])))
    lo, hi = priors.r_p
    for r in np.linspace(lo, hi, 14)[1:-1]:
        for phi in np.linspace(0, TWO_PI, 36, endpoint=False):
            cands.append((float(r), float(phi)))
    return [np.concatenate([[r, phi], geometry]) for r, phi in cands]


def find_map(logpost, likelihood, priors, scan, name, scales, n_starts: int = 3):
    """Geometry first, then a grid/scan search over (r_p, phi_p), then joint optimisation from the
    ``n_starts`` best distinct candidates; returns the best optimum."""
    geometry = _fit_geometry(likelihood, priors)
    starts = _start_points(likelihood, priors, scan, name, geometry)
    values = np.array([logpost(s) for s in starts])
    order = np.argsort(np.where(np.isfinite(values), values, -np.inf))[::-1]
    chosen: list = []
    for i in order:
        s = starts[i]
        far = all(abs(s[0] - c[0]) > 0.05 * (priors.r_p[1] - priors.r_p[0])
                  or abs(np.angle(np.exp(1j * (s[1] - c[1])))) > 0.3 for c in chosen)
        if far:
            chosen.append(s)
        if len(chosen) >= n_starts:
            break
    optima = [_optimise(logpost, s, scales) for s in chosen]
    lps = [logpost(o) for o in optima]
    best = int(np.argmax(lps))
    log.info("%s: optima from %d starts, ln p = %s", name, len(optima), np.round(lps, 2).tolist())
    return optima[best]
