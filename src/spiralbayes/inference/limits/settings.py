"""How the limits are computed: :class:`LimitSettings` (the ``[limits]`` section of the configuration) and
:class:`CompletenessSettings` (injection-recovery, :func:`~spiralbayes.inference.limits.completeness`)."""

from __future__ import annotations

from dataclasses import dataclass

from ...exceptions import InputError
from ...settings import DEFAULT_MSTAR_MSUN, documented, is_finite_number, is_integer, option
from ..detection.settings import DetectionSettings

__all__ = ["CompletenessSettings", "ForecastSettings", "HANDS", "LIMIT_METHODS", "LimitSettings", "TABLE3_THRESHOLDS"]

TABLE3_THRESHOLDS = (3.0, 1.0)
"""Planet masses [M_th] of the columns of Stevenson et al. (2024) Table 3: radii where planets of at least
3 and at least 1 thermal mass are ruled out."""
LIMIT_METHODS = ("all_phi", "marginal")
"""How the limit at one r_p treats phi_p: excluded at every phi_p, or phi_p marginalised."""
HANDS = ("R", "L")
"""Spiral hands: right-handed (the paper's) and its mirror image."""


def _check_hands(name: str, hands) -> None:
    if isinstance(hands, str) or not hands or any(h not in HANDS for h in hands):
        raise InputError(f"{name} = {hands!r} must be a non-empty list of 'R' and/or 'L'")


@documented
@dataclass(frozen=True)
class CompletenessSettings:
    """Options of :func:`~spiralbayes.inference.limits.completeness` (injection-recovery by the fast path).

    ``[limits] n_azimuths`` and ``inject_hand`` set the first two. Every field's description is its
    ``metadata["doc"]``.
    """

    n_azimuths: int = option(8, "injection azimuths per radius, evenly spaced on the scan grid")
    hands: tuple = option(("R",), "hands of the injected planets")
    max_rp_steps: int = option(2, "a recovery lies within this many radius steps of the injected planet")
    max_phi_deg: float = option(30.0, "a recovery lies within this azimuth [deg] of the injected planet")
    chunk: int = option(128, "injections per batch of the cross-term products")
    nthreads: int = option(1, "threads of the NUFFTs that build the injection engine")
    detection: DetectionSettings = option(DetectionSettings(), "the verdict run on every injection")

    def __post_init__(self):
        for name in ("n_azimuths", "chunk", "nthreads"):
            if not is_integer(getattr(self, name)) or getattr(self, name) < 1:
                raise InputError(f"{name} = {getattr(self, name)!r} must be an integer >= 1")
        if not is_integer(self.max_rp_steps) or self.max_rp_steps < 0:
            raise InputError(f"max_rp_steps = {self.max_rp_steps!r} must be an integer >= 0")
        if not is_finite_number(self.max_phi_deg) or not 0 < self.max_phi_deg <= 180:
            raise InputError(f"max_phi_deg = {self.max_phi_deg!r} must be an angle in (0, 180] degrees")
        _check_hands("hands", self.hands)
        object.__setattr__(self, "hands", tuple(self.hands))
        if not isinstance(self.detection, DetectionSettings):
            raise InputError(f"detection = {self.detection!r} must be a DetectionSettings")


