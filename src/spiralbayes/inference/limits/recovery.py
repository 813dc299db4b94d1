"""Detection completeness by injection–recovery: P(detected | M_p, r_p) and the minimum detectable mass.

For every mass of a template family, every radius and ``n_azimuths`` azimuths of the scan's grid,
a planet (the family's template of that mass and hand, scaled by its limits' margin: 0.45 for a
learned template, as :func:`~spiralbayes.inference.limits.compute_limits` assumes; 1 otherwise) is
planted into the user's own data and the detection of :func:`~spiralbayes.inference.detection.detect`
is run again: ΔBIC > 10 (test 1) and the handedness and compactness tests (test 2). A planet counts
as *recovered* when the verdict is a detection whose best template has the planted hand and lies
within ``max_rp_steps`` radius steps and ``max_phi_deg`` of the planted position.

Neither frank nor the scan is re-run per injection: the injected dataset's Δχ² at every scanned
instance is the data's Δχ² plus ``2 X(a, b)``, the cross term of the injected perturbation with
each scanned one (:mod:`spiralbayes.inference.limits.injection` states the algebra and how ``X`` comes
from the scan's polar uv grid). :func:`completeness_brute_force` re-scans injected datasets (and
optionally refits the axisymmetric model) as the reference.

``M_det(r_p)`` at a completeness level q is the smallest mass from which on every bank mass is
recovered with probability ≥ q, interpolated linearly in ln M between the last bank mass below q
and the next one (``"below_bank"`` when the lightest already reaches q).
"""

from __future__ import annotations

import json
import logging
import time
from dataclasses import dataclass, field, fields, replace

import numpy as np

from ..._provenance import provenance_record
from ...exceptions import InputError
from ...results import ResultMixin
from ...settings import with_overrides
from ...units import wrap_angle
from ..detection.settings import DetectionSettings
from ...templates.template import limit_margin
from ..detection.verdict import detect
from .families import Family, select_family, template_families
from .injection import Injection, InjectionEngine, brute_force_injection
from .settings import CompletenessSettings
from ..scan.run import ScanResult
from ..scan.engine import ScanContext

__all__ = ["CompletenessResult", "completeness", "completeness_brute_force", "injection_engine", "injection_plan"]

COMPLETENESS_KIND = "spiralbayes.CompletenessResult"

log = logging.getLogger(__name__)


