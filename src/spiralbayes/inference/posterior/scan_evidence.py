"""A template's (or a family's) Bayes factor from the scan's grid, for hypotheses too far below the best to sample.

The scan holds, for every template and grid instance ``(r_p, phi_p)``, the cross and power terms of
the spiral against the frank residual (:class:`~spiralbayes.inference.scan.run.ScanResult`), so
``ln L(A) - ln L_0 = A cross - A^2 power / 2`` at the scan's geometry. Integrating that over the
amplitude prior (analytically, :func:`~.likelihood.log_amplitude_integral`) and over the position
prior on the grid gives the template's Bayes factor against no planet with no table, no optimiser and
no chain:

* **r_p**: each prior radius takes the value of the nearest scanned radius (cells between midpoints,
  the outermost extended to the prior's edges), so radii outside the scanned range are represented
  by the grid's first or last row;
* **phi_p**: the grid's azimuths, each ``2 pi / n_phi`` of the circle;
* **M_p** (a family, ``mass="continuous"``): each prior ``ln M_p`` takes the nearest bank member's
  value, the same rule in ``ln M_p`` with the log-uniform prior.

What the grid leaves out, stated: the geometry is the scan's (the frank fit's), not integrated; the
profile is frank's, not re-fitted with the spiral (the sampler's likelihood marginalises it, which
lowers ``cross`` and ``power`` by the spiral's axisymmetric part); and a peak narrower than a grid
cell is under- or over-counted. :func:`~.sampler.sample_posterior` therefore uses this estimate only
for the hypotheses it does not sample (all but the ``max_chains`` best within ``prune_delta_lnL`` of
the best): against the chains' evidence the grid is within 0.8 for templates with ``ln B < 10`` and
under-counts the strongest by up to 6 (docs/performance.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import logsumexp

from ...exceptions import InputError
from .likelihood import draw_amplitude, log_amplitude_integral
from .priors import Priors

__all__ = ["GRID_LN_B_ERROR", "GridEvidence", "family_grid_evidence", "grid_run", "template_grid_evidence"]

GRID_LN_B_ERROR = 0.5
"""The error adopted for a grid ``ln B``: between the rms (0.31) and the largest (0.79) difference from the
chains' importance-sampled ``ln B`` over 18 templates with ``ln B < 10`` (docs/performance.md)."""


@dataclass
class GridEvidence:
    """The grid's ``ln B`` of one hypothesis and what is needed to draw from its grid posterior.

    Attributes
    ----------
    ln_bayes : float
        ``ln (Z_T / Z_0)`` on the grid (see the module docs).
    log_weights : ndarray, shape (n_members, n_rp, n_phi)
        ``ln`` of each cell's prior mass times its amplitude-integrated likelihood ratio (-inf where
        the prior gives no mass or the scan has no value); ``logsumexp`` of it is ``ln_bayes``.
    r_edges : ndarray, shape (n_rp, 2)
        The radii [arcsec] each scanned radius stands for.
    phi_p : ndarray
        The grid's azimuths [rad].
    cross, power : ndarray, shape (n_members, n_rp, n_phi)
        The scan's terms, for drawing ``A``.
    ln_mass_edges : ndarray, shape (n_members, 2) or None
        The ``ln M_p`` interval each member stands for (families only).
    masses : ndarray or None
        The members' masses [M_th] (families only).
    """

    ln_bayes: float
    log_weights: np.ndarray
    r_edges: np.ndarray
    phi_p: np.ndarray
    cross: np.ndarray
    power: np.ndarray
    ln_mass_edges: np.ndarray | None = None
    masses: np.ndarray | None = None

    def draw(self, n: int, null_samples: np.ndarray, amplitude_max: float | None, rng) -> np.ndarray:
        """``n`` draws of ``(r_p, phi_p, A, inc, PA, dRA, dDec[, M_p])`` from the grid posterior.

        The cell is drawn by its weight, the position uniformly within it, the geometry from the
        no-planet samples ``null_samples`` (rows of ``(inc, PA, dRA, dDec)``), ``A`` from its exact
        conditional at the cell, and for a family ``ln M_p`` uniformly within the member's interval.
        """
        w = self.log_weights.ravel()
        p = np.exp(w - np.max(w))
        cells = rng.choice(w.size, size=n, p=p / p.sum())
        k, i, j = np.unravel_index(cells, self.log_weights.shape)
        lo, hi = self.r_edges[i, 0], self.r_edges[i, 1]
        r_p = lo + (hi - lo) * rng.uniform(size=n)
        dphi = 2 * np.pi / self.phi_p.size
        phi_p = np.mod(self.phi_p[j] + dphi * (rng.uniform(size=n) - 0.5), 2 * np.pi)
        c1, c2 = self.cross[k, i, j], self.power[k, i, j]
        A = np.ones(n) if amplitude_max is None else draw_amplitude(c1, c2, amplitude_max, rng)
        geometry = null_samples[rng.integers(0, len(null_samples), size=n)]
        out = np.column_stack([r_p, phi_p, A, geometry])
        if self.ln_mass_edges is not None:
            a, b = self.ln_mass_edges[k, 0], self.ln_mass_edges[k, 1]
            out = np.column_stack([out, np.exp(a + (b - a) * rng.uniform(size=n))])
        return out

    def theta_map(self, null_geometry: np.ndarray) -> np.ndarray:
        """The heaviest cell's ``(r_p, phi_p)`` with the no-planet geometry (and ``ln M_p`` of its member)."""
        k, i, j = np.unravel_index(int(np.argmax(self.log_weights)), self.log_weights.shape)
        theta = np.concatenate([[0.5 * (self.r_edges[i, 0] + self.r_edges[i, 1]), self.phi_p[j]], null_geometry])
        if self.masses is not None:
            theta = np.append(theta, np.log(self.masses[k]))
        return theta