@documented
@dataclass(frozen=True)
class LimitSettings:
    """Options of :func:`~spiralbayes.inference.limits.compute_limits`, of
    :func:`~spiralbayes.inference.limits.completeness` (``n_azimuths``, ``inject_hand``) and of the
    Table 3 outputs (TOML section ``[limits]``).

    Every field's description is its ``metadata["doc"]``; ``help()``, the API pages and ``--print-config`` show them.
    ``None`` means automatic (written ``0`` in the TOML file).
    """

    cl: float = option(0.95, "one-sided confidence level of the exclusion limits, in (0.5, 1)")
    method: str = option("all_phi", "'all_phi': excluded at r_p when excluded at every phi_p (the paper's reading); "
                                    "'marginal': phi_p marginalised (uniform prior)")
    hand: str = option("both", "'both': a planet is excluded only when both hands are; 'R' or 'L' when the disc's "
                               "rotation fixes the hand")
    mstar: float = option(DEFAULT_MSTAR_MSUN, "stellar mass [M_sun], for planet masses in M_Jup (M_th = (H/r)^3 M_*)")
    h_ref: float | None = option(None, "H/r at r_ref for the thermal mass (0: the templates' h_p)", toml=0.0)
    r_ref: float = option(50.0, "reference radius of H/r [au]")
    flaring: float = option(0.25, "flaring index: H/r = h_ref (r / r_ref)^flaring, so M_th ~ r_p^(3 flaring)")
    resolution: float | None = option(None, "beam FWHM [arcsec] for the 'unresolved' flag (0: fitted to the data's "
                                            "natural-weighted beam)", toml=0.0)
    resolution_factor: float = option(1.0, "radii below resolution_factor x resolution are flagged 'unresolved', "
                                           "not excluded")
    extent_fraction: float = option(0.95, "radii beyond the radius holding this fraction of the disc's flux are "
                                          "flagged, not excluded")
    completeness: bool = option(True, "injection-recovery (fast path) for the minimum detectable mass")
    n_azimuths: int = option(CompletenessSettings.n_azimuths, "injection azimuths per radius, evenly spaced on "
                                                              "the scan grid")
    inject_hand: tuple = option(CompletenessSettings.hands, "hands of the injected planets")
    thresholds: tuple = option(TABLE3_THRESHOLDS, "planet masses [M_th] of the table's columns (the paper's Table 3: 3 "
                                           "and 1)")
    name: str = option("", "disc name in the table (empty: the data file's stem)")
    # code only
    bright_radius: float | None = option(None, "outer radius of the disc's bright part [arcsec] (default: the "
                                               "radius holding extent_fraction of the flux)", config=False)
    planet_beam: float | None = option(None, "radius [arcsec] around a known planet flagged 'near_planet' "
                                             "(default: resolution)", config=False)

    def __post_init__(self):
        if not is_finite_number(self.cl) or not 0.5 < self.cl < 1:
            raise InputError(f"cl = {self.cl!r} must be a confidence level in (0.5, 1), e.g. 0.95")
        if self.method not in LIMIT_METHODS:
            raise InputError(f"method = {self.method!r} must be one of {', '.join(map(repr, LIMIT_METHODS))}")
        if self.hand not in ("both", *HANDS):
            raise InputError(f"hand = {self.hand!r} must be one of 'both', 'R', 'L'")
        for name in ("mstar", "r_ref"):
            if not is_finite_number(getattr(self, name)) or getattr(self, name) <= 0:
                raise InputError(f"{name} = {getattr(self, name)!r} must be a positive, finite number")
        for name in ("h_ref", "resolution", "bright_radius", "planet_beam"):
            value = getattr(self, name)
            # an infinite bright radius or planet beam is allowed: no radius is flagged for it
            unbounded = name in ("bright_radius", "planet_beam") and value == float("inf")
            if value is not None and not unbounded and (not is_finite_number(value) or value < 0):
                raise InputError(f"{name} = {value!r} must be a finite number >= 0 (or None: automatic)")
        if not is_finite_number(self.flaring):
            raise InputError(f"flaring = {self.flaring!r} must be a finite number")
        if not is_finite_number(self.resolution_factor) or self.resolution_factor < 0:
            raise InputError(f"resolution_factor = {self.resolution_factor!r} must be a finite number >= 0")
        if not is_finite_number(self.extent_fraction) or not 0 < self.extent_fraction <= 1:
            raise InputError(f"extent_fraction = {self.extent_fraction!r} must be a fraction in (0, 1]")
        if not is_integer(self.n_azimuths) or self.n_azimuths < 1:
            raise InputError(f"n_azimuths = {self.n_azimuths!r} must be an integer >= 1")
        _check_hands("inject_hand", self.inject_hand)
        if isinstance(self.thresholds, str) or any(not is_finite_number(m) or m <= 0 for m in self.thresholds):
            raise InputError(f"thresholds = {self.thresholds!r} must be a list of positive planet masses [M_th]")
        object.__setattr__(self, "inject_hand", tuple(self.inject_hand))
        object.__setattr__(self, "thresholds", tuple(self.thresholds))


@documented
@dataclass(frozen=True)
class ForecastSettings:
    """Options of :func:`~spiralbayes.inference.limits.forecast` (and of
    :func:`~spiralbayes.inference.limits.compare_setups`, which uses ``n_phi`` and ``nthreads``).

    Every field's description is its ``metadata["doc"]``.
    """

    n_phi: int = option(90, "planet azimuths averaged over (the scan's 4 deg steps)")
    time_on_source: float | None = option(None, "total time on source [min]: rebuilds the tracks for that time "
                                                "(default: the set-up's)")
    sensitivity: float | None = option(None, "image noise [Jy/beam] at that time (default: the set-up's, scaled "
                                             "as t^-1/2)")
    nthreads: int = option(1, "threads of the NUFFTs")

    def __post_init__(self):
        for name in ("n_phi", "nthreads"):
            if not is_integer(getattr(self, name)) or getattr(self, name) < 1:
                raise InputError(f"{name} = {getattr(self, name)!r} must be an integer >= 1")
        for name in ("time_on_source", "sensitivity"):
            value = getattr(self, name)
            if value is not None and (not is_finite_number(value) or value <= 0):
                raise InputError(f"{name} = {value!r} must be a positive, finite number (or None: the set-up's)")
