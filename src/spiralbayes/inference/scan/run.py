"""The grid scan: Δχ² of every template at every planet position (Stevenson et al. 2024, sec. 2.3).

:func:`scan` runs the fast engine (:mod:`spiralbayes.inference.scan.engine`, where the method and
its exactness are described) over a template bank and the (r_p, phi_p) grid, with checkpoints
after every template, resume, progress bars and optional Dask parallelism; :class:`ScanResult`
holds the two terms of Δχ² = 2 cross - power per template and position.

Resume key
----------
A checkpoint is resumed only when it was written for the same inputs: :func:`.resume_key` records
a hash of the data, of the axisymmetric profile (its arrays, or the profile sampled on the
scanned radii) and frank's settings, each template's content hash (x, phi, δ) and metadata, the
(r_p, phi_p) grid, the geometry, the quadrature settings (the rule, ``cell_factor`` for the
midpoint rule, and the power path's settings, :class:`~.engine.EngineSettings`) and
spiralbayes' version, and, when morphology variants were scanned through their building blocks
(:mod:`.building_blocks`), which; a checkpoint written with other settings, or before they were
recorded, is refused. Any difference raises :class:`ResumeMismatchError` naming it; ``force_resume=True`` keeps
the completed templates anyway (same grid required). The thread count is not part of the key: it
changes the last digits only.

Accuracy
--------
Every template's ``cross`` and ``power`` come with error estimates (``cross_error``,
``power_error``; :mod:`~spiralbayes.inference.scan.engine` says how they are made); :meth:`ScanResult.delta_chi2_error`
combines them and :func:`scan` raises an :class:`~spiralbayes.exceptions.AccuracyWarning` where
the estimate exceeds ``0.05 + 1e-4 |Δχ²|`` (:mod:`.accuracy`).

Why this module is long: the result class (with its best instance, format-1 reader and the error
estimates), the runner and the resume key with its readable differences share one set of
fields; split apart, each would have to know the others' layout. The numerics live elsewhere
(:mod:`~spiralbayes.inference.scan.engine`, :mod:`.uv_levels`, :mod:`.accuracy`).
"""

from __future__ import annotations

import json
import logging
import time
import warnings
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from ..._provenance import content_hash, data_hash, json_safe, provenance_record
from ...results import ResultMixin, fields_dict
from ..._version import __version__
from ...exceptions import DataWarning, InputError, ResumeMismatchError
from ...axisymmetric.provenance import check_fitted_to
from ...geometry import DiscGeometry
from ...io.argument_checks import check_scan_arguments
from ...io.data_checks import check_search_data
from ...templates.template import repeated_names, template_metadata
from .accuracy import TOLERANCE, check_terms, warn_if_inaccurate
from .building_blocks import check_pairs, describe_blocks, scan_group, unit_rows, building_block_groups, work_units
from ...settings import with_overrides
from .engine import ScanContext, scan_template
from .settings import ScanSettings, grid_radii, renamed_keyword
from .statistics import bic_threshold, delta_chi2_from_terms

__all__ = ["ScanPeak", "ScanResult", "default_rp_grid", "resume_key", "scan"]

SCAN_KIND = "spiralbayes.ScanResult"
DATASET_UNITS = {"r_p": "arcsec", "phi_p": "rad", "cross": "dimensionless (chi^2 units)",
                 "power": "dimensionless (chi^2 units)", "cross_error": "dimensionless (chi^2 units)",
                 "power_error": "dimensionless (chi^2 units)"}
"""The ``units`` attribute of each dataset of a saved scan (Δχ² = 2 cross - power)."""

log = logging.getLogger(__name__)


def default_rp_grid(r_max: float, n: int = ScanSettings.n_r_p, r_min: float | None = None) -> np.ndarray:
    """Planet radii [arcsec]: ``n`` values from ``r_min`` (default ``r_max / n``) to ``r_max``.

    The paper used 25 radii between 0.02 and 0.5 arcsec for discs of about 0.8 arcsec radius
    (:func:`spiralbayes.inference.scan.settings.grid_radii`, which this is).
    """
    return grid_radii(r_min, r_max, n)



