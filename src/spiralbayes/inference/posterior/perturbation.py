"""The spiral perturbation's visibilities at the data, from the tables of :mod:`.interpolation`.

:class:`FastPerturbation` owns one template's tables (built by ``interpolation._TableBuilder``,
refined in ``r_p`` until the interpolation error at node midpoints is below ``rp_tolerance``) and
evaluates ``cos i P_hat`` at the data with one type-2 NUFFT per call. Both the conditional
likelihood (:mod:`.likelihood`) and the profile-marginalised one (:mod:`.likelihood`) use it. The
build logs each refinement round and shows a progress bar of node builds when asked.
"""

from __future__ import annotations

import logging
import time
import warnings

import numpy as np

from ...exceptions import AccuracyWarning, InputError
from ...geometry import DiscGeometry
from ...model import profile_breaks, profile_support
from ...units import ARCSEC, TWO_PI
from .forked import forked_map
from .interpolation import PerturbationTable, _Cells, _TableBuilder

__all__ = ["CHECKED_MIDPOINTS", "CHECK_MARGIN", "FastPerturbation"]

log = logging.getLogger(__name__)

CHECKED_MIDPOINTS = 8
"""Midpoints at which a table started from another's step (``refine_from``) measures its error: the
other table's worst ones in its final round."""

CHECK_MARGIN = 0.5
"""Fraction of ``rp_tolerance`` below which the error at the checked midpoints accepts a table
started from another's step."""


