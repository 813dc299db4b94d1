"""Interferometric visibilities: the :class:`Visibilities` container, binning and weights.

The container holds u, v [lambda], complex V [Jy] and weights [Jy^-2] and validates them on
construction; file formats live in :mod:`spiralbayes.io`. Also here: :func:`bin_deprojected`
(a "uvplot" of deprojected, binned visibilities) and :func:`estimate_weights` (one weight
rescaling factor from the scatter of the data, an explicit option), with two estimators: the
scatter within uv cells or deprojected annuli (:func:`.estimate_weight_factor`) and the scatter
about planes through uv neighbours (:func:`.neighbour_weight_factor`).

Why this module is long: the container, its binning and the two weight estimators share the
uv-plane folding and the provenance conventions; splitting them would scatter one topic (what
the weights of these visibilities are) over several files.

Conventions: ``V(u, v) = sum I(l, m) exp(+2 pi i (u l + v m))`` (CASA, frank, galario), u, v
being the Measurement Set's ``UVW[0:2] / lambda`` as stored. Data in the complex-conjugate
convention (e.g. exported by visread) carry ``conjugated=True``; call
:meth:`Visibilities.standardised` before modelling.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace
from collections.abc import Sequence

import numpy as np

from .exceptions import InputError
from .geometry import DiscGeometry
from .layout import ObservationLayout
from .units import C_LIGHT

__all__ = [
    "Visibilities",
    "BinnedVisibilities",
    "WeightRescaling",
    "bin_deprojected",
    "estimate_weight_factor",
    "estimate_weights",
    "neighbour_weight_factor",
]

log = logging.getLogger(__name__)


@dataclass
class Visibilities:
    """Visibilities of one source, in the convention of frank, galario and CASA.

    Parameters
    ----------
    u, v : ndarray, shape (N,)
        Baseline coordinates [lambda] (the Measurement Set's UVW[0:2] divided by the
        wavelength, as stored).
    V : ndarray of complex, shape (N,)
        Visibilities [Jy].
    weights : ndarray, shape (N,)
        Statistical weights ``1 / sigma^2`` [Jy^-2], sigma the noise of each of Re and Im.
        Zero weights (flagged data) are dropped at construction, with a logged count.
    wavelength : float, optional
        Observing wavelength [m], when known.
    conjugated : bool
        True if ``V`` is the complex conjugate of the frank/galario convention (e.g. data
        exported by visread). Use :meth:`standardised` before modelling.
    provenance : dict
        Where the data came from (file, reader, conversions applied).
    layout : ObservationLayout, optional
        Antennas, hour angles and w of every row, when known (simulated data); used by
        :func:`spiralbayes.io.write_ms` to write a Measurement Set with real antennas and times.
    antenna1, antenna2 : ndarray of int, shape (N,), optional
        The two antennas of each visibility, when the input records them (simulations, HDF5
        files written by spiralbayes, Measurement Sets); needed to diagnose or solve for
        antenna-based gain errors. Given together or not at all.
    time : ndarray, shape (N,), optional
        Time of each visibility [s] (any fixed origin: MJD seconds in a Measurement Set, seconds
        from the start in a simulation); only with ``antenna1`` and ``antenna2``.

    Notes
    -----
    Rows keep their antennas and times through :meth:`subset`, :meth:`standardised`,
    :meth:`with_V`, :meth:`with_weights` and the dropping of zero weights. The data hash used
    for provenance covers u, v, V and the weights only.
    """

    u: np.ndarray
    v: np.ndarray
    V: np.ndarray
    weights: np.ndarray
    wavelength: float | None = None
    conjugated: bool = False
    provenance: dict = field(default_factory=dict)
    layout: ObservationLayout | None = None
    antenna1: np.ndarray | None = None
    antenna2: np.ndarray | None = None
    time: np.ndarray | None = None

    def __post_init__(self):
        self.u = _real_array(self.u, "u")
        self.v = _real_array(self.v, "v")
        self.V = np.asarray(self.V, dtype=complex).ravel()
        self.weights = _real_array(self.weights, "weights")
        self._check_lengths()
        self._check_values()
        if self.layout is not None and self.layout.n != self.u.size:
            raise InputError(f"layout has {self.layout.n} rows for {self.u.size} visibilities")
        self._check_antennas()
        self._drop_zero_weights()
        if self.wavelength is not None:
            self.wavelength = float(self.wavelength)
            if not (np.isfinite(self.wavelength) and self.wavelength > 0):
                raise InputError(f"wavelength must be a positive number of metres, got {self.wavelength!r}")
        self.provenance = dict(self.provenance)

    def _check_lengths(self):
        lengths = {"u": self.u.size, "v": self.v.size, "V": self.V.size, "weights": self.weights.size}
        if len(set(lengths.values())) != 1:
            raise InputError(f"u, v, V and weights must have the same length, got {lengths}")
        if self.u.size == 0:
            raise InputError("no visibilities: u, v, V and weights are empty")

    def _check_values(self):
        for name, arr in (("u", self.u), ("v", self.v), ("V", self.V), ("weights", self.weights)):
            bad = ~np.isfinite(arr)
            if bad.any():
                raise InputError(
                    f"{name} has {bad.sum()} NaN/inf values (first at index {np.argmax(bad)}); "
                    "remove or flag those rows before loading"
                )
        if (self.weights < 0).any():
            n = int((self.weights < 0).sum())
            raise InputError(
                f"weights has {n} negative values (first at index {np.argmax(self.weights < 0)}); "
                "weights are 1/sigma^2 [Jy^-2] and must be >= 0"
            )

    def _check_antennas(self):
        if (self.antenna1 is None) != (self.antenna2 is None):
            raise InputError("give antenna1 and antenna2 together (the two antennas of each visibility), or neither")
        if self.antenna1 is None:
            if self.time is not None:
                raise InputError("time needs antenna1 and antenna2: give all three or drop time")
            return
        self.antenna1 = np.asarray(self.antenna1, dtype=np.int64).ravel()
        self.antenna2 = np.asarray(self.antenna2, dtype=np.int64).ravel()
        if self.time is not None:
            self.time = _real_array(self.time, "time")
        for name in ("antenna1", "antenna2", "time"):
            arr = getattr(self, name)
            if arr is not None and arr.size != self.u.size:
                raise InputError(f"{name} has {arr.size} entries for {self.u.size} visibilities")
        if self.time is not None and not np.isfinite(self.time).all():
            raise InputError("time has NaN/inf values; give a finite time [s] for every visibility")
        if (self.antenna1 < 0).any() or (self.antenna2 < 0).any():
            raise InputError("antenna1 and antenna2 must be antenna indices >= 0")

    @property
    def has_antennas(self) -> bool:
        """True when every visibility records its two antennas."""
        return self.antenna1 is not None

    def _row_fields(self, index) -> dict:
        """The per-row optional fields (layout, antennas, time) of the selected rows."""
        def pick(a):
            return None if a is None else a[index]

        return {"layout": None if self.layout is None else self.layout.subset(index),
                "antenna1": pick(self.antenna1), "antenna2": pick(self.antenna2), "time": pick(self.time)}

    def _drop_zero_weights(self):
        keep = self.weights > 0
        n_drop = int((~keep).sum())
        if n_drop == self.u.size:
            raise InputError("every visibility has zero weight (all flagged): nothing to fit")
        if n_drop:
            log.info("dropped %d visibilities with zero weight (flagged data)", n_drop)
            self.u, self.v, self.V, self.weights = (a[keep] for a in (self.u, self.v, self.V, self.weights))
            for name, value in self._row_fields(keep).items():
                setattr(self, name, value)
            self.provenance = {**self.provenance, "dropped_zero_weight": n_drop}

    # ------------------------------------------------------------------------------
    def __len__(self) -> int:
        return self.u.size

    @property
    def n(self) -> int:
        """Number of visibility points N (the N of the BIC)."""
        return self.u.size

    @property
    def uv_distance(self) -> np.ndarray:
        """Baseline length [lambda]."""
        return np.hypot(self.u, self.v)

    @property
    def sigma(self) -> np.ndarray:
        """Noise of each of Re V and Im V [Jy]."""
        return 1.0 / np.sqrt(self.weights)

    def standardised(self) -> Visibilities:
        """The same data in the frank/galario convention (un-conjugated if needed)."""
        if not self.conjugated:
            return self
        prov = {**self.provenance, "conjugated_on_load": True}
        return replace(self, V=np.conj(self.V), conjugated=False, provenance=prov)

    def subset(self, index) -> Visibilities:
        """A copy with only the selected rows (boolean mask or indices)."""
        return replace(self, u=self.u[index], v=self.v[index], V=self.V[index], weights=self.weights[index],
                       **self._row_fields(index))

    def with_weights(self, weights, note: str) -> Visibilities:
        """A copy with new weights; ``note`` is recorded in the provenance."""
        prov = {**self.provenance, "weights": note}
        return replace(self, weights=np.asarray(weights, dtype=float), provenance=prov)

    def with_V(self, V, note: str | None = None) -> Visibilities:
        """A copy with new visibility values (e.g. model or residuals)."""
        prov = self.provenance if note is None else {**self.provenance, "V": note}
        return replace(self, V=np.asarray(V, dtype=complex), provenance=prov)

    @property
    def frequency(self) -> float | None:
        """Observing frequency [Hz] (``C_LIGHT / wavelength``), when the wavelength is known."""
        return None if self.wavelength is None else C_LIGHT / self.wavelength

    def __repr__(self) -> str:
        q = self.uv_distance
        wle = "unknown" if self.wavelength is None else f"{self.wavelength:.6g} m"
        return (
            f"Visibilities(n={self.n}, baselines {q.min():.4g}-{q.max():.4g} lambda, "
            f"wavelength {wle}, conjugated={self.conjugated}, "
            f"source={self.provenance.get('source', 'in memory')!r})"
        )


def _real_array(x, name: str) -> np.ndarray:
    arr = np.asarray(x)
    if np.iscomplexobj(arr):
        raise InputError(f"{name} must be real, got complex values")
    try:
        return arr.astype(float).ravel()
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be numeric: {exc}") from None


# ----------------------------------------------------------------------------------
# deprojected radial binning
# ----------------------------------------------------------------------------------
@dataclass
class BinnedVisibilities:
    """Visibilities averaged in annuli of deprojected baseline length.

    Only bins holding at least one visibility are kept.

    Attributes
    ----------
    q : ndarray
        Bin centres [lambda] (deprojected baseline length ``hypot(u', v')``).
    q_low, q_high : ndarray
        Bin edges [lambda].
    re, im : ndarray
        Weighted means of Re V' and Im V' [Jy] (V' re-centred on the disc, not rescaled by cos i).
    re_err, im_err : ndarray
        Their standard errors from the weights, ``1 / sqrt(sum w)`` [Jy].
    counts : ndarray of int
        Number of visibilities in each bin.
    weight_sum : ndarray
        Sum of the weights in each bin [Jy^-2].
    geometry : DiscGeometry
        The geometry used to deproject.
    """

    q: np.ndarray
    q_low: np.ndarray
    q_high: np.ndarray
    re: np.ndarray
    im: np.ndarray
    re_err: np.ndarray
    im_err: np.ndarray
    counts: np.ndarray
    weight_sum: np.ndarray
    geometry: DiscGeometry

    @property
    def V(self) -> np.ndarray:
        """Binned complex visibilities [Jy]."""
        return self.re + 1j * self.im

    def __len__(self) -> int:
        return self.q.size


def _bin_edges(qmax: float, bin_width: float | None, bins) -> np.ndarray:
    if bin_width is not None and bins is not None:
        raise InputError("give either bin_width or bins, not both")
    if bins is not None and np.ndim(bins) == 0:
        n = int(bins)
        if n < 1:
            raise InputError(f"bins must be a positive number of bins, got {bins!r}")
        return np.linspace(0.0, qmax * (1 + 1e-12), n + 1)
    if bins is not None:
        edges = np.asarray(bins, dtype=float)
        if edges.ndim != 1 or edges.size < 2 or np.any(np.diff(edges) <= 0) or not np.isfinite(edges).all():
            raise InputError("bins must be an increasing 1-D array of at least two finite edges [lambda]")
        return edges
    width = qmax / 100.0 if bin_width is None else float(bin_width)
    if not (np.isfinite(width) and width > 0):
        raise InputError(f"bin_width must be a positive number of wavelengths, got {bin_width!r}")
    return np.arange(0.0, qmax + width, width)


def bin_deprojected(
    vis: Visibilities,
    geometry: DiscGeometry | None = None,
    *,
    bin_width: float | None = None,
    bins: int | Sequence[float] | None = None,
) -> BinnedVisibilities:
    """Average visibilities in annuli of deprojected baseline length (a "uvplot").

    The visibilities are re-centred and deprojected with
    :meth:`.DiscGeometry.apply_correction` (no ``cos i`` flux rescaling), then binned in
    ``q = hypot(u', v')`` with inverse-variance weights.

    Parameters
    ----------
    vis : Visibilities
        Data; used in the frank/galario convention (:meth:`Visibilities.standardised`).
    geometry : DiscGeometry, optional
        Disc geometry; default face on and centred (no deprojection).
    bin_width : float, optional
        Bin width [lambda]; bins then start at q = 0.
    bins : int or sequence of float, optional
        Number of equal bins from 0 to the longest baseline, or the bin edges [lambda].
        Default (neither given): 100 equal bins.

    Returns
    -------
    BinnedVisibilities
    """
    geometry = DiscGeometry() if geometry is None else geometry
    vis = vis.standardised()
    up, vp, Vp = geometry.apply_correction(vis.u, vis.v, vis.V)
    q = np.hypot(up, vp)
    edges = _bin_edges(float(q.max()), bin_width, bins)
    idx = np.digitize(q, edges) - 1
    inside = (idx >= 0) & (idx < edges.size - 1)
    if not inside.all():
        log.info("bin_deprojected: %d visibilities outside the bin edges ignored", int((~inside).sum()))
    nb = edges.size - 1
    w = vis.weights[inside]
    counts = np.bincount(idx[inside], minlength=nb)
    wsum = np.bincount(idx[inside], weights=w, minlength=nb)
    re = np.bincount(idx[inside], weights=w * Vp.real[inside], minlength=nb)
    im = np.bincount(idx[inside], weights=w * Vp.imag[inside], minlength=nb)
    keep = counts > 0
    err = 1.0 / np.sqrt(wsum[keep])
    return BinnedVisibilities(
        q=0.5 * (edges[:-1] + edges[1:])[keep], q_low=edges[:-1][keep], q_high=edges[1:][keep],
        re=re[keep] / wsum[keep], im=im[keep] / wsum[keep], re_err=err, im_err=err.copy(),
        counts=counts[keep], weight_sum=wsum[keep], geometry=geometry,
    )


# ----------------------------------------------------------------------------------
# weight re-estimation from the scatter in uv cells
# ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class WeightRescaling:
    """Result of :func:`.estimate_weight_factor`.

    Attributes
    ----------
    factor : float
        Multiply the weights by this to make them match the scatter of the data.
    factor_error : float
        1-sigma statistical error of ``factor`` (``factor * sqrt(2 / dof)``).
    dof : int
        Degrees of freedom in the estimate, ``2 * sum(n_cell - 1)`` over cells (Re and Im).
    n_cells : int
        Number of cells holding two or more visibilities.
    bin_width : float
        Cell size [lambda].
    binning : str
        ``'deprojected annuli'`` (with a geometry) or ``'uv cells'`` (without).
    """

    factor: float
    factor_error: float
    dof: int
    n_cells: int
    bin_width: float
    binning: str

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def _cell_index(vis: Visibilities, geometry, bin_width: float | None) -> tuple[np.ndarray, np.ndarray, float, str]:
    """Cell of each visibility, the visibilities to use (re-centred/folded) and the cell size."""
    V = vis.standardised().V
    if geometry is not None:
        up, vp, V = geometry.apply_correction(vis.u, vis.v, V)
        q = np.hypot(up, vp)
        width = bin_width or _default_width(q.max() - q.min(), vis.n, ndim=1)
        return np.floor((q - q.min()) / width).astype(np.int64), V, width, "deprojected annuli"
    # fold onto the half plane v >= 0 using V(-u, -v) = conj V(u, v), so that both halves share cells
    flip = (vis.v < 0) | ((vis.v == 0) & (vis.u < 0))
    u, v = np.where(flip, -vis.u, vis.u), np.where(flip, -vis.v, vis.v)
    V = np.where(flip, np.conj(V), V)
    width = bin_width or _default_width(float(np.hypot(u, v).max()), vis.n, ndim=2)
    iu, iv = np.floor(u / width).astype(np.int64), np.floor(v / width).astype(np.int64)
    _, cell = np.unique(np.stack([iu, iv]), axis=1, return_inverse=True)
    return cell.ravel(), V, width, "uv cells"


def _default_width(extent: float, n: int, ndim: int, per_cell: float = 10.0) -> float:
    """Cell size giving about ``per_cell`` points per cell for uniform coverage."""
    if ndim == 1:
        return max(extent, 1.0) * per_cell / n
    return float(np.sqrt(0.5 * np.pi * max(extent, 1.0) ** 2 * per_cell / n))


def estimate_weight_factor(
    vis: Visibilities,
    geometry: DiscGeometry | None = None,
    *,
    bin_width: float | None = None,
    min_dof: int = 20,
) -> WeightRescaling:
    """Estimate one factor ``f`` such that ``f * weights`` matches the scatter of the data.

    Within each cell, the weighted mean of Re V and Im V is subtracted and
    ``chi2 = sum w (dRe^2 + dIm^2)`` accumulated; for correct weights its expectation is
    ``dof = 2 sum (n_cell - 1)``, and if the true weights are ``f w`` it is ``dof / f``. So
    ``f = dof / chi2``, with relative error ``sqrt(2 / dof)``. Like frank's
    ``estimate_weights`` this assumes the signal is nearly constant within a cell:
    structure in the source adds scatter and biases ``f`` low, so keep cells small
    (many visibilities per cell help).

    Parameters
    ----------
    vis : Visibilities
    geometry : DiscGeometry, optional
        If given, cells are annuli of deprojected baseline length of the re-centred data
        (assumes an axisymmetric source, as frank does). Otherwise square cells in the
        (u, v) plane, with the two half planes folded together (no symmetry assumed).
    bin_width : float, optional
        Cell size [lambda]. Default: about 10 visibilities per cell for uniform coverage.
    min_dof : int
        Fewer degrees of freedom than this raise :class:`ValueError`.

    Returns
    -------
    WeightRescaling
    """
    if bin_width is not None and not (np.isfinite(bin_width) and bin_width > 0):
        raise InputError(f"bin_width must be a positive number of wavelengths, got {bin_width!r}")
    cell, V, width, binning = _cell_index(vis, geometry, bin_width)
    w = vis.weights
    wsum = np.bincount(cell, weights=w)
    counts = np.bincount(cell)
    wV = np.bincount(cell, weights=w * V.real) + 1j * np.bincount(cell, weights=w * V.imag)
    mean = np.divide(wV, wsum, out=np.zeros_like(wV), where=wsum > 0)  # empty cells never indexed
    chi2 = float(np.sum(w * np.abs(V - mean[cell]) ** 2))
    dof = int(2 * np.sum(np.maximum(counts - 1, 0)))
    if dof < min_dof or chi2 <= 0:
        raise InputError(
            f"estimate_weight_factor: only {dof} degrees of freedom with cells of {width:.4g} lambda "
            f"({int((counts > 1).sum())} cells with 2+ visibilities); increase bin_width"
        )
    factor = dof / chi2
    return WeightRescaling(factor=factor, factor_error=factor * np.sqrt(2.0 / dof), dof=dof,
                           n_cells=int((counts > 1).sum()), bin_width=float(width), binning=binning)


def neighbour_weight_factor(vis: Visibilities, max_points: int = 20_000, seed: int = 0) -> WeightRescaling:
    """One factor ``f`` such that ``f * weights`` matches the scatter about planes through uv neighbours.

    Each visibility is predicted from its three nearest uv neighbours by the plane through them
    (barycentric weights ``b``), which cancels the signal's gradient; ``d = V_i - sum b_m V_m`` is
    then nearly pure noise and ``|d|^2 / (2 (1/w_i + sum b_m^2 / w_m))`` is exponentially
    distributed with mean ``1/f``. The median of that ratio gives ``f = ln 2 / median`` — robust
    against the minority of points where the signal curves between neighbours; curvature can only
    add scatter, biasing ``f`` low. No model, geometry or symmetry is assumed. Measured with correct
    weights: 1.02 (fiducial synthetic set-up), 0.98 (Taurus set-up), 1.01 (high-sensitivity set-up,
    4.4e5 visibilities, ~1 s on 2 busy cores; ``benchmarks/bench_guards.py``), 0.93 (3000 random
    baselines at peak S/N 1000), 0.89 (the 196-point AS 209 sample); with weights 1.1e4 times too
    small it returned 1.14e4 (true: 1.13e4). For comparison,
    :func:`.estimate_weight_factor` in uv cells gave 0.024 on the fiducial set-up (the bright disc
    varies within a cell) and in deprojected annuli 1.00 there but 0.67 on a disc with a spiral.

    Parameters
    ----------
    vis : Visibilities
        Hermitian symmetry folds the uv plane onto ``v >= 0`` first.
    max_points : int
        With more visibilities, a random subset (fixed ``seed``) is predicted from its neighbours
        among all of them.
    seed : int

    Returns
    -------
    WeightRescaling
        ``dof`` and ``n_cells`` are the number of points used (those inside or near their
        neighbours' triangle: barycentric weights within ±3), ``bin_width`` is NaN.
    """
    from scipy.spatial import cKDTree

    flip = (vis.v < 0) | ((vis.v == 0) & (vis.u < 0))
    uv = np.column_stack([np.where(flip, -vis.u, vis.u), np.where(flip, -vis.v, vis.v)])
    V = vis.standardised().V
    V = np.where(flip, np.conj(V), V)
    rows = np.arange(vis.n)
    if vis.n > max_points:
        rows = np.sort(np.random.default_rng(seed).choice(vis.n, max_points, replace=False))
    tree = cKDTree(uv, balanced_tree=False, compact_nodes=False)  # twice as fast to build, as fast to query
    nb = tree.query(uv[rows], k=4)[1][:, 1:] if vis.n >= 4 else np.zeros((0, 3), int)
    rows = rows[: nb.shape[0]]
    # barycentric weights b of each point in its neighbours' triangle: [x_m; y_m; 1] b = [x; y; 1]
    A = np.concatenate([uv[nb].transpose(0, 2, 1), np.ones((rows.size, 1, 3))], axis=1)
    rhs = np.concatenate([uv[rows], np.ones((rows.size, 1))], axis=1)[..., None]
    ok = np.abs(np.linalg.det(A)) > 1e-9 * np.abs(A[:, :2]).max(axis=(1, 2), initial=0.0) ** 2
    b = np.linalg.solve(A[ok], rhs[ok])[..., 0]
    good = np.abs(b).max(axis=1) < 3
    i, nb, b = rows[ok][good], nb[ok][good], b[good]
    if i.size < 20:
        raise InputError(f"neighbour_weight_factor: only {i.size} visibilities have three uv neighbours around "
                         "them; too few to estimate the weights")
    residual = V[i] - np.sum(b * V[nb], axis=1)
    variance = 1.0 / vis.weights[i] + np.sum(b ** 2 / vis.weights[nb], axis=1)
    median = float(np.median(np.abs(residual) ** 2 / (2.0 * variance)))
    factor = float(np.log(2.0) / median) if median > 0 else float("inf")
    # the sample median of an exponential has relative error 1 / (sqrt(n) ln 2)
    return WeightRescaling(factor=factor, factor_error=factor / (np.sqrt(i.size) * np.log(2.0)), dof=int(i.size),
                           n_cells=int(i.size), bin_width=float("nan"), binning="uv neighbour planes")


def estimate_weights(
    vis: Visibilities,
    geometry: DiscGeometry | None = None,
    *,
    bin_width: float | None = None,
    method: str = "scatter",
) -> Visibilities:
    """Rescale the weights by one factor estimated from the scatter of the data.

    An explicit option — spiralbayes never rescales weights on its own. CASA weights are
    often not statistical (and uvplot's export halves them): this measures by how much.
    See :func:`.estimate_weight_factor` for the estimator and its assumptions.

    Parameters
    ----------
    vis : Visibilities
    geometry : DiscGeometry, optional
        Bin in deprojected annuli (axisymmetric source) instead of uv cells.
    bin_width : float, optional
        Cell size [lambda].
    method : {'scatter', 'neighbours'}
        ``'scatter'``: within uv cells or deprojected annuli (:func:`.estimate_weight_factor`;
        give the geometry for a bright disc). ``'neighbours'``: about planes through uv
        neighbours (:func:`.neighbour_weight_factor`; ``geometry`` and ``bin_width`` unused).

    Returns
    -------
    Visibilities
        A copy with weights ``factor * weights``; the factor, its error and the binning are
        recorded in ``provenance['weight_rescaling']`` and logged.
    """
    if method not in ("scatter", "neighbours"):
        raise InputError(f"method={method!r} is not known: use 'scatter' or 'neighbours'")
    if method == "neighbours":
        result = neighbour_weight_factor(vis)
        log.info("weights rescaled by %.4g +/- %.2g (scatter about %s, %d points)",
                 result.factor, result.factor_error, result.binning, result.dof)
    else:
        result = estimate_weight_factor(vis, geometry, bin_width=bin_width)
        log.info("weights rescaled by %.4g +/- %.2g (scatter in %d %s of %.4g lambda, %d dof)",
                 result.factor, result.factor_error, result.n_cells, result.binning, result.bin_width, result.dof)
    where = "about" if method == "neighbours" else "within"
    note = f"rescaled by {result.factor:.6g} (scatter {where} {result.binning})"
    record = {**result.to_dict(), "method": method,
              "geometry": None if geometry is None else geometry.to_dict()}
    new = vis.with_weights(vis.weights * result.factor, note)
    new.provenance["weight_rescaling"] = record
    return new
