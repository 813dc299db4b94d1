"""Exclusion limits from a scan: which planets the data rule out, and the limiting mass M_lim(r_p).

Stevenson et al. (2024, sec. 4.3, Table 3, Fig. 14) read exclusion regions off Δχ² heatmaps by
eye; here they follow from the scan's two terms (``docs/limits.md`` has the derivations).

**Amplitude test.** Give the template at ``(r_p, phi_p)`` a free linear amplitude ``A`` (the
scan's model is ``A = 1``): ``Δχ²(A) = 2 A cross - A² power``, so ``A_hat = cross / power`` with
error ``sigma_A = 1 / sqrt(power)`` (Gaussian noise: ``cross = power (A_true + noise)``). The
one-sided upper limit at confidence ``CL`` is ``A_up = A_hat + z_CL sigma_A``
(``z_CL = Phi^-1(CL)``, 1.645 at 95 %); the planet is **excluded** there when ``A_up < 1``. For
a planet planted exactly as the template, ``P(excluded) = 1 - CL``. A template's ``limit_margin`` m
(metadata; the learned bank's) makes it stand for m times itself: its ``A_up`` is divided by m.

**Azimuths.** (a) ``excluded_fraction``: the fraction of the scanned ``phi_p`` where a template
is excluded. (b) A planet is excluded at ``r_p`` (``method="all_phi"``, the paper's conservative
reading) when it is excluded at every ``phi_p``: ``A_up(r_p) = max_phi A_up < 1``. With
``method="marginal"`` ``phi_p`` is marginalised with a uniform prior: the posterior of ``A``
(flat prior) is the mixture ``sum_phi w_phi N(A_hat_phi, sigma_phi²)`` with
``w_phi ∝ sigma_phi exp(A_hat_phi² / 2 sigma_phi²)``, and ``A_up`` solves
``P(A > A_up | data) = 1 - CL``. Both hands must be excluded (the hand is not known), unless
``hand="R"`` or ``"L"`` says which one the disc's rotation allows.

**Limiting mass.** Per template family (fixed tau0, beta, h_p): ``M_lim(r_p)`` is the smallest
mass above which every bank mass is excluded. Between the last allowed bank mass ``m_k``
(``A_up >= 1``) and the next, excluded one, ``ln A_up`` is interpolated linearly in ``ln M`` to
``ln A_up = 0`` (for a noise-dominated limit ``A_up ∝ 1 / amplitude(M)``, a power of M). When
every bank mass is excluded ``M_lim`` is the smallest one (status ``"below_bank"``: lighter
planets are not tested); when the heaviest is allowed there is no limit (``"none"``). Masses
above the bank's largest are not tested either. In Jupiter masses, ``M = M_lim M_th(r_p)`` with
``M_th = h(r_p)^3 M_*`` and ``h = h_ref (r / r_ref)^flaring`` (:func:`spiralbayes.units.mth_to_mjup`).

**Flags.** Radii where the template is not constrained by the data's information are flagged,
not excluded: ``"unresolved"`` when ``r_p < resolution_factor x resolution`` (the spiral and
the planet lie within about one beam of the star: the scan cannot tell a spiral from an
axisymmetric or compact residual, the paper's small-r_p caveat), and ``"beyond_bright_extent"``
when ``r_p`` exceeds the radius holding ``extent_fraction`` (95 %) of the disc's flux (half of
the template, the outer arm, would lie where ``I_A ≈ 0`` and the model ``I_A (1 + delta)`` says
nothing about a planet there: the large-r_p caveat). Given the detection verdict (``planets``),
``"near_planet"`` within one beam of a detected or candidate planet, and ``"near_asymmetry"``
within one beam of the annulus ``r_c ± 2 σ_r`` of every competing asymmetry model (test 3's arc,
lopsided ring, m = 2, eccentric ring) with ΔBIC > 10 against the axisymmetric disc: the limits
assume that the residual holds noise and perhaps a spiral, and a disc with unmodelled asymmetric
emission there (a vortex-dominated gap edge, say) breaks that — no template stands for it
(docs/limits.md §4d).
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass, field

import numpy as np

from ..._provenance import provenance_record
from ...exceptions import InputError
from ...results import ResultMixin
from ...settings import with_overrides
from ...templates.template import limit_margin
from ...units import mth_to_mjup
from . import guards
from .families import Family, select_family, template_families
from .settings import LIMIT_METHODS, LimitSettings
from .table3 import describe_family_limits, runs

__all__ = ["ExclusionLimits", "amplitude_upper_limit", "compute_limits", "data_resolution", "bright_extent", "z_score"]

LIMITS_KIND = "spiralbayes.ExclusionLimits"
FLAG_UNRESOLVED = "unresolved"
FLAG_EXTENT = "beyond_bright_extent"
FLAG_NEAR_PLANET, FLAG_NEAR_ASYMMETRY = guards.FLAG_NEAR_PLANET, guards.FLAG_NEAR_ASYMMETRY
METHODS = LIMIT_METHODS

log = logging.getLogger(__name__)


def z_score(cl: float) -> float:
    """One-sided ``z_CL = Phi^-1(CL)``; ``cl`` must lie in (0.5, 1)."""
    from scipy.stats import norm

    try:
        cl = float(cl)
    except (TypeError, ValueError):
        raise InputError(f"cl must be a confidence level in (0.5, 1), e.g. 0.95, got {cl!r}") from None
    if not 0.5 < cl < 1.0:
        raise InputError(f"cl = {cl!r} is not a confidence level in (0.5, 1): use e.g. 0.95 (one-sided 95 %)")
    return float(norm.ppf(cl))


def _amplitude(cross, power):
    cross = np.asarray(cross, dtype=float)
    power = np.asarray(power, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        a_hat = np.where(power > 0, cross / np.where(power > 0, power, 1.0), 0.0)
        sigma = np.where(power > 0, 1.0 / np.sqrt(np.where(power > 0, power, 1.0)), np.inf)
    return a_hat, sigma


def amplitude_upper_limit(cross, power, cl: float = 0.95, method: str = "instance") -> np.ndarray:
    """Upper limit on the template amplitude ``A`` at confidence ``cl``.

    ``method="instance"``: per instance, ``A_hat + z sigma_A`` (same shape as the inputs).
    ``"all_phi"``: the largest over the last axis (phi_p). ``"marginal"``: phi_p marginalised
    over the last axis (see the module docstring).
    """
    z = z_score(cl)
    a_hat, sigma = _amplitude(cross, power)
    if method == "instance":
        return a_hat + z * sigma
    if method == "all_phi":
        return np.max(a_hat + z * sigma, axis=-1)
    if method == "marginal":
        return _marginal_upper_limit(a_hat, sigma, 1.0 - float(cl))
    raise InputError(f"method must be 'instance', 'all_phi' or 'marginal', got {method!r}")


def _marginal_upper_limit(a_hat, sigma, tail: float, iterations: int = 80) -> np.ndarray:
    """``A_up`` with ``sum_phi w_phi Q((A_up - a_hat_phi) / sigma_phi) = tail`` (vectorised bisection)."""
    from scipy.special import logsumexp
    from scipy.stats import norm

    finite = np.isfinite(sigma)
    s = np.where(finite, sigma, 1.0)
    log_w = np.where(finite, np.log(s) + 0.5 * (a_hat / s) ** 2, -np.inf)
    log_w = log_w - logsumexp(log_w, axis=-1, keepdims=True)
    w = np.exp(log_w)
    lo = np.min(np.where(finite, a_hat - 12 * s, np.inf), axis=-1)
    hi = np.max(np.where(finite, a_hat + 12 * s, -np.inf), axis=-1)
    none = ~np.isfinite(lo)  # no power at any azimuth: nothing is constrained
    lo, hi = np.where(none, 0.0, lo), np.where(none, 1.0, hi)
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        tail_mid = np.sum(w * norm.sf((mid[..., None] - a_hat) / s), axis=-1)
        above = tail_mid > tail
        lo, hi = np.where(above, mid, lo), np.where(above, hi, mid)
    return np.where(none, np.inf, 0.5 * (lo + hi))


def data_resolution(vis) -> float:
    """FWHM [arcsec] of the natural-weighted beam, ``sqrt(bmaj bmin)`` (:func:`spiralbayes.simulate.noise.fit_beam`)."""
    from ...simulate.noise import fit_beam

    bmaj, bmin, _ = fit_beam(vis.u, vis.v, vis.weights)
    return float(np.sqrt(bmaj * bmin))


def bright_extent(axisymmetric, fraction: float = 0.95) -> float:
    """Radius [arcsec] holding ``fraction`` of the axisymmetric model's face-on flux."""
    return float(axisymmetric.R_eff(fraction))