class FastPerturbation:
    """``cos i P_hat(q; r_p, phi_p)`` at fixed baselines from the tables (see the module docs).

    Parameters
    ----------
    u, v, weights : ndarray
        The data's baselines [lambda] and weights (the weights only steer the r_p refinement).
    profile : callable
        ``I_A(r [arcsec])`` [Jy/sr] of the perturbation ``I_A delta``.
    template : SpiralTemplate
    r_range : (float, float)
        Planet radii [arcsec] to serve.
    reference_geometry : DiscGeometry
        Geometry at which the refinement measures interpolation errors.
    epsilon, oversample, rp_tolerance, rp_step, cell_factor, progress
        As :class:`~spiralbayes.inference.posterior.conditional.SpiralLikelihood`.
    mirror_of : FastPerturbation, optional
        The same perturbation for the mirror template (``template == mirror_of.template.mirror()``,
        same profile and baselines): its table is shared and one coordinate flipped.
    radial_cache : dict, optional
        Shared by tables of templates on one radial grid with the same ``profile`` object and
        baselines (a family's mass nodes): each radius's quadrature rule and radial integrals are
        computed once (the same numbers; more than half of a table's build).
    processes : int
        Worker processes that build each refinement round's ``r_p`` nodes (:func:`.forked.forked_map`;
        default 1: this process). The nodes are the same numbers either way.
    refine_from : FastPerturbation, optional
        A refined table of another template on the same radial grid, data, profile and ``r_p`` range
        (a family's heaviest mass node): this table starts at its step and measures the interpolation
        error at the midpoints nearest its worst ones only (:data:`CHECKED_MIDPOINTS`); where that
        exceeds ``CHECK_MARGIN rp_tolerance`` it refines further, over every midpoint. Where the
        error peaks is set by the profile's radial structure, which the templates share
        (docs/templates.md, "The mass in the posterior").
    """

    # declared because a mirror reads them from its partner (``mirror_of``) before assigning its own
    _cells: _Cells
    _delta: float
    table: PerturbationTable
    quadrature_error: float

    def __init__(self, u, v, weights, profile, template, r_range, reference_geometry: DiscGeometry, *,
                 epsilon: float = 1e-5, oversample: float = 1.5, rp_tolerance: float = 0.01,
                 rp_step: float | None = None, cell_factor: float = 20.0, progress: bool = False,
                 mirror_of: FastPerturbation | None = None, max_nodes: int = 2000, rp_order: int = 6,
                 radial_cache: dict | None = None, processes: int = 1, refine_from: FastPerturbation | None = None):
        t0 = time.perf_counter()
        r_lo, r_hi = float(r_range[0]), float(r_range[1])
        if not (0 < r_lo < r_hi):
            raise InputError(f"r_range = {r_range!r}: need 0 < r_min < r_max [arcsec]")
        self.template = template
        self.profile = profile
        self.r_range = (r_lo, r_hi)
        self.epsilon = float(epsilon)
        self.u, self.v, self.weights = u, v, weights
        self.reference_geometry = reference_geometry
        self._u32, self._v32 = u.astype(np.float32), v.astype(np.float32)
        self.uv_max = float(np.max(np.hypot(u, v)))
        self._complex = np.complex64 if self.epsilon >= 1e-6 else np.complex128
        self.mirrored = mirror_of is not None
        if mirror_of is not None:
            _check_mirror(mirror_of, template, r_range, u)
            self._cells, self._delta, self.table = mirror_of._cells, mirror_of._delta, mirror_of.table
            self.table_source = mirror_of.template.name
            self.quadrature_error = mirror_of.quadrature_error
            self.build_time_s = time.perf_counter() - t0
            return
        # the product rule built once for the largest table node (_lattice: up to
        # r_max + (order / 2 + 1) h for the first, largest step h) serves every smaller r_p
        h0 = float(rp_step) if rp_step is not None else (r_hi - r_lo) / 8.0
        r_cells = r_hi + (int(rp_order) // 2 + 1) * h0
        self._cells = _Cells.build(template, r_cells, self.uv_max, support=profile_support(profile),
                                   breaks=profile_breaks(profile), radial_cache=radial_cache)
        self._oversample = float(oversample)
        builder = self._builder()
        self._delta = builder.delta
        start = None
        if refine_from is not None and rp_step is None and refine_from.table.refinement:
            if tuple(refine_from.r_range) != self.r_range or refine_from.u.size != u.size:
                raise InputError("refine_from must be a table on the same data and r_p range")
            last = refine_from.table.refinement[-1]
            start = (last["step_arcsec"], last.get("worst_midpoints_arcsec", []))
        with forked_map(builder, processes) as build_nodes:
            self.table, self.n_node_builds = _refine(self, builder, build_nodes, rp_step, rp_tolerance, progress,
                                                     max_nodes, int(rp_order), start=start)
        self.table_source = getattr(template, "name", "")
        self.quadrature_error = _quadrature_error(self, rp_tolerance)
        self.build_time_s = time.perf_counter() - t0
        self.table.build_time_s = self.build_time_s

    def _builder(self) -> _TableBuilder:
        return _TableBuilder(self._cells, self.profile, self.r_range[1] * ARCSEC * self.uv_max, self._cells.x_max,
                             self._oversample)

    def midpoint_errors(self) -> tuple[np.ndarray, np.ndarray]:
        """Every node midpoint [arcsec] and the table's interpolation error there, in the norm of
        ``rp_tolerance``, against grids built afresh (the check a table started from another's step
        makes at a few midpoints only)."""
        exact = self._builder()
        return _midpoint_errors(self, self.table, lambda radii: [exact(r) for r in radii])

    # -- coordinates -----------------------------------------------------------------------------
    def check_r_p(self, r_p: float) -> None:
        if not (self.r_range[0] <= r_p <= self.r_range[1]):
            raise InputError(f"r_p = {r_p} arcsec is outside the likelihood's range {self.r_range}")

    def coords(self, r_p, phi_p, inc, PA) -> np.ndarray:
        """ducc0 coordinates ``2 pi Delta sigma`` of the data (n, 2), float32 or float64.

        ``sigma = r_p R(-phi_p) (xi, eta)`` with ``(xi, eta)`` the disc-frame baseline; the mirror
        of a template reads its partner's table at ``(sigma_xi, -sigma_eta)``.
        """
        ci = np.cos(np.radians(inc))
        cp, sp = np.cos(np.radians(PA)), np.sin(np.radians(PA))
        D = np.array([[-ci * cp, ci * sp], [sp, cp]])  # (u, v) -> (xi, eta)
        c, s = np.cos(phi_p), np.sin(phi_p)
        R = np.array([[c, s], [-s, c]])  # rotation by -phi_p
        L = TWO_PI * self._delta * r_p * ARCSEC * (R @ D)
        if self.mirrored:
            L[1] *= -1.0
        u, v = (self._u32, self._v32) if self._complex is np.complex64 else (self.u, self.v)
        L = L.astype(u.dtype)
        coord = np.empty((u.size, 2), dtype=u.dtype)
        for j in range(2):
            col = coord[:, j]
            np.multiply(u, L[j, 0], out=col)
            col += v * L[j, 1]
        return coord

    def u2nu(self, grid, coord) -> np.ndarray:
        import ducc0

        grid = grid.astype(self._complex, copy=False)
        coord = coord.astype(np.float32 if self._complex is np.complex64 else np.float64, copy=False)
        return ducc0.nufft.u2nu(grid=grid, coord=coord, forward=False, epsilon=self.epsilon, nthreads=1)

    def disc_frame(self, r_p, phi_p, inc, PA) -> np.ndarray:
        """``cos i P_hat`` at the data [Jy] (no phase-centre factor); complex64 by default."""
        ci = np.cos(np.radians(inc))
        grid = self.table.grid(r_p, scale=ci * (r_p * ARCSEC) ** 2)
        return self.u2nu(grid, self.coords(r_p, phi_p, inc, PA))

    def quadrature(self, r_p: float):
        return self._cells.quadrature(r_p)

    @property
    def nbytes(self) -> int:
        return 0 if self.mirrored else self.table.nbytes

    def describe(self) -> dict:
        return {"template": getattr(self.template, "name", ""), "r_range_arcsec": list(self.r_range),
                "n_rp_nodes": int(self.table.r_nodes.size), "rp_step_arcsec": self.table.step,
                "grid_N": int(self.table.N), "pseudo_pixel": self.table.delta, "sigma_max": self.table.sigma_max,
                "epsilon": self.epsilon, "table_bytes": int(self.nbytes), "build_time_s": self.build_time_s,
                "refinement": self.table.refinement, "n_cells": int(self._cells.positions.shape[0]),
                "table_from": self.table_source, "quadrature_error": float(self.quadrature_error)}

    def __getstate__(self):
        state = self.__dict__.copy()
        state.pop("profile", None)  # a bound method of the model: not needed after the build
        return state


def _check_mirror(other: FastPerturbation, template, r_range, u) -> None:
    mine = getattr(template, "delta", None)
    partner = other.template.mirror()
    same = (mine is not None and np.shape(mine) == np.shape(partner.delta)
            and np.allclose(np.asarray(mine, float), np.asarray(partner.delta, float), rtol=0, atol=1e-7)
            and np.array_equal(template.x, partner.x) and np.array_equal(template.phi, partner.phi))
    if not same or tuple(r_range) != tuple(other.r_range) or u.size != other.u.size:
        raise InputError(f"template {getattr(template, 'name', '')!r} is not the mirror of {other.template.name!r} "
                         "on the same data and r_p range: build its own table")


def _quadrature_error(fp: FastPerturbation, tolerance: float) -> float:
    """The product rule's bound over the table's radii in the norm of ``rp_tolerance``,
    ``sqrt(sum w |dV|^2) <= cos i B sqrt(sum w)`` (``B`` bounds ``|dP_hat|`` at every baseline,
    :meth:`~spiralbayes.quadrature.ProductQuadrature.error_bound`); warns above ``tolerance``."""
    bound = max(fp._cells.bounds.values(), default=0.0)
    error = fp.reference_geometry.cos_inc * bound * float(np.sqrt(np.sum(fp.weights)))
    if error > tolerance:
        msg = (f"{getattr(fp.template, 'name', 'the template')}: the quadrature's error bound sqrt(sum w |dV|^2) "
               f"<= {error:.3g} exceeds rp_tolerance = {tolerance:.3g}; give a profile without jumps inside the disc")
        log.warning(msg)
        warnings.warn(msg, AccuracyWarning, stacklevel=4)
    return error


def _refine(fp: FastPerturbation, builder: _TableBuilder, build_nodes, rp_step, tol, progress, max_nodes,
            order: int = 6, start: tuple | None = None) -> tuple[PerturbationTable, int]:
    """Uniform r_p nodes, halved until the midpoint interpolation error is below ``tol``; returns the
    table and the number of node grids built.

    The nodes of every round lie on one lattice anchored at ``r_min`` (:func:`_lattice`), so the
    midpoints whose exact grids measure a round's error are the next round's new nodes: no grid
    is built twice. While the error is far above ``tol`` (100x) the step is quartered
    (``order``-point interpolation errors fall like ``h^order`` once the profile is resolved).
    Measured on the fiducial frank profile, default prior: 6-point interpolation met the
    tolerance with 132 nodes where cubic needed 197-260. ``build_nodes(radii) -> grids`` builds a
    round's missing nodes together (in worker processes where asked). ``start = (step, radii)``
    begins at ``step``, measured at the midpoints nearest ``radii`` only (accepted below
    ``CHECK_MARGIN tol``), and refines over every midpoint from there.
    """
    r_lo, r_hi = fp.r_range
    h = float(rp_step) if rp_step is not None else (r_hi - r_lo) / 8.0
    checked = None
    if start is not None:
        h, checked = float(start[0]), np.asarray(start[1], float)
    cache: dict = {}

    def nodes_at(radii) -> list:
        keys = [round(float(r), 12) for r in radii]
        missing = [k for k in dict.fromkeys(keys) if k not in cache]
        for k, grid in zip(missing, build_nodes(missing)):
            cache[k] = grid
        return [cache[k] for k in keys]

    history: list[dict] = []
    name = getattr(fp.template, "name", "template")
    while True:
        nodes = _lattice(r_lo, r_hi, h, order)
        grids = np.stack(_with_progress(nodes_at, nodes, progress, f"{name}: r_p nodes"))
        table = PerturbationTable(nodes, grids, builder.delta, builder.sigma_max, fp.r_range, refinement=history,
                                  order=order)
        if rp_step is not None:
            return table, len(cache)
        mids, errors = _midpoint_errors(fp, table, nodes_at, near=checked)
        err = float(errors.max(initial=0.0))
        entry: dict = {"step_arcsec": h, "n_nodes": int(nodes.size), "max_midpoint_error": err}
        if checked is not None:
            entry["midpoints_checked"] = int(mids.size)
        else:
            worst = mids[np.argsort(errors)[::-1][:CHECKED_MIDPOINTS]]
            entry["worst_midpoints_arcsec"] = [float(r) for r in np.sort(worst)]
        history.append(entry)
        log.info("%s: r_p step %.4g arcsec, %d nodes, largest midpoint error %.3g (tolerance %.3g; %s)", name, h,
                 nodes.size, err, tol, "every midpoint" if checked is None else f"{mids.size} midpoints checked")
        # a check at a few midpoints accepts with room for the unchecked ones (on the fiducial
        # observation the eight came within 4 % of the largest error over every midpoint)
        if err <= (tol if checked is None else CHECK_MARGIN * tol):
            return table, len(cache)
        checked = None
        factor = 4.0 if err > 100 * tol else 2.0
        if _lattice(r_lo, r_hi, h / factor, order).size > max_nodes:
            log.warning("%s: r_p interpolation error %.3g > tolerance %.3g with %d nodes; the cap is %d nodes",
                        name, err, tol, nodes.size, max_nodes)
            return table, len(cache)
        h /= factor


def _lattice(r_lo: float, r_hi: float, h: float, order: int = 4) -> np.ndarray:
    """Nodes ``r_lo + k h`` covering ``[r_lo - (order/2 - 1) h, r_hi + (order/2) h]`` (>= ``order``
    nodes, none below 0: near ``r = 0`` the stencil becomes one-sided)."""
    below = order // 2 - 1
    k_lo = min(below, int(np.floor(r_lo / h)))
    k_hi = max(int(np.ceil((r_hi - r_lo) / h)) + order // 2, order - 1 - k_lo)
    return r_lo + h * np.arange(-k_lo, k_hi + 1)


def _midpoint_errors(fp: FastPerturbation, table: PerturbationTable, nodes_at, near=None):
    """The node midpoints inside the range (or those nearest the radii ``near``) and the largest
    data-weighted norm of the r_p-interpolation error at each, over four planet azimuths."""
    r_lo, r_hi = fp.r_range
    mids = 0.5 * (table.r_nodes[1:] + table.r_nodes[:-1])
    mids = mids[(mids >= r_lo) & (mids <= r_hi)]
    if near is not None and len(near):
        mids = np.unique(mids[np.abs(mids[:, None] - np.asarray(near)[None, :]).argmin(axis=0)])
    errors = np.zeros(mids.size)
    g0 = fp.reference_geometry
    for i, (r, exact) in enumerate(zip(mids, nodes_at(mids))):
        diff = table.grid(r) - exact
        scale = g0.cos_inc * (r * ARCSEC) ** 2
        for phi_p in (0.0, 0.5 * np.pi, np.pi, 1.5 * np.pi):
            dV = fp.u2nu(diff, fp.coords(r, phi_p, g0.inc, g0.PA)) * scale
            errors[i] = max(errors[i], float(np.sqrt(np.sum(fp.weights * np.abs(dV) ** 2))))
    return mids, errors


def _with_progress(nodes_at, radii, enabled: bool, desc: str, chunk: int = 8) -> list:
    """``nodes_at(radii)``, in chunks of ``chunk`` radii under a progress bar when ``enabled``."""
    if not enabled:
        return nodes_at(radii)
    from tqdm.auto import tqdm

    out: list = []
    with tqdm(total=len(radii), desc=desc, unit="node", leave=False, mininterval=1.0) as bar:
        for i in range(0, len(radii), chunk):
            out += nodes_at(radii[i:i + chunk])
            bar.update(len(radii[i:i + chunk]))
    return out