@dataclass(repr=False)
class CompletenessResult(ResultMixin):
    """Outcome of injection–recovery over masses × radii × azimuths (× hands).

    Attributes
    ----------
    family : Family
        The template family injected (and whose limit it complements).
    hands : list of str
        Hands injected.
    masses : ndarray (n_m,)
        Injected masses [M_th].
    r_p : ndarray (n_r,)
        Injection radii [arcsec] (scan grid points).
    phi_p : ndarray (n_az,)
        Injection azimuths [rad] (scan grid points).
    detected, recovered : ndarray of bool (n_hands, n_m, n_r, n_az)
        The verdict's detection, and detection at the planted place with the planted hand.
    delta_bic : ndarray (n_hands, n_m, n_r, n_az)
        Best ΔBIC of each injected dataset.
    criteria : dict
        Detection thresholds, amplitude mode and position tolerance used.
    distance : float or None
        [pc].
    provenance : dict
        Including ``method`` ("fast" or "brute_force") and the wall time.
    """

    family: Family
    hands: list
    masses: np.ndarray
    r_p: np.ndarray
    phi_p: np.ndarray
    detected: np.ndarray
    recovered: np.ndarray
    delta_bic: np.ndarray
    criteria: dict = field(default_factory=dict)
    distance: float | None = None
    provenance: dict = field(default_factory=dict)

    KIND = COMPLETENESS_KIND
    WHAT = "completeness file"

    @property
    def n_trials(self) -> int:
        """Injections per (mass, radius) cell."""
        return int(self.recovered.shape[0] * self.recovered.shape[3])

    @property
    def probability(self) -> np.ndarray:
        """``P(recovered | M_p, r_p)``, shape (n_m, n_r)."""
        return self.recovered.mean(axis=(0, 3))

    @property
    def probability_error(self) -> np.ndarray:
        """Binomial standard error of :attr:`probability` (at least ``1 / (2 n)`` to avoid 0)."""
        p, n = self.probability, self.n_trials
        return np.maximum(np.sqrt(p * (1 - p) / n), 0.5 / n)

    def m_det(self, level: float = 0.5) -> np.ndarray:
        """Minimum detectable mass [M_th] at completeness ``level`` for each radius (NaN: none)."""
        if not 0 < level < 1:
            raise InputError(f"completeness level must lie in (0, 1), got {level!r}")
        p = self.probability
        out = np.full(self.r_p.size, np.nan)
        for i in range(self.r_p.size):
            below = np.flatnonzero(p[:, i] < level)
            if below.size == 0:
                out[i] = self.masses[0]
            elif below[-1] < self.masses.size - 1:
                k = below[-1]
                t = (level - p[k, i]) / (p[k + 1, i] - p[k, i])
                out[i] = float(np.exp(np.log(self.masses[k]) + t * np.log(self.masses[k + 1] / self.masses[k])))
        return out

    def summary(self, level: float = 0.5) -> str:
        """Completeness over the grid and the minimum detectable mass at ``level``, in words."""
        m_det = self.m_det(level)
        ok = np.isfinite(m_det)
        where = (f"M_det({100 * level:g} %) from {np.nanmin(m_det):.3g} to {np.nanmax(m_det):.3g} M_th at "
                 f"{int(ok.sum())} of {self.r_p.size} radii" if ok.any() else
                 f"no bank mass reaches {100 * level:g} % completeness at any radius")
        return (f"Injection-recovery of the family {self.family.label} ({', '.join(self.hands)}-handed): "
                f"{self.masses.size} masses x {self.r_p.size} radii x {self.n_trials} trials per cell; mean "
                f"completeness {100 * float(self.probability.mean()):.1f} %; {where}.")

    def __repr__(self) -> str:
        return (f"CompletenessResult({self.family.label}, hands {self.hands}, {self.masses.size} masses x "
                f"{self.r_p.size} r_p x {self.phi_p.size} phi_p, mean P = {float(self.probability.mean()):.3g})")


def _read_format_1(f) -> CompletenessResult:
    """Completeness written before the dataclass layout (``format_version`` 1)."""
    meta = json.loads(f.attrs["meta"])
    arrays = {n: f[n][()] for n in ("masses", "r_p", "phi_p", "detected", "recovered", "delta_bic")}
    return CompletenessResult(Family.from_dict(meta["family"]), meta["hands"], arrays["masses"], arrays["r_p"],
                              arrays["phi_p"], arrays["detected"].astype(bool), arrays["recovered"].astype(bool),
                              arrays["delta_bic"], meta["criteria"], meta["distance"], meta["provenance"])


CompletenessResult.LEGACY_READERS = {1: _read_format_1}


