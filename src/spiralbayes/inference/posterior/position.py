"""A template's Bayes factor from its scan, the planet's position integrated, on a grid refined at the peak.

A scan gives each template's ``ln L/L_0`` at every scanned ``(r_p, φ_p)``. :func:`position_ln_bayes`
integrates ``L`` over the position's prior: ``ln L`` (smooth, and near a peak close to quadratic, where
``L`` itself can be narrower than a cell) is interpolated by bicubic splines, periodic in ``φ_p``, onto
a grid :data:`UPSAMPLE` times finer and summed there.

A strong planet's peak can still be narrower than the scan's cells. Then the grid is refined where the
likelihood is: :func:`peak_window` picks the radii that hold the templates' likelihood (all but
``e^-20`` of it, and at least :data:`MIN_WINDOW_STEPS` cells either side of the peak), those radii are
rescanned twice as densely and with twice the azimuths, and the integral is the sum of each level's
spline over its radii outside the next level's window (:class:`PositionLevel`,
:func:`composite_ln_bayes`). Only the templates that can matter are rescanned (``ln B`` within
:data:`REFINE_LN_B_RANGE` of the best); the others keep the previous level's value.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.special import logsumexp

from ...exceptions import InputError
from .likelihood import log_amplitude_integral

__all__ = ["MIN_WINDOW_STEPS", "PositionLevel", "REFINE_LN_B_RANGE", "UPSAMPLE", "composite_ln_bayes",
           "grid_log_likelihood", "peak_window", "position_ln_bayes"]

UPSAMPLE = 4
"""How many times finer than the scan's grid :func:`position_ln_bayes` integrates the likelihood."""

REFINE_LN_B_RANGE = 20.0
"""Templates whose ``ln B`` lies further than this below the best one's are not rescanned when the
grid is refined (their posterior weight is below ``e^-20`` of the best's)."""

WINDOW_LN_DROP = 20.0
""":func:`peak_window` keeps the radii where the likelihood summed over azimuths and templates lies
within this of its largest value."""

MIN_WINDOW_STEPS = 4
"""The refined window reaches at least this many of the coarser grid's radial steps either side of the
peak (so that every level's half grid keeps the 4 radii a bicubic spline needs)."""


def grid_log_likelihood(cross: np.ndarray, power: np.ndarray, amplitude_max: float | None) -> np.ndarray:
    """``ln L/L_0`` of a template at each scanned position from the scan's terms.

    The amplitude is fixed at 1 (``amplitude_max`` None) or integrated over its uniform prior
    (:func:`~.likelihood.log_amplitude_integral`). A position the scan has no value for takes the
    smallest value elsewhere, so that it cannot lift the evidence.
    """
    c1, c2 = np.asarray(cross, dtype=float), np.asarray(power, dtype=float)
    bad = ~(np.isfinite(c1) & np.isfinite(c2))
    c1, c2 = np.where(bad, 0.0, c1), np.where(bad, 0.0, c2)
    ll = c1 - 0.5 * c2 if amplitude_max is None else log_amplitude_integral(c1, c2, amplitude_max)
    ll = np.asarray(ll, dtype=float)
    if np.any(bad):
        ll[bad] = np.min(ll[~bad]) if np.any(~bad) else 0.0
    return ll