@dataclass(frozen=True)
class ScanPeak:
    """One scanned instance: the best of a template (or of the whole scan).

    Attributes
    ----------
    template : str
        Template name.
    template_index, i_rp, i_phi : int
        Indices into the scan's arrays.
    r_p, phi_p : float
        Planet position [arcsec, rad].
    delta_chi2, delta_bic : float
        Δχ² there and ``Δχ² − k ln N``.
    """

    template: str
    template_index: int
    r_p: float
    phi_p: float
    i_rp: int
    i_phi: int
    delta_chi2: float
    delta_bic: float

    def to_dict(self) -> dict:
        return fields_dict(self)


@dataclass(repr=False)
class ScanResult(ResultMixin):
    """Δχ² over template × r_p × phi_p, with what is needed to reproduce it.

    Attributes
    ----------
    templates : list of dict
        Template metadata (name, mass, tau0, beta, hand, ...), one per row of the arrays.
    r_p : ndarray
        Planet radii [arcsec].
    phi_p : ndarray
        Planet azimuths [rad] (disc azimuth convention).
    cross, power : ndarray, shape (n_templates, n_rp, n_phi)
        ``Re sum w R* ΔV`` and ``sum w |ΔV|^2``; NaN where not yet computed.
    chi2_AO : float
        χ² of the axisymmetric model.
    n_data : int
        Number of visibility points N.
    geometry : DiscGeometry
    distance : float or None
        Distance [pc], for au axes.
    provenance : dict
    cross_error, power_error : ndarray, shape (n_templates, n_rp, n_phi)
        Error estimates of ``cross`` and ``power`` (NaN where unknown: not computed, the midpoint
        rule, or a checkpoint written before they were recorded).
    """

    KIND = SCAN_KIND
    WHAT = "scan result"

    templates: list
    r_p: np.ndarray = field(metadata={"units": DATASET_UNITS["r_p"]})
    phi_p: np.ndarray = field(metadata={"units": DATASET_UNITS["phi_p"]})
    cross: np.ndarray = field(metadata={"units": DATASET_UNITS["cross"]})
    power: np.ndarray = field(metadata={"units": DATASET_UNITS["power"]})
    chi2_AO: float
    n_data: int
    geometry: DiscGeometry
    distance: float | None = None
    provenance: dict = field(default_factory=dict)
    cross_error: np.ndarray | None = field(default=None, metadata={"units": DATASET_UNITS["cross_error"]})
    power_error: np.ndarray | None = field(default=None, metadata={"units": DATASET_UNITS["power_error"]})

    def __post_init__(self):
        if self.cross_error is None:
            self.cross_error = np.full(np.shape(self.cross), np.nan)
        if self.power_error is None:
            self.power_error = np.full(np.shape(self.cross), np.nan)
        shape = (len(self.templates), np.size(self.r_p), np.size(self.phi_p))
        if any(np.shape(a) != shape for a in (self.cross, self.power, self.cross_error, self.power_error)):
            raise InputError(f"ScanResult: arrays of shape {np.shape(self.cross)} / {np.shape(self.power)} do not "
                             f"match {shape[0]} templates x {shape[1]} radii x {shape[2]} azimuths")

    def _error_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """``(cross_error, power_error)``, arrays since construction (NaN where there is no estimate)."""
        if self.cross_error is None or self.power_error is None:
            raise InputError("ScanResult: cross_error and power_error were set to None; they must be arrays "
                             "(NaN where there is no estimate)")
        return self.cross_error, self.power_error

    def delta_chi2_error(self) -> np.ndarray:
        """Error estimate of :meth:`delta_chi2` (the paper's fixed amplitude): ``2 cross_error + power_error``."""
        cross_error, power_error = self._error_arrays()
        return 2 * cross_error + power_error

    def accuracy_violations(self, tolerance=TOLERANCE) -> np.ndarray:
        """Where the error estimate exceeds ``tolerance[0] + tolerance[1] |Δχ²|`` (boolean, like ``cross``)."""
        err = np.nan_to_num(self.delta_chi2_error(), nan=0.0)
        return err > tolerance[0] + tolerance[1] * np.abs(np.nan_to_num(self.dchi2))

    def delta_chi2(self, amplitude=None) -> np.ndarray:
        """Δχ² array (template, r_p, phi_p); ``amplitude="free"`` fits a linear amplitude ≥ 0."""
        return delta_chi2_from_terms(self.cross, self.power, amplitude)

    @property
    def dchi2(self) -> np.ndarray:
        return self.delta_chi2()

    @property
    def completed(self) -> np.ndarray:
        return ~np.isnan(self.cross).any(axis=(1, 2))

    def n_params(self, amplitude=None) -> int:
        return 6 + (1 if amplitude == "free" else 0)

    def delta_bic(self, amplitude=None) -> np.ndarray:
        """ΔBIC of each template: peak Δχ² minus ``k ln N`` (k = 6, or 7 with a free amplitude)."""
        peak = np.nanmax(self.delta_chi2(amplitude), axis=(1, 2))
        return peak - bic_threshold(self.n_data, self.n_params(amplitude))

    @property
    def best(self) -> ScanPeak:
        """The scan's best instance (largest Δχ², the paper's fixed amplitude)."""
        return self.peak()

    def peak(self, template: int | str | None = None, amplitude=None) -> ScanPeak:
        """The best instance of one template (default: of the whole scan), for ``amplitude``."""
        dchi2 = self.delta_chi2(amplitude)
        if template is None:
            t, i, j = np.unravel_index(np.nanargmax(dchi2), dchi2.shape)
            t_index = int(t)
        else:
            t_index = self.template_index(template)
            i, j = np.unravel_index(np.nanargmax(dchi2[t_index]), dchi2.shape[1:])
        value = float(dchi2[t_index, i, j])
        return ScanPeak(self.templates[t_index]["name"], int(t_index), float(self.r_p[i]), float(self.phi_p[j]),
                        int(i), int(j), value, value - bic_threshold(self.n_data, self.n_params(amplitude)))

    def template_index(self, template: int | str) -> int:
        if isinstance(template, (int, np.integer)):
            return int(template)
        names = [t["name"] for t in self.templates]
        if template not in names:
            raise KeyError(f"no template named {template!r}; have {names}")
        return names.index(template)

    def summary(self) -> str:
        """The grid scanned and the best instance, in words."""
        done = int(self.completed.sum())
        text = (f"Scan of {len(self.templates)} templates ({done} done) over {self.r_p.size} radii "
                f"({self.r_p[0]:.3g}-{self.r_p[-1]:.3g} arcsec) x {self.phi_p.size} azimuths, N = {self.n_data} "
                f"visibilities, chi2 of the axisymmetric model {self.chi2_AO:.6g}.")
        if done:
            b = self.best
            au = f" ({b.r_p * self.distance:.0f} au)" if self.distance else ""
            text += (f" Best: {b.template} at r_p = {b.r_p:.3f} arcsec{au}, phi_p = {np.degrees(b.phi_p):.0f} deg, "
                     f"Delta chi2 = {b.delta_chi2:.1f}, Delta BIC = {b.delta_bic:.1f}.")
        return text

    def to_dict(self) -> dict:
        """The fields as JSON-safe values, with ``best`` (the best instance) when any template is done."""
        out = fields_dict(self)
        out["best"] = self.best.to_dict() if self.completed.any() else None
        return out

    def __repr__(self) -> str:
        done = int(self.completed.sum())
        head = (f"ScanResult({len(self.templates)} templates ({done} done), {self.r_p.size} r_p from "
                f"{self.r_p[0]:.3g} to {self.r_p[-1]:.3g} arcsec x {self.phi_p.size} phi_p, N = {self.n_data}, "
                f"chi2_AO = {self.chi2_AO:.6g}")
        if done:
            best = self.best
            head += f"; best {best.template}: Delta chi2 = {best.delta_chi2:.1f} at r_p = {best.r_p:.3g}"
        return head + ")"