# --------------------------------------------------------------------------------------------
def injection_plan(scan_result, family=None, *, masses=None, radii=None,
                   n_azimuths: int = CompletenessSettings.n_azimuths, hands=CompletenessSettings.hands) -> dict:
    """The injection grid on the scan's grid: family, hands, masses, radius and azimuth indices.

    Raises
    ------
    InputError
        An empty family, masses not in it, radii not on the scan's r_p grid, or a bad count.
    """
    fam = select_family(template_families(scan_result.templates), family)
    hands = [h for h in ([hands] if isinstance(hands, str) else list(hands))]
    missing = [h for h in hands if h not in fam.members]
    if not hands or missing:
        raise InputError(f"the family {fam.label} has no {missing or hands} templates to inject (hands {fam.hands})")
    masses = list(fam.masses) if masses is None else [float(m) for m in masses]
    for m in masses:
        if any(fam.index(m, h) is None for h in hands):
            raise InputError(f"mass {m} M_th is not in the family {fam.label} (masses {fam.masses})")
    r_grid = np.asarray(scan_result.r_p, dtype=float)
    if radii is None:
        i_r = np.arange(r_grid.size)
    else:
        radii = np.atleast_1d(np.asarray(radii, dtype=float))
        i_r = np.array([int(np.argmin(np.abs(r_grid - r))) for r in radii])
        off = np.abs(r_grid[i_r] - radii) > 1e-6 * max(float(r_grid.max()), 1e-12)
        if np.any(off):
            raise InputError(f"injection radii {radii[off].tolist()} arcsec are not on the scan's r_p grid "
                             f"({r_grid.min():.4g}-{r_grid.max():.4g} arcsec, {r_grid.size} points): inject at "
                             "scanned radii")
    n_phi = len(scan_result.phi_p)
    if not 1 <= int(n_azimuths) <= n_phi:
        raise InputError(f"n_azimuths must be between 1 and the scan's {n_phi} azimuths, got {n_azimuths}")
    i_phi = np.unique(np.round(np.arange(int(n_azimuths)) * n_phi / int(n_azimuths)).astype(int) % n_phi)
    return {"family": fam, "hands": hands, "masses": np.array(sorted(masses)), "i_r": i_r, "i_phi": i_phi}


def _injection(templates, scan_result, index: int, i_r: int, i_phi: int) -> Injection:
    """Template ``index`` planted at a scanned position, scaled by its limits' margin (a learned
    template's planet may give only that fraction of its signal, as the limits assume)."""
    return Injection(templates[index], float(scan_result.r_p[i_r]), float(scan_result.phi_p[i_phi]),
                     amplitude=limit_margin(scan_result.templates[index]))


def _recovered(verdict, best, best_meta, meta_inj, i_r, phi, criteria) -> bool:
    if not verdict.detected:
        return False
    if best_meta.get("hand") != meta_inj.get("hand"):
        return False
    dphi = np.degrees(abs(wrap_angle(best.phi_p - phi)))
    return abs(best.i_rp - i_r) <= criteria["max_rp_steps"] and dphi <= criteria["max_phi_deg"]


def _judge(result: ScanResult, meta_inj, i_r, phi, criteria, amplitude, detection: DetectionSettings):
    verdict = detect(result, amplitude, settings=detection)
    best = result.peak(amplitude=amplitude)
    recovered = _recovered(verdict, best, result.templates[best.template_index], meta_inj, i_r, phi, criteria)
    return verdict.detected, recovered, verdict.delta_bic


def _criteria(amplitude, max_rp_steps, max_phi_deg, detection: DetectionSettings) -> dict:
    # the detection thresholds that differ from the paper's are recorded beside the position tolerance
    changed = {f.name: getattr(detection, f.name) for f in fields(DetectionSettings)
               if getattr(detection, f.name) != f.default}
    return {"amplitude": amplitude or "fixed", "max_rp_steps": int(max_rp_steps), "max_phi_deg": float(max_phi_deg),
            **changed}


def _settings(settings, overrides: dict, where: str) -> CompletenessSettings:
    """``settings`` with ``overrides``; overrides naming :class:`DetectionSettings` fields go to its ``detection``."""
    names = {f.name for f in fields(DetectionSettings)}
    detect_kwargs = {k: overrides.pop(k) for k in list(overrides) if k in names}
    s = with_overrides(settings, CompletenessSettings, overrides, where)
    if detect_kwargs:
        s = replace(s, detection=with_overrides(s.detection, DetectionSettings, detect_kwargs, where))
    return s


def _check_scan(templates, scan_result) -> None:
    names = [getattr(t, "name", None) for t in templates]
    if names != [t["name"] for t in scan_result.templates]:
        raise InputError("the templates given are not the scan's (names and order must match scan_result.templates)")
    if not np.all(scan_result.completed):
        raise InputError("the scan is incomplete (NaN rows): finish it before injecting")


def _cells(plan):
    for h, hand in enumerate(plan["hands"]):
        for k, mass in enumerate(plan["masses"]):
            for ri, i_r in enumerate(plan["i_r"]):
                for pj, i_phi in enumerate(plan["i_phi"]):
                    yield (h, k, ri, pj), hand, mass, int(i_r), int(i_phi)