@dataclass(repr=False)
class ExclusionLimits(ResultMixin):
    """Exclusion limits of one scan (see the module docstring for the definitions).

    Attributes
    ----------
    templates : list of dict
        The scan's template metadata.
    r_p, phi_p : ndarray
        Planet radii [arcsec] and azimuths [rad] of the scan.
    cl : float
        Confidence level (one-sided).
    method : {'all_phi', 'marginal'}
    hand : {'both', 'R', 'L'}
        Hands that must be excluded.
    upper_limit : ndarray (n_templates, n_rp)
        ``A_up`` of each template at each radius (over phi_p by ``method``).
    excluded_fraction : ndarray (n_templates, n_rp)
        Fraction of the azimuths where the template is excluded.
    flags : ndarray of str (n_rp,)
        ``""``, ``"unresolved"`` or ``"beyond_bright_extent"``.
    families : list of Family
    m_lim : ndarray (n_families, n_rp)
        Limiting mass [M_th]; NaN where there is none or the radius is flagged.
    m_lim_status : ndarray of str (n_families, n_rp)
        ``"limit"``, ``"below_bank"``, ``"none"`` or ``"flagged"``.
    distance : float or None
        [pc], for au and M_Jup.
    disc : dict
        ``mstar`` [M_sun], ``h_ref``, ``r_ref`` [au], ``flaring``: the thermal-mass conversion.
    resolution, bright_radius, resolution_factor : float
        The flag criteria used [arcsec].
    provenance : dict
    """

    templates: list
    r_p: np.ndarray
    phi_p: np.ndarray
    cl: float
    method: str
    hand: str
    upper_limit: np.ndarray
    excluded_fraction: np.ndarray
    flags: np.ndarray
    families: list
    m_lim: np.ndarray
    m_lim_status: np.ndarray
    distance: float | None = None
    disc: dict = field(default_factory=dict)
    resolution: float = 0.0
    bright_radius: float = np.inf
    resolution_factor: float = 1.0
    provenance: dict = field(default_factory=dict)

    KIND = LIMITS_KIND
    WHAT = "exclusion-limits file"

    # -- queries ---------------------------------------------------------------------------------
    def family(self, family=None) -> Family:
        return select_family(self.families, family)

    def family_index(self, family=None) -> int:
        return self.families.index(self.family(family))

    def excluded(self, family=None, mass: float | None = None) -> np.ndarray:
        """Whether planets of ``mass`` [M_th] (default: every bank mass) are excluded at each r_p.

        Shape (n_rp,) for one mass, else (n_masses, n_rp). Without ``family`` on a scan of several
        families: excluded only where every family that has the mass excludes it
        (:func:`~spiralbayes.inference.limits.robust.combined_excluded`; masses are then those of the union).
        """
        if family is None and len(self.families) > 1:
            from .robust import combined_excluded

            return combined_excluded(self, mass)
        fam = self.family(family)
        masses = fam.masses if mass is None else [mass]
        rows = []
        for m in masses:
            found = [fam.index(m, h) for h in self._hands(fam)]
            idx = [i for i in found if i is not None]
            if len(idx) < len(found):
                raise InputError(f"mass {m} is not in the family {fam.label} (masses {fam.masses}) for every hand")
            rows.append(np.all(self.upper_limit[idx] < 1.0, axis=0) & (self.flags == ""))
        out = np.array(rows)
        return out[0] if mass is not None else out

    def _hands(self, fam: Family) -> list:
        return fam.hands if self.hand == "both" else [self.hand]

    def m_lim_mjup(self, family=None) -> np.ndarray:
        """``M_lim(r_p)`` [M_Jup] of a family, with that family's own ``h_p`` (needs a distance)."""
        fam = self.family(family)
        return self.to_mjup(self.m_lim[self.families.index(fam)], family=fam)

    def h_ref(self, family=None) -> float:
        """``H/r`` at ``r_ref`` used for M_th of ``family``: the ``h_ref`` given to
        :func:`compute_limits`, else the family's own ``h_p``, else 0.07."""
        if self.disc.get("h_ref") is not None and not self.disc.get("h_ref_from_family", False):
            return float(self.disc["h_ref"])
        fams = self.families if family is None else [family if isinstance(family, Family) else self.family(family)]
        h_ps = {f.key["h_p"] for f in fams if f.key.get("h_p") is not None}
        if len(h_ps) > 1:
            raise InputError(f"the families have several h_p ({sorted(h_ps)}): give family= for Jupiter masses")
        return float(h_ps.pop()) if h_ps else 0.07

    def to_mjup(self, mass_mth, r_p=None, family=None) -> np.ndarray:
        """Convert masses [M_th] at the scan's radii (or ``r_p`` [arcsec]) to M_Jup, with
        ``M_th = h³ M_*`` and ``h`` from ``family``'s ``h_p`` (see :meth:`h_ref`)."""
        if self.distance is None:
            raise InputError("Jupiter masses need the distance: give distance= to the scan or to compute_limits")
        h_ref = self.h_ref(family)
        r_p = self.r_p if r_p is None else np.asarray(r_p, dtype=float)
        mass = np.asarray(mass_mth, dtype=float)
        out = np.full(np.broadcast(mass, r_p).shape, np.nan)
        ok = np.isfinite(mass) & np.broadcast_to(np.isfinite(r_p), out.shape)
        if ok.any():
            full_m, full_r = np.broadcast_to(mass, out.shape), np.broadcast_to(r_p, out.shape)
            out[ok] = mth_to_mjup(full_m[ok], full_r[ok], self.disc["mstar"], h_ref=h_ref,
                                  r_ref=self.disc["r_ref"], flaring=self.disc["flaring"], distance=self.distance)
        return out

    def excluded_ranges(self, family=None, mass: float = 3.0) -> list[tuple[float, float]]:
        """Contiguous r_p ranges [arcsec] (grid points) where planets of ``mass`` [M_th] and above are
        excluded (without ``family`` on several families: by every family, :mod:`.robust`)."""
        m_lim, status = self.robust_m_lim(family)
        ok = (status == "limit") | (status == "below_bank")
        ok &= np.nan_to_num(m_lim, nan=np.inf) <= mass * (1 + 1e-9)
        return runs(self.r_p, ok)

    def robust_m_lim(self, family=None) -> tuple[np.ndarray, np.ndarray]:
        """``(M_lim, status)`` of ``family``; without one on several families, the limit that holds
        for every family (the largest, :func:`~spiralbayes.inference.limits.robust.combined_m_lim`)."""
        if family is None and len(self.families) > 1:
            from .robust import combined_m_lim

            return combined_m_lim(self)
        fi = self.family_index(family)
        return self.m_lim[fi], self.m_lim_status[fi]

    # -- the morphologies assumed (:mod:`.robust`) --------------------------------------------------
    @property
    def morphologies(self) -> list[str]:
        """Names of the spiral morphologies the limits assume (e.g. ``["compromise", "hydro",
        "wakeflow"]`` for the default bank, ``["compromise"]`` for the compromise bank)."""
        from .robust import morphologies

        return morphologies(self)

    def price_of_robustness(self, family=None) -> np.ndarray:
        """``M_lim(robust) / M_lim(compromise)`` per r_p, over every family or over the morphology
        variants of ``family``'s group; NaN where either has no limit, 1 for a single morphology."""
        from .robust import overall_price

        return overall_price(self, family)

    def price_of_robustness_median(self, family=None) -> float:
        """Median of :meth:`price_of_robustness` over the radii where it is defined (NaN if none)."""
        price = self.price_of_robustness(family)
        return float(np.median(price[np.isfinite(price)])) if np.isfinite(price).any() else float("nan")

    def morphology_note(self, family=None) -> str:
        """The sentence naming the morphologies assumed and the price of robustness (or that the
        limits assume one morphology and are not robust to the spiral's shape)."""
        from .robust import morphology_note

        return morphology_note(self, family)

    def summary(self, family=None) -> str:
        """A sentence per mass threshold (the paper's Table 3 wording) and the morphologies assumed;
        without ``family`` on a scan of several families, the limits that hold for every family, the
        set named (:func:`~spiralbayes.inference.limits.robust.describe_over_families`)."""
        if family is None and len(self.families) > 1:
            from .robust import describe_over_families

            return describe_over_families(self)
        return f"{describe_family_limits(self, family)} {self.morphology_note(family)}"

    def __repr__(self) -> str:
        flagged = int(np.count_nonzero(self.flags != ""))
        return (f"ExclusionLimits({len(self.templates)} templates in {len(self.families)} families, {self.r_p.size} "
                f"r_p ({flagged} flagged), CL = {self.cl:g}, method = {self.method!r}, hand = {self.hand!r})")