def _read_format_1(f) -> ScanResult:
    """A scan written before the dataclass layout (``format_version`` 1)."""
    distance = float(f.attrs["distance"])
    return ScanResult(json.loads(f.attrs["templates"]), f["r_p"][()], f["phi_p"][()], f["cross"][()],
                      f["power"][()], float(f.attrs["chi2_AO"]), int(f.attrs["n_data"]),
                      DiscGeometry(**json.loads(f.attrs["geometry"])), None if distance < 0 else distance,
                      json.loads(f.attrs["provenance"]),
                      *(f[name][()] if name in f else None for name in ("cross_error", "power_error")))


ScanResult.LEGACY_READERS = {1: _read_format_1}


# --------------------------------------------------------------------------------------------
def scan(vis, axisymmetric, templates, geometry: DiscGeometry | None = None, *, settings: ScanSettings | None = None,
         r_p=None, scheduler=None, checkpoint=None, progress: bool = True, distance: float | None = None,
         force_resume: bool = False, allow_other_data: bool = False, **overrides) -> ScanResult:
    """Δχ² of every template at every planet position.

    Parameters
    ----------
    vis : Visibilities
        The observed data.
    axisymmetric : AxisymmetricModel or (profile, V_A)
        The axisymmetric model: frank's fit (its ``brightness`` [Jy/sr] and ``visibilities``),
        or a brightness callable and its model visibilities at ``vis``.
    templates : TemplateBank or sequence of SpiralTemplate
    geometry : DiscGeometry, optional
        Defaults to the axisymmetric model's.
    settings : ScanSettings, optional
        The grid and how the terms are computed (:class:`~.settings.ScanSettings`; the same
        options as the ``[grid]`` and ``[scan]`` sections of ``spiralbayes scan``). Default: the
        data-driven grid of ``n_r_p = 25`` radii up to 0.6 R_eff of ``axisymmetric`` and 90
        azimuths, the exact product quadrature.
    r_p : array_like, optional
        Planet radii [arcsec], positive, finite and increasing, instead of the grid of
        ``settings`` (``r_p_min``, ``r_p_max``, ``n_r_p``). Radii beyond the model's ``Rmax``
        raise a DataWarning.
    scheduler : None, "serial", "local", str or dask.distributed.Client, optional
        Run templates in parallel on Dask: ``"local"`` (a LocalCluster with one single-threaded
        worker per core), a scheduler address (``tcp://host:8786``) or an existing client; serial
        when None, ``""`` or ``"serial"``, or when Dask is not installed. On one machine a serial
        scan with ``nthreads`` = cores is as fast; Dask pays off on a cluster.
    checkpoint : path, optional
        HDF5 file updated after every template; an existing one with the same inputs (see
        :func:`.resume_key`) is resumed, one for other inputs raises
        :class:`~spiralbayes.exceptions.ResumeMismatchError`. Ignored when
        ``settings.checkpoint`` is False.
    progress : bool
        Show a tqdm progress bar.
    distance : float, optional
        Distance [pc], recorded for au axes.
    force_resume : bool
        Resume a checkpoint even though it was written for other inputs (its completed
        templates are kept where the names match; the grids must be the same). The
        differences are logged and recorded in ``provenance["forced_resume"]``.
    allow_other_data : bool
        Scan with an axisymmetric model whose recorded data hash is not that of ``vis`` (e.g.
        injected signals); by default such a model is refused (InputError).
    **overrides
        Fields of :class:`~.settings.ScanSettings` replacing those of ``settings``
        (``n_phi_p=46``, ``nthreads=2``, ``power_path="direct"``, ``building_blocks=False``, ...).
        ``rule=`` and ``client=``, the old names of ``quadrature=`` and ``scheduler=``, are
        accepted with a FutureWarning.

    Returns
    -------
    ScanResult
        Δχ² (and the cross and power terms, with error estimates) of every template at every
        ``(r_p [arcsec], phi_p [rad])``, with the provenance of the data, model and templates.

    Notes
    -----
    The result carries error estimates (:meth:`ScanResult.delta_chi2_error`); an
    :class:`~spiralbayes.exceptions.AccuracyWarning` says where they exceed
    ``0.05 + 1e-4 |Δχ²|``. The power path's own check is in ``provenance["power_check"]``, the
    settings used in ``provenance["scan_settings"]``. Results agree to ~1e-9 between thread
    counts and are identical for the same count.

    Examples
    --------
    >>> import spiralbayes as sb
    >>> vis = sb.simulate_observation("taurus", seed=1)  # the Taurus survey's set-up, no planet
    >>> disc = sb.fit_axisymmetric(vis, sb.DiscGeometry(inc=30, PA=60), progress=False, N=100)
    >>> templates = [sb.make_template(mass=3.0, tau0=3.0, beta=10.0, hand=h, wavelength=1.33e-3) for h in "RL"]
    >>> result = sb.scan(vis, disc, templates, r_p=[0.2, 0.3, 0.4], distance=140.0, progress=False)
    >>> result.delta_chi2().shape  # (template, r_p, phi_p)
    (2, 3, 90)

    Scan a whole bank with ``sb.default_bank()`` (576 templates) or a selection of it
    (``sb.default_bank().select(tau0=3, h_p=0.07)``).
    """
    scheduler = renamed_keyword(overrides, "client", "scheduler", scheduler, "scan")
    if "rule" in overrides:
        overrides["quadrature"] = renamed_keyword(overrides, "rule", "quadrature", overrides.get("quadrature"),
                                                  "scan")
    settings = with_overrides(settings, ScanSettings, overrides, "scan")
    check_scan_arguments(vis, axisymmetric, templates)
    templates = list(templates)
    if not templates:
        raise InputError("no templates to scan: pass a TemplateBank or a list of SpiralTemplate")
    dup = repeated_names(templates)
    if dup:  # results, checkpoints and test 3 find a template by its name
        raise InputError(f"{len(dup)} template name(s) occur more than once ({', '.join(map(repr, dup[:5]))}): "
                         "the scan's results are looked up by name, so give each template its own, e.g. "
                         "dataclasses.replace(template, name='run42_R')")
    check_search_data(vis, distance=distance)
    if not allow_other_data:
        check_fitted_to(axisymmetric, vis)
    geometry = geometry or getattr(axisymmetric, "geometry", None)
    if geometry is None:
        raise InputError("geometry is needed: pass geometry=DiscGeometry(...) or an AxisymmetricModel")
    r_p = settings.planet_radii(axisymmetric) if r_p is None else _check_rp(r_p)
    warn_beyond_rmax(axisymmetric, r_p)
    if checkpoint is not None and not settings.checkpoint:
        log.info("checkpoint %s not used: settings.checkpoint is False", checkpoint)
        checkpoint = None
    t0 = time.perf_counter()
    x_max = max(float(np.max(t.x)) for t in templates)
    context = ScanContext.build(vis, axisymmetric, geometry, r_p, settings.n_phi_p, x_max=x_max,
                                nthreads=settings.nthreads, settings=settings)
    setup_s = time.perf_counter() - t0
    log.info("scan set-up (%s power path, %d uv grids): %.2f s", context.power_path, len(context.levels), setup_s)
    _warn_if_weights_too_small(context.chi2_AO, vis.n)
    result = empty_result(context, templates, vis, distance)
    t_blocks = time.perf_counter()
    product = settings.quadrature == "product"
    groups, plain = building_block_groups(templates) if settings.building_blocks and product else ([], None)
    t_blocks = time.perf_counter() - t_blocks
    if groups:
        log.info("%d templates scanned through %d groups of building blocks",
                 sum(len(g.indices) for g in groups), len(groups))
    result.provenance["resume_key"] = resume_key(vis, axisymmetric, templates, context, describe_blocks(groups))
    result.provenance["scan_settings"] = json_safe(asdict(settings))
    if checkpoint is not None:
        result = resume_from_checkpoint(checkpoint, result, force_resume)
    todo = [i for i in range(len(templates)) if not result.completed[i]]
    if todo and product:
        context.algorithm_error = check_terms(context, templates[0])
        if groups:
            check_pairs(context, groups[0])
        result.provenance["power_check"] = context.algorithm_error
    t1 = time.perf_counter()
    runner = _run_serial if scheduler in (None, "", "serial") else _run_dask
    runner(context, work_units(templates, todo, groups, plain), result, checkpoint, progress, scheduler)
    result.provenance["scan_time_s"] = time.perf_counter() - t0
    result.provenance["timing_s"] = {"setup": setup_s, "building_blocks": t_blocks,
                                     "check": t1 - t0 - setup_s - t_blocks, "templates": time.perf_counter() - t1}
    warn_if_inaccurate(result)
    return result