def position_ln_bayes(r_p: np.ndarray, phi_p: np.ndarray, log_like: np.ndarray, r_prior: tuple[float, float],
                      upsample: int = UPSAMPLE, r_range: tuple[float, float] | None = None) -> float:
    """``ln B`` of one template from its ``ln L/L_0`` on a scan's grid, the position integrated over its prior.

    ``ln L`` is interpolated by bicubic splines (periodic in ``φ_p``) onto a grid ``upsample`` times
    finer, and ``L`` integrated there: trapezoidal in ``r_p``, uniform over the circle in ``φ_p``,
    normalised by the whole r_p prior. Radii of the prior outside the scanned range are taken to hold
    no planet (their share of the prior counts, their likelihood does not).

    Parameters
    ----------
    r_p : (n_r,) array
        Increasing scanned radii [arcsec] (at least 4).
    phi_p : (n_phi,) array
        Equally spaced azimuths over the circle [rad].
    log_like : (n_r, n_phi) array
    r_prior : (float, float)
        The uniform r_p prior's range [arcsec].
    upsample : int
    r_range : (float, float), optional
        Integrate over these radii only [arcsec] (still normalised by the whole prior): one level's
        share of a refined grid. ``-inf`` when it holds none of the scanned prior.

    Returns
    -------
    float
    """
    from scipy.interpolate import RectBivariateSpline

    lo, hi = max(r_prior[0], float(r_p[0])), min(r_prior[1], float(r_p[-1]))
    if not lo < hi:
        raise InputError(f"the scanned radii {r_p[0]:.3g}-{r_p[-1]:.3g} arcsec lie outside the r_p prior {r_prior}")
    if r_range is not None:
        lo, hi = max(lo, float(r_range[0])), min(hi, float(r_range[1]))
        if not lo < hi:
            return -np.inf
    n, pad = phi_p.size, 3
    step = 2 * np.pi / n
    wrap = np.arange(-pad, n + pad)
    spline = RectBivariateSpline(r_p, phi_p[0] + step * wrap, log_like[:, wrap % n], kx=3, ky=3)
    n_fine = max(2, int(np.ceil((hi - lo) / float(np.min(np.diff(r_p))))) * int(upsample) + 1)
    r_fine = np.linspace(lo, hi, n_fine)
    fine = spline(r_fine, phi_p[0] + step / upsample * np.arange(n * upsample))
    w = np.full(n_fine, (hi - lo) / (n_fine - 1))
    w[[0, -1]] *= 0.5
    return float(logsumexp(fine + np.log(w / (r_prior[1] - r_prior[0]))[:, None]) - np.log(fine.shape[1]))


@dataclass
class PositionLevel:
    """One level of a refined position grid.

    Attributes
    ----------
    r_p : (n_r,) array
        Scanned radii [arcsec], increasing.
    phi_p : (n_phi,) array
        Scanned azimuths [rad], equally spaced over the circle.
    window : (float, float)
        The radii [arcsec] this level stands for; a finer level's window lies inside it.
    log_like : dict
        ``{template index: (n_r, n_phi) ln L/L_0}`` of the templates scanned at this level.
    """

    r_p: np.ndarray
    phi_p: np.ndarray
    window: tuple[float, float]
    log_like: dict = field(default_factory=dict)


def composite_ln_bayes(levels: list[PositionLevel], k: int, r_prior: tuple[float, float], half: bool = False) -> float:
    """``ln B`` of template ``k`` over refined levels: each level integrates its radii outside the next window.

    The levels holding ``k`` must be a prefix of ``levels`` (a template left out of a refinement is left
    out of every later one). With ``half`` the finest level uses every other radius and azimuth: the
    check of whether that level resolves the peak.
    """
    own = [lev for lev in levels if k in lev.log_like]
    parts = []
    for i, lev in enumerate(own):
        r, phi, ll = lev.r_p, lev.phi_p, lev.log_like[k]
        if i == len(own) - 1:
            if half:
                r, phi, ll = r[::2], phi[::2], ll[::2, ::2]
            segments = [lev.window]
        else:
            inner = own[i + 1].window
            segments = [(lev.window[0], inner[0]), (inner[1], lev.window[1])]
        parts += [position_ln_bayes(r, phi, ll, r_prior, r_range=s) for s in segments]
    return float(logsumexp(parts))


def peak_window(level: PositionLevel, log_weight: dict) -> tuple[float, float]:
    """The radii [arcsec] of ``level`` that hold the likelihood of the templates ``log_weight`` names.

    Parameters
    ----------
    level : PositionLevel
    log_weight : dict
        ``{template index: ln prior weight}`` of the templates that matter.

    Returns
    -------
    (float, float)
        Grid radii of ``level``: those where ``ln Σ_templates Σ_φ w L`` lies within
        :data:`WINDOW_LN_DROP` of its largest value, one step more either side, and at least
        :data:`MIN_WINDOW_STEPS` steps either side of the largest; clipped to the level's window.
    """
    r = level.r_p
    profile = logsumexp([w + logsumexp(level.log_like[k], axis=1) for k, w in log_weight.items()], axis=0)
    inside = np.flatnonzero(profile >= profile.max() - WINDOW_LN_DROP)
    peak = int(np.argmax(profile))
    i0 = max(0, min(inside[0] - 1, peak - MIN_WINDOW_STEPS))
    i1 = min(r.size - 1, max(inside[-1] + 1, peak + MIN_WINDOW_STEPS))
    return max(float(r[i0]), level.window[0]), min(float(r[i1]), level.window[1])