def _read_format_1(f) -> ExclusionLimits:
    """Limits written before the dataclass layout (``format_version`` 1)."""
    meta = json.loads(f.attrs["meta"])
    arrays = {n: f[n][()] for n in ("r_p", "phi_p", "upper_limit", "excluded_fraction", "m_lim")}
    flags = np.array([s.decode() for s in f["flags"][()]])
    status = np.array([[s.decode() for s in row] for row in f["m_lim_status"][()]]).reshape(arrays["m_lim"].shape)
    bright = meta["bright_radius"]
    return ExclusionLimits(meta["templates"], arrays["r_p"], arrays["phi_p"], meta["cl"], meta["method"], meta["hand"],
                           arrays["upper_limit"], arrays["excluded_fraction"], flags,
                           [Family.from_dict(d) for d in meta["families"]], arrays["m_lim"], status, meta["distance"],
                           meta["disc"], meta["resolution"], np.inf if bright is None else bright,
                           meta["resolution_factor"], meta["provenance"])


ExclusionLimits.LEGACY_READERS = {1: _read_format_1}


def _flags(r_p, resolution: float, resolution_factor: float, bright_radius: float) -> np.ndarray:
    flags = np.full(r_p.size, "", dtype=object)
    flags[r_p < resolution_factor * resolution] = FLAG_UNRESOLVED
    flags[r_p > bright_radius] = FLAG_EXTENT
    return flags.astype(str)