def empty_result(context: ScanContext, templates, vis, distance) -> ScanResult:
    shape = (len(templates), context.r_p.size, context.n_phi_p)
    prov = provenance_record(
        data=vis.provenance, data_hash=data_hash(vis.u, vis.v, vis.V, vis.weights), quadrature=context.describe())
    return ScanResult([template_metadata(t) for t in templates], context.r_p.copy(),
                      2 * np.pi * np.arange(context.n_phi_p) / context.n_phi_p,
                      np.full(shape, np.nan), np.full(shape, np.nan), context.chi2_AO, int(vis.n),
                      context.geometry, distance, prov)


def _check_rp(r_p) -> np.ndarray:
    try:
        r_p = np.atleast_1d(np.asarray(r_p, dtype=float))
    except (TypeError, ValueError):
        raise InputError(f"r_p must be planet radii in arcsec (numbers), got {r_p!r}") from None
    if r_p.ndim != 1 or r_p.size == 0 or not np.all(np.isfinite(r_p)) or np.any(r_p <= 0):
        raise InputError(f"r_p must be positive, finite radii in arcsec (a 1-D grid), got {r_p}")
    if np.any(np.diff(r_p) <= 0):
        raise InputError(f"r_p must be strictly increasing (no repeated radii), got {r_p}")
    return r_p