def injection_engine(vis, axisymmetric, templates, scan_result, *, geometry=None, keep=(), nthreads: int = 1,
                     progress: bool = False) -> InjectionEngine:
    """The :class:`InjectionEngine` of a scan (checks that the data and model are the scan's)."""
    _check_scan(templates, scan_result)
    geometry = geometry or scan_result.geometry
    context = ScanContext.build(vis, axisymmetric, geometry, scan_result.r_p, len(scan_result.phi_p),
                                scan_result.provenance.get("cell_factor", 20.0), nthreads=nthreads)
    if not np.isclose(context.chi2_AO, scan_result.chi2_AO, rtol=1e-9, atol=1e-6):
        raise InputError("the data or the axisymmetric model differ from the scan's (chi2_AO "
                         f"{context.chi2_AO:.6g} vs {scan_result.chi2_AO:.6g}): pass the scan's own inputs")
    return InjectionEngine(context, templates, keep=keep, progress=progress)


def completeness(vis, axisymmetric, templates, scan_result, *, settings: CompletenessSettings | None = None,
                 family=None, masses=None, radii=None, geometry=None, amplitude=None, progress: bool = True,
                 engine: InjectionEngine | None = None, **overrides) -> CompletenessResult:
    """Injection–recovery completeness of a scan, by the fast cross-term path.

    Parameters
    ----------
    vis, axisymmetric, templates, scan_result
        The data, the axisymmetric model and the templates the scan was run with (same order),
        and its :class:`ScanResult`.
    settings : CompletenessSettings, optional
        Azimuths per radius (``n_azimuths``) and hands injected, the position tolerance of a recovery
        (``max_rp_steps`` radius steps, ``max_phi_deg`` [deg]), the batch size and threads, and the
        verdict's thresholds (``detection``, a :class:`DetectionSettings`); default
        ``CompletenessSettings()``.
    family : dict, str, int or Family, optional
        The template family to inject (default: the scan's only family).
    masses, radii : sequence, optional
        Injected masses [M_th] (family members) and radii [arcsec] (scan grid points); default all.
    geometry : DiscGeometry, optional
        Geometry of the injections (default: the scan's).
    amplitude : None or 'free'
        Amplitude mode of the detection (as :func:`.detect`).
    progress : bool
        Progress bars.
    engine : InjectionEngine, optional
        One built for this scan (see :func:`.injection_engine`), to share it between families.
    **overrides
        Fields of :class:`CompletenessSettings` (e.g. ``n_azimuths=4``) or of its ``detection``
        (e.g. ``bic_threshold_value=15``) replacing those of ``settings``.

    Returns
    -------
    CompletenessResult
        The detected fraction at every (mass [M_th], r_p [arcsec]) and the minimum detectable mass
        ``M_det(r_p)`` [M_th].
    """
    s = _settings(settings, overrides, "completeness")
    n_azimuths, hands, chunk, nthreads = s.n_azimuths, s.hands, s.chunk, s.nthreads
    t0 = time.perf_counter()
    _check_scan(templates, scan_result)
    plan = injection_plan(scan_result, family, masses=masses, radii=radii, n_azimuths=n_azimuths, hands=hands)
    fam = plan["family"]
    if engine is None:
        inj_templates = [templates[fam.index(m, h)] for h in plan["hands"] for m in plan["masses"]]
        engine = injection_engine(vis, axisymmetric, templates, scan_result, geometry=geometry, keep=inj_templates,
                                  nthreads=nthreads, progress=progress)
    t_engine = time.perf_counter() - t0
    shape = (len(plan["hands"]), plan["masses"].size, plan["i_r"].size, plan["i_phi"].size)
    detected, recovered = np.zeros(shape, bool), np.zeros(shape, bool)
    delta_bic = np.zeros(shape)
    criteria = _criteria(amplitude, s.max_rp_steps, s.max_phi_deg, s.detection)
    cells = list(_cells(plan))
    from tqdm.auto import tqdm

    with tqdm(total=len(cells), desc="injections", unit="injection", disable=not progress) as bar:
        for start in range(0, len(cells), chunk):
            part = cells[start:start + chunk]
            injections = [_injection(templates, scan_result, fam.index(mass, hand), i_r, i_phi)
                          for _, hand, mass, i_r, i_phi in part]
            extra = engine.cross(injections, chunk=chunk)
            for (where, hand, mass, i_r, i_phi), x in zip(part, extra):
                injected = ScanResult(scan_result.templates, scan_result.r_p, scan_result.phi_p,
                                      scan_result.cross + x, scan_result.power, scan_result.chi2_AO,
                                      scan_result.n_data, scan_result.geometry, scan_result.distance)
                meta = scan_result.templates[fam.index(mass, hand)]
                detected[where], recovered[where], delta_bic[where] = _judge(
                    injected, meta, i_r, scan_result.phi_p[i_phi], criteria, amplitude, s.detection)
            bar.update(len(part))
    wall = time.perf_counter() - t0
    prov = provenance_record(method="fast", wall_time_s=wall, engine_time_s=t_engine, n_injections=len(cells),
                             scan=scan_result.provenance.get("data_hash"))
    return CompletenessResult(fam, plan["hands"], plan["masses"], scan_result.r_p[plan["i_r"]],
                              scan_result.phi_p[plan["i_phi"]], detected, recovered, delta_bic, criteria,
                              scan_result.distance, prov)