def _nearest_cells(nodes: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """``(n, 2)`` intervals of ``[lo, hi]`` nearest to each sorted node (empty intervals have lo == hi)."""
    mid = 0.5 * (nodes[1:] + nodes[:-1])
    left = np.clip(np.concatenate([[lo], mid]), lo, hi)
    right = np.clip(np.concatenate([mid, [hi]]), lo, hi)
    return np.column_stack([left, np.maximum(left, right)])


def _cell_terms(scan, index: int, priors: Priors) -> tuple:
    order = np.argsort(scan.r_p)
    r = np.asarray(scan.r_p, float)[order]
    cross = np.asarray(scan.cross[index], float)[order]
    power = np.asarray(scan.power[index], float)[order]
    lo, hi = priors.r_p
    edges = _nearest_cells(r, lo, hi)
    with np.errstate(divide="ignore"):
        log_prior = np.log((edges[:, 1] - edges[:, 0]) / (hi - lo))[:, None] - np.log(scan.phi_p.size)
    bad = ~(np.isfinite(cross) & np.isfinite(power))
    c1, c2 = np.where(bad, 0.0, cross), np.where(bad, 0.0, power)
    a_max = priors.amplitude_max
    log_like = c1 - 0.5 * c2 if a_max is None else log_amplitude_integral(c1, c2, a_max)
    log_w = np.where(bad, -np.inf, log_prior + log_like)
    return log_w, edges, c1, c2


def template_grid_evidence(scan, name: str, priors: Priors) -> GridEvidence:
    """The grid's Bayes factor of template ``name`` against no planet (module docs)."""
    log_w, edges, c1, c2 = _cell_terms(scan, scan.template_index(name), priors)
    return GridEvidence(float(logsumexp(log_w)), log_w[None], edges, np.asarray(scan.phi_p, float), c1[None],
                        c2[None])


def family_grid_evidence(scan, members, mass_range: tuple[float, float], priors: Priors) -> GridEvidence:
    """The grid's Bayes factor of a family whose bank ``members`` the scan holds, ``ln M_p`` log-uniform
    on ``mass_range`` [M_th], each prior mass represented by the nearest member (module docs)."""
    members = sorted(members, key=lambda t: float(t.mass))
    masses = np.array([float(t.mass) for t in members])
    lo, hi = np.log(mass_range[0]), np.log(mass_range[1])
    ln_edges = _nearest_cells(np.log(masses), lo, hi)
    with np.errstate(divide="ignore"):
        log_q = np.log((ln_edges[:, 1] - ln_edges[:, 0]) / (hi - lo))
    parts = [_cell_terms(scan, scan.template_index(t.name), priors) for t in members]
    log_w = np.stack([p[0] for p in parts]) + log_q[:, None, None]
    return GridEvidence(float(logsumexp(log_w)), log_w, parts[0][1], np.asarray(scan.phi_p, float),
                        np.stack([p[2] for p in parts]), np.stack([p[3] for p in parts]), ln_edges, masses)


def grid_run(name: str, metadata: dict, grid: GridEvidence, null, priors: Priors, rng, *, n_samples: int = 400,
             mass_prior=None, h_p: float | None = None):
    """A :class:`~.results.TemplateRun` (mode ``"scan"``) from the grid: ``ln Z = ln Z_0 + ln B_grid``.

    The error of ``ln Z`` is the no-planet evidence's and :data:`GRID_LN_B_ERROR` in quadrature. Its
    samples are :meth:`GridEvidence.draw`'s (``M_p`` and ``M_p_MJup`` added for a family, with
    ``mass_prior`` and the family's ``h_p``).
    """
    from .results import TemplateRun, wrap_phi

    draws = wrap_phi(grid.draw(n_samples, np.asarray(null.samples, float), priors.amplitude_max, rng))[0]
    theta_map = grid.theta_map(np.asarray(null.geometry_map, float))
    params = np.column_stack([draws[:, :2], draws[:, 3:7]])
    if grid.masses is not None:
        if mass_prior is None or h_p is None:
            raise InputError("a family's grid run needs its mass_prior and h_p (for M_p in M_Jup)")
        params = np.column_stack([params, np.log(draws[:, 7])])
        draws = np.column_stack([draws[:, :7], *mass_prior.planet_masses(draws[:, 7], float(h_p), rng)])
    cov = np.atleast_2d(np.cov(params, rowvar=False))
    ln_z = float(null.ln_evidence) + grid.ln_bayes
    err = float(np.hypot(null.ln_evidence_err, GRID_LN_B_ERROR))
    info = {"evidence": {"method": "scan grid", "ln_bayes_grid": grid.ln_bayes}}
    return TemplateRun(name, metadata, "scan", draws, theta_map, cov, ln_z, err, float("nan"), info)