def warn_beyond_rmax(axisymmetric, r_p) -> None:
    r_max = getattr(axisymmetric, "Rmax", None)
    if r_max is not None and r_p.max() > r_max:
        warnings.warn(f"planet radii up to {r_p.max():.3g} arcsec lie beyond frank's Rmax = {r_max:g} arcsec, "
                      "where the axisymmetric profile is zero (no spiral can show there): lower the largest "
                      "r_p or refit with a larger Rmax", DataWarning, stacklevel=3)


def _warn_if_weights_too_small(chi2_AO: float, n: int) -> None:
    """chi2_AO far below its expectation 2N means weights too small (it cannot be a poor model)."""
    ratio = chi2_AO / (2 * n)
    if ratio < 0.5:
        warnings.warn(f"the axisymmetric model fits the data with chi2 = {chi2_AO:.4g} for 2N = {2 * n} (Re and Im): "
                      f"the weights look about {1 / ratio:.3g} times too small (CASA's simobserve leaves WEIGHT = 1), "
                      "so every Delta chi2 and Delta BIC is too small by that factor; re-estimate them with "
                      "estimate_weights(vis, method='neighbours') ([data] estimate_weights = true)",
                      DataWarning, stacklevel=3)


def _axisymmetric_key(axisymmetric, r_p) -> tuple[str, dict]:
    """Hash of the axisymmetric profile and frank's settings (empty for a bare profile)."""
    if hasattr(axisymmetric, "r") and hasattr(axisymmetric, "I"):
        profile = content_hash(np.asarray(axisymmetric.r, float), np.asarray(axisymmetric.I, float),
                               float(getattr(axisymmetric, "Rmax", 0.0)))
        return profile, json_safe(dict(getattr(axisymmetric, "hyperparameters", {}) or {}))
    brightness, V_A = axisymmetric if isinstance(axisymmetric, tuple) else (axisymmetric.brightness, None)
    radii = np.linspace(0.0, 2.5 * float(np.max(r_p)), 2049)  # beyond the templates' reach (2.2 r_p)
    items = [np.asarray(brightness(radii), dtype=float)]
    if V_A is not None:
        items.append(np.asarray(V_A, dtype=complex))
    return content_hash(*items), {}