def _limiting_mass(masses, upper) -> tuple[np.ndarray, np.ndarray]:
    """``M_lim`` per radius from ``A_up`` of each mass (rows, increasing masses); see the module docstring."""
    masses = np.asarray(masses, dtype=float)
    n_r = upper.shape[1]
    m_lim = np.full(n_r, np.nan)
    status = np.full(n_r, "none", dtype=object)
    excluded = upper < 1.0
    for i in range(n_r):
        allowed = np.flatnonzero(~excluded[:, i])
        if allowed.size == 0:
            m_lim[i], status[i] = masses[0], "below_bank"
            continue
        k = allowed[-1]
        if k == masses.size - 1:
            continue
        m_lim[i] = _crossing(masses[k], masses[k + 1], upper[k, i], upper[k + 1, i])
        status[i] = "limit"
    return m_lim, status.astype(str)


def _crossing(m0, m1, u0, u1) -> float:
    """Mass where ``A_up`` crosses 1, between ``m0`` (``u0 >= 1``) and ``m1`` (``u1 < 1``), in log mass."""
    if u1 > 0 and np.isfinite(u0):
        t = np.log(u0) / (np.log(u0) - np.log(u1))
    elif np.isfinite(u0):  # a negative upper limit: interpolate A_up itself
        t = (u0 - 1.0) / (u0 - u1)
    else:
        t = 1.0
    return float(np.exp(np.log(m0) + np.clip(t, 0.0, 1.0) * (np.log(m1) - np.log(m0))))


