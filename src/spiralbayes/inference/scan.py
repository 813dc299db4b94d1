"""The grid scan: Δχ² of every template at every planet position (Stevenson et al. 2024, sec. 2.3).

:func:`scan` runs the fast engine (:mod:`spiralbayes.inference.scan_engine`, where the method and
its exactness are described) over a template bank and the (r_p, phi_p) grid, with checkpoints
after every template, resume, progress bars and optional Dask parallelism; :class:`ScanResult`
holds the two terms of Δχ² = 2 cross - power per template and position.
"""

from __future__ import annotations

import json
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._hdf5 import open_file, write_file
from .._provenance import data_hash, json_default, provenance_record
from ..exceptions import InputError
from ..geometry import DiscGeometry
from ..model import DEFAULT_CELL_FACTOR
from ..templates.template import template_metadata
from .scan_engine import ScanContext, scan_template
from .statistics import bic_threshold, delta_chi2_from_terms

__all__ = ["ScanResult", "default_rp_grid", "scan"]

SCAN_KIND = "spiralbayes.ScanResult"

log = logging.getLogger(__name__)


def default_rp_grid(r_max: float, n: int = 25, r_min: float | None = None) -> np.ndarray:
    """Planet radii [arcsec]: ``n`` values from ``r_min`` (default ``r_max / 25``) to ``r_max``.

    The paper used 25 radii between 0.02 and 0.5 arcsec for discs of about 0.8 arcsec radius.
    """
    r_min = r_max / n if r_min is None else r_min
    return np.linspace(r_min, r_max, n)


@dataclass
class ScanResult:
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
    """

    templates: list
    r_p: np.ndarray
    phi_p: np.ndarray
    cross: np.ndarray
    power: np.ndarray
    chi2_AO: float
    n_data: int
    geometry: DiscGeometry
    distance: float | None = None
    provenance: dict = field(default_factory=dict)

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

    def best(self, template: int | str | None = None, amplitude=None) -> dict:
        """The best instance of one template (or overall): indices, position and Δχ²."""
        dchi2 = self.delta_chi2(amplitude)
        t_index = self.template_index(template) if template is not None else None
        if t_index is None:
            t_index, i, j = np.unravel_index(np.nanargmax(dchi2), dchi2.shape)
        else:
            i, j = np.unravel_index(np.nanargmax(dchi2[t_index]), dchi2.shape[1:])
        value = float(dchi2[t_index, i, j])
        return {"template": self.templates[t_index]["name"], "template_index": int(t_index),
                "r_p": float(self.r_p[i]), "phi_p": float(self.phi_p[j]), "i_rp": int(i), "i_phi": int(j),
                "delta_chi2": value,
                "delta_bic": value - bic_threshold(self.n_data, self.n_params(amplitude))}

    def template_index(self, template: int | str) -> int:
        if isinstance(template, (int, np.integer)):
            return int(template)
        names = [t["name"] for t in self.templates]
        if template not in names:
            raise KeyError(f"no template named {template!r}; have {names}")
        return names.index(template)

    # -- persistence ------------------------------------------------------------------------
    def save(self, path) -> Path:
        """Write to HDF5 (atomically)."""
        with write_file(path, SCAN_KIND) as f:
            for name in ("r_p", "phi_p", "cross", "power"):
                f.create_dataset(name, data=getattr(self, name))
            f.attrs["chi2_AO"] = self.chi2_AO
            f.attrs["n_data"] = self.n_data
            f.attrs["geometry"] = json.dumps(self.geometry.to_dict())
            f.attrs["distance"] = -1.0 if self.distance is None else self.distance
            f.attrs["templates"] = json.dumps(self.templates, default=json_default)
            f.attrs["provenance"] = json.dumps(self.provenance, default=json_default)
        return Path(path)

    @classmethod
    def load(cls, path) -> "ScanResult":
        with open_file(path, SCAN_KIND, "scan result") as f:
            distance = float(f.attrs["distance"])
            return cls(json.loads(f.attrs["templates"]), f["r_p"][()], f["phi_p"][()], f["cross"][()],
                       f["power"][()], float(f.attrs["chi2_AO"]), int(f.attrs["n_data"]),
                       DiscGeometry(**json.loads(f.attrs["geometry"])), None if distance < 0 else distance,
                       json.loads(f.attrs["provenance"]))


# --------------------------------------------------------------------------------------------
def scan(vis, axisymmetric, templates, geometry: DiscGeometry | None = None, *, r_p=None, n_phi_p: int = 90,
         distance: float | None = None, checkpoint=None, client=None, progress: bool = True,
         cell_factor: float = DEFAULT_CELL_FACTOR, nthreads: int = 1) -> ScanResult:
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
    r_p : array_like, optional
        Planet radii [arcsec]; default 25 radii up to 0.6 R_eff (the paper's 0.02–0.5 arcsec).
    n_phi_p : int
        Number of planet azimuths over 360 deg (default 90: 4 deg steps, as the paper).
    distance : float, optional
        Distance [pc], recorded for au axes.
    checkpoint : path, optional
        HDF5 file updated after every template; an existing one with the same inputs is resumed.
    client : dask.distributed.Client, str, or "local", optional
        Run templates in parallel on a Dask cluster (a scheduler address, an existing client, or
        ``"local"`` for a LocalCluster with one single-threaded worker per core); serial when None
        or when Dask is not installed. On one machine a serial scan with ``nthreads`` = cores is
        as fast; Dask pays off on a cluster (one scan per disc, or many discs at once).
    progress : bool
        Show a tqdm progress bar.
    cell_factor : float
        Quadrature cells are at most ``1 / (cell_factor u_max)`` across (see :mod:`spiralbayes.model`).
    nthreads : int
        Threads for the NUFFTs of each template. Results agree to ~1e-6 of ``power`` between
        thread counts (single-precision power term) and are identical for the same count.
    """
    templates = list(templates)
    if not templates:
        raise InputError("no templates to scan: pass a TemplateBank or a list of SpiralTemplate")
    geometry = geometry or getattr(axisymmetric, "geometry", None)
    if geometry is None:
        raise InputError("geometry is needed: pass geometry=DiscGeometry(...) or an AxisymmetricModel")
    r_p = _default_rp(axisymmetric) if r_p is None else np.atleast_1d(np.asarray(r_p, dtype=float))
    if np.any(r_p <= 0):
        raise InputError(f"r_p must be positive radii in arcsec, got {r_p}")
    t0 = time.perf_counter()
    context = ScanContext.build(vis, axisymmetric, geometry, r_p, n_phi_p, cell_factor, nthreads=nthreads)
    log.info("scan set-up (residual, uv weights on a %d x %d polar grid): %.2f s",
             *context.uv_weights_hat.shape, time.perf_counter() - t0)
    result = _empty_result(context, templates, vis, distance)
    if checkpoint is not None:
        result = _resume(checkpoint, result)
    todo = [i for i in range(len(templates)) if not result.completed[i]]
    runner = _run_dask if client is not None else _run_serial
    runner(context, templates, todo, result, checkpoint, progress, client)
    result.provenance["scan_time_s"] = time.perf_counter() - t0
    return result