def resume_key(vis, axisymmetric, templates, context: ScanContext, structure: dict | None = None) -> dict:
    """Everything a checkpoint's numbers depend on, as hashes and small dicts (JSON-able).

    Two scans with equal keys compute identical arrays (for the same thread count). ``structure``:
    the building blocks used (:func:`.building_blocks.describe_blocks`), recorded only when there are some.
    """
    profile, settings = _axisymmetric_key(axisymmetric, context.r_p)
    key = {
        "spiralbayes": __version__,
        "data": data_hash(vis.u, vis.v, vis.V, vis.weights) + ("*" if getattr(vis, "conjugated", False) else ""),
        "axisymmetric_profile": profile,
        "axisymmetric_settings": settings,
        "templates": [content_hash(np.asarray(t.x), np.asarray(t.phi), np.asarray(t.delta), template_metadata(t))
                      for t in templates],
        "r_p": content_hash(context.r_p),
        "n_phi_p": context.n_phi_p,
        "geometry": context.geometry.to_dict(),
        "quadrature": context.settings.describe(),
    }
    if structure is not None:
        key["structure"] = structure
    return key


def _describe_differences(old: ScanResult, fresh: ScanResult) -> list[str]:
    """What differs between a checkpoint and the run that found it, in words."""
    a, b = old.provenance.get("resume_key"), fresh.provenance["resume_key"]
    if not isinstance(a, dict):
        return ["it holds no resume key (written by an older spiralbayes)"]
    diffs = []
    if a.get("spiralbayes") != b["spiralbayes"]:
        diffs.append(f"spiralbayes version ({a.get('spiralbayes')} -> {b['spiralbayes']})")
    if a.get("data") != b["data"]:
        diffs.append("the data (u, v, V or weights)")
    if a.get("axisymmetric_profile") != b["axisymmetric_profile"]:
        diffs.append("the axisymmetric model's profile")
    settings = _changed(a.get("axisymmetric_settings") or {}, b["axisymmetric_settings"])
    if settings:
        diffs.append(f"frank settings ({settings})")
    templates = _template_differences(old.templates, a.get("templates"), fresh.templates, b["templates"])
    if templates:
        diffs.append(templates)
    grid_changed = a.get("r_p") != b["r_p"] or a.get("n_phi_p") != b["n_phi_p"]
    if grid_changed:
        diffs.append(f"the planet grid ({_grid_text(old)} -> {_grid_text(fresh)})")
    geometry = _changed(a.get("geometry") or {}, b["geometry"])
    if geometry:
        diffs.append(f"geometry ({geometry})")
    quadrature = _changed(a.get("quadrature") or {}, b["quadrature"])
    if quadrature:
        diffs.append(f"quadrature settings ({quadrature})")
    if a.get("structure") != b.get("structure"):
        diffs.append("the building blocks of the variant templates (scanned through them or plainly)")
    return diffs