def completeness_brute_force(vis, axisymmetric, templates, scan_result, *, settings: CompletenessSettings | None = None,
                             family=None, masses=None, radii=None, geometry=None, amplitude=None, refit=None,
                             progress: bool = False, **overrides) -> CompletenessResult:
    """The reference: plant each planet into the visibilities and scan the new dataset from scratch.

    The arguments are :func:`completeness`'s; ``refit``: optional ``callable(vis) -> axisymmetric
    model`` run on every injected dataset (e.g. a frank refit); by default the scan's axisymmetric
    model is kept, as in the fast path.
    """
    s = _settings(settings, overrides, "completeness_brute_force")
    n_azimuths, hands, nthreads = s.n_azimuths, s.hands, s.nthreads
    t0 = time.perf_counter()
    _check_scan(templates, scan_result)
    plan = injection_plan(scan_result, family, masses=masses, radii=radii, n_azimuths=n_azimuths, hands=hands)
    geometry = geometry or scan_result.geometry
    fam = plan["family"]
    shape = (len(plan["hands"]), plan["masses"].size, plan["i_r"].size, plan["i_phi"].size)
    detected, recovered = np.zeros(shape, bool), np.zeros(shape, bool)
    delta_bic = np.zeros(shape)
    criteria = _criteria(amplitude, s.max_rp_steps, s.max_phi_deg, s.detection)
    cells = list(_cells(plan))
    for where, hand, mass, i_r, i_phi in cells:
        injection = _injection(templates, scan_result, fam.index(mass, hand), i_r, i_phi)
        result = brute_force_injection(vis, axisymmetric, templates, injection, geometry, refit=refit,
                                       r_p=scan_result.r_p, n_phi_p=len(scan_result.phi_p),
                                       distance=scan_result.distance, progress=progress, nthreads=nthreads,
                                       cell_factor=scan_result.provenance.get("cell_factor", 20.0))
        meta = scan_result.templates[fam.index(mass, hand)]
        detected[where], recovered[where], delta_bic[where] = _judge(
            result, meta, i_r, scan_result.phi_p[i_phi], criteria, amplitude, s.detection)
    prov = provenance_record(method="brute_force", refit=refit is not None, wall_time_s=time.perf_counter() - t0,
                             n_injections=len(cells))
    return CompletenessResult(fam, plan["hands"], plan["masses"], scan_result.r_p[plan["i_r"]],
                              scan_result.phi_p[plan["i_phi"]], detected, recovered, delta_bic, criteria,
                              scan_result.distance, prov)