def _default_rp(axisymmetric) -> np.ndarray:
    r_eff = getattr(axisymmetric, "R_eff", None)
    if r_eff is None:
        raise InputError("give r_p (planet radii in arcsec): the axisymmetric model has no R_eff")
    r_max = 0.6 * float(r_eff() if callable(r_eff) else r_eff)
    return default_rp_grid(r_max)


def _empty_result(context: ScanContext, templates, vis, distance) -> ScanResult:
    shape = (len(templates), context.r_p.size, context.n_phi_p)
    prov = provenance_record(
        data=vis.provenance, data_hash=data_hash(vis.u, vis.v, vis.V, vis.weights),
        cell_factor=context.cell_factor, n_theta=context.n_theta, d_rho=context.d_rho)
    return ScanResult([template_metadata(t) for t in templates], context.r_p.copy(),
                      2 * np.pi * np.arange(context.n_phi_p) / context.n_phi_p,
                      np.full(shape, np.nan), np.full(shape, np.nan), context.chi2_AO, int(vis.n),
                      context.geometry, distance, prov)


def _resume(checkpoint, fresh: ScanResult) -> ScanResult:
    checkpoint = Path(checkpoint)
    if not checkpoint.exists():
        return fresh
    old = ScanResult.load(checkpoint)
    same = (old.provenance.get("data_hash") == fresh.provenance["data_hash"]
            and old.templates == fresh.templates and np.array_equal(old.r_p, fresh.r_p)
            and np.array_equal(old.phi_p, fresh.phi_p) and old.geometry == fresh.geometry)
    if not same:
        raise InputError(
            f"checkpoint {checkpoint} was written for different inputs (data, templates, grid or "
            "geometry): delete it or choose another checkpoint path")
    log.info("resuming from %s: %d of %d templates done", checkpoint, old.completed.sum(), len(old.templates))
    fresh.cross, fresh.power = old.cross, old.power
    return fresh


def _store(result: ScanResult, index: int, cross, power, checkpoint) -> None:
    result.cross[index], result.power[index] = cross, power
    if checkpoint is not None:
        result.save(checkpoint)


def _progress(total: int, enabled: bool):
    from tqdm.auto import tqdm

    return tqdm(total=total, desc="templates", unit="template", disable=not enabled)


def _run_serial(context, templates, todo, result, checkpoint, progress, client=None) -> None:
    with _progress(len(todo), progress) as bar:
        for i in todo:
            _store(result, i, *scan_template(context, templates[i]), checkpoint)
            bar.update()


def _run_dask(context, templates, todo, result, checkpoint, progress, client) -> None:
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError:
        log.warning("dask.distributed is not installed: scanning serially (pip install 'dask[distributed]')")
        _run_serial(context, templates, todo, result, checkpoint, progress)
        return

    own = None
    if isinstance(client, str):
        if client == "local":
            own = Client(LocalCluster(processes=True, threads_per_worker=1))
        else:
            own = Client(client)
        client = own
    try:
        shared = client.scatter(context, broadcast=True)
        futures = {client.submit(scan_template, shared, templates[i], pure=False): i for i in todo}
        with _progress(len(todo), progress) as bar:
            for future in as_completed(futures):
                _store(result, futures[future], *future.result(), checkpoint)
                bar.update()
    finally:
        if own is not None:
            own.close()