def _grid_text(result: ScanResult) -> str:
    return (f"{result.r_p.size} r_p from {result.r_p[0]:.4g} to {result.r_p[-1]:.4g} arcsec x "
            f"{result.phi_p.size} phi_p")


def _changed(a: dict, b: dict) -> str:
    keys = sorted(set(a) | set(b), key=str)
    return ", ".join(f"{k}: {a.get(k)!r} -> {b.get(k)!r}" for k in keys if a.get(k) != b.get(k))


def _template_differences(old_meta, old_hashes, new_meta, new_hashes) -> str:
    old = {m["name"]: h for m, h in zip(old_meta, old_hashes or [None] * len(old_meta))}
    new = {m["name"]: h for m, h in zip(new_meta, new_hashes)}
    changed = [n for n in new if n in old and old[n] != new[n]]
    parts = [f"{label}: {', '.join(names[:4])}{' ...' if len(names) > 4 else ''}" for label, names in (
        ("changed", changed), ("new", [n for n in new if n not in old]),
        ("only in the checkpoint", [n for n in old if n not in new])) if names]
    return f"templates ({'; '.join(parts)})" if parts else ""


def resume_from_checkpoint(checkpoint, fresh: ScanResult, force: bool = False) -> ScanResult:
    checkpoint = Path(checkpoint)
    if not checkpoint.exists():
        return fresh
    old = ScanResult.load(checkpoint)
    diffs = _describe_differences(old, fresh)
    if diffs and not force:
        raise ResumeMismatchError(
            f"checkpoint {checkpoint} was written for other inputs — {'; '.join(diffs)}: delete it (or use "
            "another checkpoint path) to start afresh, or pass force_resume=True (CLI: --force-resume) to "
            "keep its completed templates anyway")
    if diffs:
        if old.r_p.shape != fresh.r_p.shape or not np.allclose(old.r_p, fresh.r_p, rtol=1e-12, atol=0) \
                or old.phi_p.size != fresh.phi_p.size:
            raise ResumeMismatchError(f"checkpoint {checkpoint} cannot be force-resumed: its planet grid differs "
                                      "(r_p or n_phi_p); delete it to start afresh")
        log.warning("force-resuming %s although %s differ", checkpoint, "; ".join(diffs))
    rows = {m["name"]: i for i, m in enumerate(old.templates)}
    kept = []
    fresh_cross_error, fresh_power_error = fresh._error_arrays()
    old_cross_error, old_power_error = old._error_arrays()
    for i, meta in enumerate(fresh.templates):
        j = rows.get(meta["name"])
        if j is not None and old.completed[j]:
            fresh.cross[i], fresh.power[i] = old.cross[j], old.power[j]
            fresh_cross_error[i], fresh_power_error[i] = old_cross_error[j], old_power_error[j]
            kept.append(meta["name"])
    if diffs:
        fresh = _record_forced_resume(fresh, old, checkpoint, diffs, kept)
    log.info("resuming from %s: %d of %d templates done", checkpoint, fresh.completed.sum(), len(fresh.templates))
    return fresh


