"""Averaging visibilities in time per baseline, or in uv cells, with a stated smearing bound.

Large Measurement Sets (10^6-10^8 visibilities after channel averaging) are usually averaged before
modelling, as CASA's ``split``/``mstransform`` (``timebin``, ``width``) or frank's uv binning do.
Averaging a group of visibilities replaces the model at each of their baselines by the model at
their weighted mean baseline; :func:`average_visibilities` chooses the groups so that this
replacement costs at most a stated fraction of any model's signal.

The bound
---------
For a group with weights ``w_k`` at baselines ``u_k`` [lambda], weighted mean ``ū`` and weighted
covariance ``C`` of the positions, and any brightness ``I`` that lies within an angle ``θ`` [rad] of
the phase centre, Taylor's theorem with ``|e^{ix} - 1 - ix| <= x²/2`` gives::

    | Σ w_k V(u_k) / Σ w_k  -  V(ū) |  <=  ½ (2π θ)² tr(C) · ∫ |I| dΩ ,

the linear term vanishing because ``ū`` is the weighted mean. The factor ``ε = ½ (2π θ)² tr(C)``
is the group's *smearing*: the largest error of the averaged model, as a fraction of the model's
L1 norm (its flux for a positive image; for the spiral, the L1 norm of ``I_A δ``, the same measure
the scan's quadrature error uses). It covers time smearing (the baseline rotating during the
group), bandwidth smearing (channels of one integration at different ``u = b/λ``) and uv-cell
averaging alike, because it is computed from the positions themselves. ``θ`` is the disc's outer
radius plus the disc centre's offset from the phase centre.

Groups start as the rows of one baseline in one time window (``mode="time"``; antennas and times are
kept, so gains can still be solved) or as the rows in one uv cell (``mode="uv"``, Hermitian-folded;
no antennas), and any group whose smearing exceeds ``max_smearing`` is split along the principal
axis of its positions until none does. Weights combine as inverse variances (``Σ w``), the averaged
visibility is the weighted mean, so the noise of Re and Im of each average is ``1/√Σw``.
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import asdict, dataclass

import numpy as np

from .exceptions import DataWarning, InputError
from .geometry import DiscGeometry
from .units import ARCSEC
from .visibilities import Visibilities

__all__ = ["AVERAGING_MODES", "DEFAULT_MAX_SMEARING", "AveragingReport", "average_visibilities", "group_smearing",
           "smearing_angle"]

log = logging.getLogger(__name__)

DEFAULT_MAX_SMEARING = 1e-3
"""Default bound on the smearing ``ε`` of every averaged visibility (fraction of the model's L1 norm)."""

AVERAGING_MODES = ("none", "time", "uv")
"""``"time"``: per baseline in time (needs antennas and times); ``"uv"``: in uv cells; ``"none"``."""

_MAX_SPLITS = 64


@dataclass(frozen=True)
class AveragingReport:
    """What :func:`average_visibilities` did (also stored as ``vis.provenance["averaging"]``).

    Attributes
    ----------
    mode : str
        ``"time"`` or ``"uv"``.
    n_in, n_out : int
        Visibilities before and after.
    r_out : float
        Disc outer radius used for the bound [arcsec].
    theta : float
        ``r_out`` plus the disc centre's offset from the phase centre [arcsec].
    max_smearing : float
        The bound every group was kept below.
    smearing : float
        The largest smearing of any averaged visibility (≤ ``max_smearing``).
    median_smearing : float
        Median smearing over the averaged visibilities.
    time_bin : float or None
        Time window [s] the groups started from (``mode="time"``); None: whole tracks.
    uv_cell : float or None
        Cell size [lambda] the groups started from (``mode="uv"``).
    requested_smearing : float
        The largest smearing the requested ``time_bin`` or ``uv_cell`` would have given before
        splitting (the same as ``smearing`` where nothing had to be split).
    n_split : int
        How many starting groups had to be split to stay within the bound.
    """

    mode: str
    n_in: int
    n_out: int
    r_out: float
    theta: float
    max_smearing: float
    smearing: float
    median_smearing: float
    time_bin: float | None
    uv_cell: float | None
    requested_smearing: float
    n_split: int

    @property
    def reduction(self) -> float:
        """``n_in / n_out``."""
        return self.n_in / self.n_out

    def to_dict(self) -> dict:
        return {**asdict(self), "reduction": self.reduction}

    def summary(self) -> str:
        start = (f"time windows of {self.time_bin:g} s" if self.time_bin else "whole baseline tracks") \
            if self.mode == "time" else f"uv cells of {self.uv_cell:.4g} lambda"
        return (f"averaged {self.n_in} -> {self.n_out} visibilities ({self.reduction:.1f}x, {self.mode}: {start}); "
                f"smearing at most {self.smearing:.2e} of the model's L1 norm within {self.theta:.3g} arcsec "
                f"(bound {self.max_smearing:.1e}; median {self.median_smearing:.1e})")


def smearing_angle(r_out: float, geometry: DiscGeometry | None = None) -> float:
    """``θ`` of the bound [arcsec]: the outer radius plus the disc centre's distance from the phase centre."""
    if not (np.isfinite(r_out) and r_out > 0):
        raise InputError(f"r_out = {r_out!r}: give the disc's outer radius in arcsec (> 0), e.g. frank's Rmax")
    offset = 0.0 if geometry is None else float(np.hypot(geometry.dRA, geometry.dDec))
    return float(r_out) + offset


def group_smearing(u, v, weights, groups, theta: float) -> np.ndarray:
    """Smearing ``ε = ½ (2π θ)² tr(C)`` of each group (``groups``: integer ids 0..G-1 per row).

    ``theta`` in arcsec; ``u, v`` in lambda. Returns an array of length G.
    """
    return _group_moments(u, v, weights, groups)[1] * 0.5 * (2 * np.pi * theta * ARCSEC) ** 2


def _group_moments(u, v, w, groups):
    """Per group: (weight sum, tr C, mean u, mean v, C_uu, C_vv, C_uv)."""
    g = int(groups.max()) + 1 if groups.size else 0
    W = np.bincount(groups, w, g)
    mu = np.bincount(groups, w * u, g) / W
    mv = np.bincount(groups, w * v, g) / W
    du, dv = u - mu[groups], v - mv[groups]   # centred first: no cancellation at long baselines
    cuu = np.bincount(groups, w * du * du, g) / W
    cvv = np.bincount(groups, w * dv * dv, g) / W
    cuv = np.bincount(groups, w * du * dv, g) / W
    return W, cuu + cvv, mu, mv, cuu, cvv, cuv


def _split_until_bounded(u, v, w, groups, theta, bound):
    """Split every group above ``bound`` in two along its principal axis until none is above it."""
    factor = 0.5 * (2 * np.pi * theta * ARCSEC) ** 2
    first = None
    n_split = 0
    for _ in range(_MAX_SPLITS):
        W, trace, mu, mv, cuu, cvv, cuv = _group_moments(u, v, w, groups)
        eps = trace * factor
        if first is None:
            first = eps
        over = eps > bound
        if not over.any():
            return groups, eps, first
        if n_split == 0:
            n_split = int(over.sum())
        angle = 0.5 * np.arctan2(2 * cuv, cuu - cvv)
        rows = over[groups]
        g = groups[rows]
        side = ((u[rows] - mu[g]) * np.cos(angle[g]) + (v[rows] - mv[g]) * np.sin(angle[g])) > 0
        new = groups.astype(np.int64) * 2
        new[rows] += side
        _, groups = np.unique(new, return_inverse=True)
        groups = groups.ravel()
    raise RuntimeError("averaging: groups did not reach the smearing bound")  # pragma: no cover - tr C halves


def _uv_cell_for(bound: float, theta: float) -> float:
    """The cell [lambda] whose worst case (weights at opposite corners, tr C = Δ²/2) meets ``bound``."""
    return float(np.sqrt(4.0 * bound) / (2 * np.pi * theta * ARCSEC))


def average_visibilities(vis: Visibilities, mode: str = "time", *, r_out: float, geometry: DiscGeometry | None = None,
                         max_smearing: float = DEFAULT_MAX_SMEARING, time_bin: float | None = None,
                         uv_cell: float | None = None) -> Visibilities:
    """Average visibilities so that no average smears a model by more than ``max_smearing``.

    Parameters
    ----------
    vis : Visibilities
        The data. ``mode="time"`` needs their antennas and times.
    mode : {"time", "uv", "none"}
        ``"time"``: each baseline's rows averaged over time (and over channels of one integration),
        keeping antennas and the weighted mean time of each average; ``"uv"``: rows averaged in uv
        cells after folding to ``v >= 0`` (antennas and times are dropped); ``"none"``: ``vis``.
    r_out : float
        The disc's outer radius [arcsec] (frank's ``Rmax`` is the natural choice): the bound holds
        for any emission inside it.
    geometry : DiscGeometry, optional
        Its offsets ``dRA, dDec`` [arcsec] widen the bound's angle; default centred.
    max_smearing : float
        The largest smearing ``ε`` allowed for any average (default :data:`DEFAULT_MAX_SMEARING`):
        the averaged model differs from the average of the model by at most ``ε`` times the
        model's L1 norm (module docstring). Must lie in (0, 0.1].
    time_bin : float, optional
        ``mode="time"``: averages never span more than this [s] (e.g. the gain solution interval,
        so that each average lies within one gain). Default: only the bound limits them.
    uv_cell : float, optional
        ``mode="uv"``: starting cell size [lambda]; default the largest cell whose worst case meets
        the bound.

    Returns
    -------
    Visibilities
        The averages, with :class:`AveragingReport` as ``provenance["averaging"]`` (a dict).

    Raises
    ------
    InputError
        An unknown ``mode``; ``mode="time"`` on data without antennas and times; a bound or bin
        that is not a positive number.

    Warns
    -----
    DataWarning
        A requested ``time_bin`` or ``uv_cell`` that would smear beyond ``max_smearing``: its
        groups are split to stay within the bound, and the message gives the smearing asked for and
        the ``max_smearing`` that would allow it.
    """
    if mode not in AVERAGING_MODES:
        raise InputError(f"average = {mode!r}: use one of {', '.join(map(repr, AVERAGING_MODES))}")
    if mode == "none":
        return vis
    if not (np.isfinite(max_smearing) and 0 < max_smearing <= 0.1):
        raise InputError(f"max_smearing = {max_smearing!r} must lie in (0, 0.1] (a fraction of the model's "
                         f"L1 norm; default {DEFAULT_MAX_SMEARING:g})")
    theta = smearing_angle(r_out, geometry)
    u, v, w = vis.u, vis.v, vis.weights
    V = vis.V
    if mode == "time":
        if not vis.has_antennas or vis.time is None:
            raise InputError("average = 'time' needs the antennas and time of every visibility, and these data "
                             f"({vis.provenance.get('source', 'in memory')}) do not record them: use average = 'uv' "
                             "([data] average in a configuration), or read a Measurement Set or a spiralbayes .h5 "
                             "file that keeps them")
        if time_bin is not None and not (np.isfinite(time_bin) and time_bin > 0):
            raise InputError(f"time_bin = {time_bin!r} must be a positive time [s], or None (bound only)")
        a1, a2, times = np.asarray(vis.antenna1), np.asarray(vis.antenna2), np.asarray(vis.time)
        n_ant = int(max(a1.max(), a2.max())) + 1
        key = a1 * n_ant + a2
        if time_bin is not None:
            window = np.floor((times - times.min()) / time_bin).astype(np.int64)
            key = key * (int(window.max()) + 1) + window
        requested = time_bin is not None
    else:
        flip = (v < 0) | ((v == 0) & (u < 0))
        u, v = np.where(flip, -u, u), np.where(flip, -v, v)
        V = np.where(flip, np.conj(V), V)
        requested = uv_cell is not None
        cell = _uv_cell_for(max_smearing, theta) if uv_cell is None else float(uv_cell)
        if not (np.isfinite(cell) and cell > 0):
            raise InputError(f"uv_cell = {uv_cell!r} must be a positive size [lambda], or None (from the bound)")
        iu = np.floor(u / cell).astype(np.int64)
        iv = np.floor(v / cell).astype(np.int64)
        iu -= iu.min()
        key = iv * (int(iu.max()) + 1) + iu
    _, groups = np.unique(key, return_inverse=True)
    groups, eps, first = _split_until_bounded(u, v, w, groups.ravel(), theta, max_smearing)
    n_split = int((first > max_smearing).sum())
    if requested and n_split:
        what = f"time_bin = {time_bin:g} s" if mode == "time" else f"uv_cell = {uv_cell:g} lambda"
        warnings.warn(f"{what} would smear the model by up to {first.max():.2e} of its L1 norm within "
                      f"{theta:.3g} arcsec, beyond the bound max_smearing = {max_smearing:.1e}; {n_split} of "
                      f"{first.size} averages were split to stay within it. To average as requested, pass "
                      f"max_smearing = {first.max():.2g} (or use a shorter bin)", DataWarning, stacklevel=2)
    W, _, mu, mv, *_ = _group_moments(u, v, w, groups)
    g = mu.size
    Vm = (np.bincount(groups, w * V.real, g) + 1j * np.bincount(groups, w * V.imag, g)) / W
    fields: dict = {}
    if mode == "time":
        first_row = np.zeros(g, dtype=np.int64)
        first_row[groups] = np.arange(groups.size)   # any row of a group: a group is one baseline's
        fields = {"antenna1": a1[first_row], "antenna2": a2[first_row],
                  "time": np.bincount(groups, w * times, g) / W}
    report = AveragingReport(mode=mode, n_in=vis.n, n_out=g, r_out=float(r_out), theta=theta,
                             max_smearing=float(max_smearing), smearing=float(eps.max()),
                             median_smearing=float(np.median(eps)),
                             time_bin=None if time_bin is None else float(time_bin),
                             uv_cell=None if mode == "time" else cell,
                             requested_smearing=float(first.max()), n_split=n_split)
    log.info(report.summary())
    return Visibilities(mu, mv, Vm, W, wavelength=vis.wavelength, conjugated=vis.conjugated,
                        provenance={**vis.provenance, "averaging": report.to_dict()}, **fields)