def compute_limits(scan_result, *, settings: LimitSettings | None = None, vis=None, axisymmetric=None,
                   distance: float | None = None, planets=None, **overrides) -> ExclusionLimits:
    """Exclusion limits and ``M_lim(r_p)`` of every template family of a scan.

    Parameters
    ----------
    scan_result : ScanResult
    settings : LimitSettings, optional
        The confidence level ``cl`` in (0.5, 1); the ``method`` ('all_phi': excluded at r_p when
        excluded at every phi_p; 'marginal': phi_p marginalised); the ``hand`` ('both', 'R', 'L')
        that must be excluded; the flags: ``resolution`` (beam FWHM [arcsec]; default from
        ``vis``, :func:`.data_resolution`, else 0: no flag), ``resolution_factor`` (radii below
        ``resolution_factor x resolution`` are flagged ``"unresolved"``), ``bright_radius``
        (outer radius of the bright part [arcsec]; default the radius holding
        ``extent_fraction`` of ``axisymmetric``'s flux, else no flag) and ``planet_beam``
        ([arcsec]; default ``resolution``); and the disc for M_Jup: stellar mass ``mstar``
        [M_sun] and ``H/r = h_ref (r / r_ref [au])^flaring`` (``h_ref`` default: each family's
        own ``h_p``, else 0.07). Default ``LimitSettings()``.
    vis : Visibilities, optional
        The scanned data, for the beam.
    axisymmetric : AxisymmetricModel, optional
        The scan's axisymmetric model, for the bright extent.
    distance : float, optional
        [pc]; default the scan's.
    planets : Verdict, dict or sequence of float, optional
        Detected or candidate planets not in the scan's model: a :func:`.detect` verdict or its
        ``to_dict()`` (its peak when test 1 passes, and its candidate) or radii [arcsec]. Radii
        within ``planet_beam`` of one are flagged ``"near_planet"``, not excluded (:mod:`.robust`).
        Leave it out when the planet is in the model (scan the residual of a fit that includes it).
        A verdict with test 3's alternatives also flags ``"near_asymmetry"`` the radii within
        ``planet_beam`` of each significant asymmetry model's annulus (:mod:`.guards`).
    **overrides
        Fields of :class:`LimitSettings` replacing those of ``settings`` (e.g. ``cl=0.99``).

    Returns
    -------
    ExclusionLimits
        ``M_lim(r_p)`` [M_th] of every template family (and the robust limit over morphologies), the
        upper limits on the amplitude per instance, and the flags of radii the data cannot judge.

    Raises
    ------
    InputError
        A confidence level outside (0.5, 1), an unknown method or hand, a scan without families,
        or a radius grid lying entirely outside the data (every r_p flagged).

    Examples
    --------
    >>> import spiralbayes as sb
    >>> vis = sb.simulate_observation("taurus", seed=1)  # the Taurus survey's set-up, no planet
    >>> disc = sb.fit_axisymmetric(vis, sb.DiscGeometry(inc=30, PA=60), progress=False, N=100)
    >>> templates = [sb.make_template(mass=3.0, tau0=3.0, beta=10.0, hand=h, wavelength=1.33e-3) for h in "RL"]
    >>> result = sb.scan(vis, disc, templates, r_p=[0.2, 0.3, 0.4], distance=140.0, progress=False)
    >>> limits = sb.compute_limits(result, vis=vis, axisymmetric=disc, distance=140.0)
    >>> limits.excluded_ranges(mass=3.0)  # r_p [arcsec] where planets of >= 3 M_th are ruled out
    [(0.3, 0.4)]
    >>> print(limits.summary())  # doctest: +ELLIPSIS
    Planets of >= 3 M_th ... are ruled out at 95% confidence at 42-56 au (0.76-0.94 M_Jup)...
    """
    s = with_overrides(settings, LimitSettings, overrides, "compute_limits")
    cl, method, hand, resolution, resolution_factor = s.cl, s.method, s.hand, s.resolution, s.resolution_factor
    bright_radius, extent_fraction, planet_beam = s.bright_radius, s.extent_fraction, s.planet_beam
    mstar, h_ref, r_ref, flaring = s.mstar, s.h_ref, s.r_ref, s.flaring
    z_score(cl)
    if method not in METHODS:
        raise InputError(f"method must be one of {METHODS}, got {method!r}")
    if hand not in ("both", "R", "L"):
        raise InputError(f"hand must be 'both', 'R' or 'L', got {hand!r}")
    if not np.all(scan_result.completed):
        raise InputError("the scan is incomplete (NaN rows): finish it (run the scan again to resume) first")
    families = template_families(scan_result.templates)
    if not families:
        select_family(families)  # raises the explanation
    resolution = (data_resolution(vis) if vis is not None else 0.0) if resolution is None else resolution
    bright_radius = ((bright_extent(axisymmetric, extent_fraction) if axisymmetric is not None else np.inf)
                     if bright_radius is None else bright_radius)
    r_p = np.asarray(scan_result.r_p, dtype=float)
    flags = _flags(r_p, resolution, resolution_factor, bright_radius)
    if np.all(flags != ""):
        raise InputError(f"every scanned r_p ({r_p.min():.3g}-{r_p.max():.3g} arcsec) lies outside the data: below "
                         f"{resolution_factor:g} x the resolution ({resolution:.3g} arcsec) or beyond the disc's "
                         f"bright extent ({bright_radius:.3g} arcsec); scan radii between these")
    flags, near, bands = guards.guard_flags(r_p, flags, planets, resolution if planet_beam is None else planet_beam)
    margin = np.array([limit_margin(meta) for meta in scan_result.templates])[:, None]
    upper = amplitude_upper_limit(scan_result.cross, scan_result.power, cl, method) / margin
    per_instance = amplitude_upper_limit(scan_result.cross, scan_result.power, cl, "instance") / margin[..., None]
    fraction = np.mean(per_instance < 1.0, axis=-1)
    m_lim = np.full((len(families), r_p.size), np.nan)
    status = np.full((len(families), r_p.size), "none", dtype=object)
    for fi, fam in enumerate(families):
        hands = fam.hands if hand == "both" else [hand]
        if any(h not in fam.members for h in hands):
            log.warning("family %s has no %s-handed templates: its limit uses hands %s", fam.label,
                        "/".join(h for h in hands if h not in fam.members), fam.hands)
            hands = [h for h in hands if h in fam.members] or fam.hands
        rows = []
        for k in range(len(fam.masses)):
            idx = [fam.members[h][k] for h in hands if fam.members[h][k] is not None]
            rows.append(np.max(upper[idx], axis=0) if idx else np.full(r_p.size, np.inf))
        m_lim[fi], status[fi] = _limiting_mass(fam.masses, np.array(rows))
    status[:, flags != ""] = "flagged"
    m_lim[:, flags != ""] = np.nan
    disc = {"mstar": float(mstar), "h_ref": None if h_ref is None else float(h_ref), "r_ref": float(r_ref),
            "flaring": float(flaring), "h_ref_from_family": h_ref is None}
    distance, data = scan_result.distance if distance is None else distance, scan_result.provenance.get("data_hash")
    prov = provenance_record(scan=data, method=method, cl=cl, hand=hand, near_planets=near, near_asymmetries=bands,
                             candidate_source=guards.candidate_source(planets))
    return ExclusionLimits(list(scan_result.templates), r_p, np.asarray(scan_result.phi_p), float(cl), method, hand,
                           upper, fraction, flags, families, m_lim, status.astype(str), distance, disc,
                           float(resolution), float(bright_radius), float(resolution_factor), prov)