def _record_forced_resume(fresh: ScanResult, old: ScanResult, checkpoint, diffs, kept) -> ScanResult:
    """Record the truth of a forced resume: the numbers kept were computed with the checkpoint's inputs.

    When every template comes from the checkpoint, the result takes the checkpoint's geometry and
    resume key (what its numbers were computed with) and keeps the requested ones under
    ``provenance["forced_resume"]["requested"]``; otherwise the result is mixed and says which
    templates came from the checkpoint.
    """
    record = {"checkpoint": str(checkpoint), "differences": diffs, "templates_from_checkpoint": kept,
              "checkpoint_geometry": old.geometry.to_dict(), "checkpoint_resume_key": old.provenance.get("resume_key")}
    if len(kept) == len(fresh.templates):
        record["requested"] = {"geometry": fresh.geometry.to_dict(), "resume_key": fresh.provenance["resume_key"]}
        fresh.provenance["resume_key"] = old.provenance.get("resume_key")
        fresh = replace(fresh, geometry=old.geometry)
    else:
        record["mixed"] = ("templates_from_checkpoint were computed with the checkpoint's inputs, the others with "
                           "the requested ones")
    fresh.provenance["forced_resume"] = record
    return fresh


def store_template_terms(result: ScanResult, index: int, terms, checkpoint) -> None:
    """Keep one template's :class:`~.engine.TemplateTerms` (and checkpoint)."""
    result.cross[index], result.power[index] = terms
    cross_error, power_error = result._error_arrays()
    cross_error[index] = getattr(terms, "cross_error", np.nan)
    power_error[index] = getattr(terms, "power_error", np.nan)
    if checkpoint is not None:
        result.save(checkpoint)


def run_unit(context: ScanContext, unit) -> dict:
    """One unit of :func:`~.building_blocks.work_units`: groups of variants or ``(index, template)``."""
    if isinstance(unit, list):
        return scan_group(context, unit)
    index, template = unit
    return {index: scan_template(context, template)}


def _store_unit(result: ScanResult, terms: dict, checkpoint) -> int:
    """Keep the rows of one unit of work that are not done yet (a group may hold resumed rows); checkpoint once."""
    stored = 0
    for index, t in terms.items():
        if not result.completed[index]:
            store_template_terms(result, index, t, None)
            stored += 1
    if checkpoint is not None:
        result.save(checkpoint)
    return stored


def _progress(total: int, enabled: bool):
    from tqdm.auto import tqdm

    return tqdm(total=total, desc="templates", unit="template", disable=not enabled)


def _todo_rows(result: ScanResult, units) -> int:
    return sum(int(not result.completed[i]) for u in units for i in unit_rows(u))


def _run_serial(context, units, result, checkpoint, progress, scheduler=None) -> None:
    with _progress(_todo_rows(result, units), progress) as bar:
        for unit in units:
            bar.update(_store_unit(result, run_unit(context, unit), checkpoint))


def _run_dask(context, units, result, checkpoint, progress, scheduler) -> None:
    try:
        from dask.distributed import as_completed
    except ImportError:
        log.warning("dask.distributed is not installed: scanning serially (pip install 'dask[distributed]')")
        _run_serial(context, units, result, checkpoint, progress)
        return

    from ...cluster import open_scheduler

    # the engine closes what it started (client, cluster, worker processes) and never a client passed in
    with open_scheduler(scheduler, default="serial") as engine:
        if engine is None:
            _run_serial(context, units, result, checkpoint, progress)
            return
        shared = engine.scatter(context, broadcast=True)
        futures = [engine.submit(run_unit, shared, unit, pure=False) for unit in units]
        with _progress(_todo_rows(result, units), progress) as bar:
            for future in as_completed(futures):
                bar.update(_store_unit(result, future.result(), checkpoint))
