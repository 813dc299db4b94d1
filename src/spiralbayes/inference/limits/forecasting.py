"""Observation forecasts: will ALMA detect this planet's spiral, and how long must it look?

For a disc model, a planet (template and r_p) and an observing set-up (one of the paper's Table 1
presets, or a :class:`~spiralbayes.simulate.Preset` with other configurations, times on source or
sensitivity), the data that would contain the planet give, at the planet's own instance,

    Δχ² = 2 cross - power,   cross = power + n,   n ~ N(0, power),

(residual = the planet's ΔV plus noise, axisymmetric model and template exact), so

    ``E[Δχ²] = power = sum_k w_k |ΔV_k|^2``  (= chi2_SA, the paper's App. B),   ``sd[Δχ²] = 2 sqrt(power)``,

and ``P(ΔBIC > 10) ≈ Q((6 ln N + 10 - E) / (2 sqrt(E)))`` (Q the Gaussian tail), averaged over
phi_p (uniform: where the planet happens to be). ``power`` comes from the scan's power term on
the set-up's uv coverage with weights ``1 / sigma^2``, ``sigma = sensitivity sqrt(N)``.

**Time on source.** At fixed uv coverage the weights, and so E[Δχ²], scale linearly with time;
more time as more integrations also grows N (the threshold ``6 ln N`` rises by ``6 ln f`` for
``f`` times the time). :meth:`Forecast.time_for_probability` solves for the time that gives a
chosen detection probability under that scaling. The approximation breaks (1) when the extra
time changes the uv coverage (longer tracks, other configurations: re-run :func:`forecast` with
``time_on_source``, which rebuilds the tracks), (2) when the axisymmetric model or the template
is wrong: mismatch residuals grow with time like the signal, so a systematic floor appears
(ΔBIC may grow for spurious fits too; the handedness test is not modelled here), (3) when
calibration or dynamic-range errors, not thermal noise, limit the data, and (4) near the
threshold the scan's maximum over many instances (look-elsewhere) and frank absorbing part of
the signal make the single-instance estimate optimistic for weak, and pessimistic for
very strong, spirals. The forecast covers test 1 (ΔBIC) only.
"""

from __future__ import annotations

import dataclasses
import logging
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..._provenance import json_safe
from ...exceptions import DataWarning, InputError
from ...results import ResultMixin, fields_dict
from ...geometry import DiscGeometry
from ...settings import with_overrides
from ...simulate import DiscModel, Preset, get_preset
from ...simulate.noise import sigma_for_sensitivity
from ...templates.template import template_metadata
from ...visibilities import Visibilities
from ..detection.verdict import DELTA_BIC_THRESHOLD
from ..scan.engine import ScanContext, scan_template
from ..scan.statistics import N_SPIRAL_PARAMETERS
from .settings import ForecastSettings

__all__ = ["Forecast", "compare_setups", "detectable_mass", "forecast", "format_minutes", "setup_for_time"]

log = logging.getLogger(__name__)


def setup_for_time(setup, time_on_source: float | None = None, sensitivity: float | None = None) -> Preset:
    """A preset with its times on source scaled to ``time_on_source`` [min] in total.

    The image noise scales as ``t^-1/2`` (radiometer equation) unless ``sensitivity`` [Jy/beam]
    is given; each configuration keeps its share of the time.
    """
    p = get_preset(setup)
    if time_on_source is None:
        return p if sensitivity is None else dataclasses.replace(p, sensitivity=float(sensitivity))
    if not time_on_source > 0:
        raise InputError(f"time_on_source must be positive [min], got {time_on_source!r}")
    f = float(time_on_source) / p.total_time_on_source
    noise = p.sensitivity / np.sqrt(f) if sensitivity is None else float(sensitivity)
    return dataclasses.replace(p, time_on_source=tuple(t * f for t in p.time_on_source), sensitivity=noise,
                               name=f"{p.name} ({time_on_source:g} min)")


def _profile(disc, wavelength: float):
    if isinstance(disc, DiscModel):
        return disc.profile(wavelength)
    if callable(getattr(disc, "brightness", None)):
        return disc.brightness
    if callable(disc):
        return disc
    raise InputError("disc must be a DiscModel, an AxisymmetricModel or a brightness callable I(r [arcsec]) [Jy/sr]")


@dataclass(repr=False)
class Forecast(ResultMixin):
    """Expected detectability of one planet with one set-up (see the module docstring).

    Attributes
    ----------
    template : dict
        Metadata of the planet's template.
    r_p : float
        Planet radius [arcsec].
    phi_p : ndarray
        Azimuths [rad] the expectation was computed at.
    expected : ndarray
        ``E[Δχ²] = sum w |ΔV|^2`` at each azimuth.
    n_data : int
        Number of visibilities N of the set-up.
    time_on_source : float
        [min].
    setup : dict
        The preset used (``Preset.to_dict``).
    bic_threshold : float
        ΔBIC a detection needs (10).
    n_params : int
        Parameters in the BIC (6).
    distance : float or None
    """

    template: dict
    r_p: float
    phi_p: np.ndarray
    expected: np.ndarray
    n_data: int
    time_on_source: float
    setup: dict = field(default_factory=dict)
    bic_threshold: float = DELTA_BIC_THRESHOLD
    n_params: int = N_SPIRAL_PARAMETERS
    distance: float | None = None

    KIND = "spiralbayes.Forecast"
    WHAT = "forecast"

    def threshold(self, time: float | None = None) -> float:
        """Δχ² a detection needs, ``k ln N + ΔBIC_min``, at ``time`` [min] (N ∝ time)."""
        f = 1.0 if time is None else float(time) / self.time_on_source
        return self.n_params * float(np.log(self.n_data * f)) + self.bic_threshold

    def expected_at(self, time: float | None = None) -> np.ndarray:
        """E[Δχ²] at each azimuth after ``time`` [min] (linear in time at fixed uv coverage)."""
        f = 1.0 if time is None else float(time) / self.time_on_source
        return self.expected * f

    @property
    def spread(self) -> np.ndarray:
        """Standard deviation of Δχ² at each azimuth, ``2 sqrt(E)``."""
        return 2.0 * np.sqrt(self.expected)

    def probability_per_phi(self, time: float | None = None) -> np.ndarray:
        """``P(ΔBIC > threshold)`` at each azimuth, ``Phi((E - threshold) / (2 sqrt(E)))``."""
        from scipy.stats import norm

        e = self.expected_at(time)
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.where(e > 0, (e - self.threshold(time)) / (2 * np.sqrt(np.where(e > 0, e, 1.0))), -np.inf)
        return norm.cdf(z)

    def probability(self, time: float | None = None) -> float:
        """``P(ΔBIC > threshold)`` averaged over phi_p (uniform), after ``time`` [min]."""
        return float(np.mean(self.probability_per_phi(time)))

    def time_for_probability(self, probability: float = 0.9, max_time: float = 1e6) -> float:
        """On-source time [min] for a detection probability (``inf`` if beyond ``max_time``).

        Searched between 100 visibilities' worth of time and ``max_time`` [min].
        """
        from scipy.optimize import brentq

        if not 0 < probability < 1:
            raise InputError(f"probability must lie in (0, 1), got {probability!r}")
        # shortest time considered: 100 visibilities' worth (below that 6 ln N loses its meaning)
        lo, hi = np.log(self.time_on_source * min(1.0, 100.0 / self.n_data)), np.log(max_time)
        if self.probability(np.exp(hi)) < probability:
            return float("inf")
        if self.probability(np.exp(lo)) >= probability:
            return float(np.exp(lo))
        return float(np.exp(brentq(lambda lt: self.probability(np.exp(lt)) - probability, lo, hi, xtol=1e-6)))

    def summary(self, probability: float = 0.9) -> str:
        """One paragraph: E[Δχ²], the threshold, P(ΔBIC > 10) and the time for ``probability``."""
        where = f"r_p = {self.r_p:.3f} arcsec" + (f" ({self.r_p * self.distance:.0f} au)" if self.distance else "")
        e = self.expected
        needed = format_minutes(self.time_for_probability(probability))
        return (f"{self.template.get('name', 'planet')} at {where} with {self.setup.get('name', 'set-up')} "
                f"({self.time_on_source:.0f} min, N = {self.n_data}): E[Δχ²] = {e.mean():.1f} "
                f"(range over phi_p {e.min():.1f}-{e.max():.1f}, sd {2 * np.sqrt(e.mean()):.1f}) against "
                f"6 ln N + 10 = {self.threshold():.1f}; P(ΔBIC > 10) = {self.probability():.2f}; "
                f"{100 * probability:g} % needs {needed} on source (linear scaling, fixed uv coverage).")

    def to_dict(self) -> dict:
        """The fields as JSON-safe values, with the expectation's range, the threshold, P(ΔBIC > 10)
        and the time for 90 % (``inf`` becomes None)."""
        return {**fields_dict(self), "time_on_source_min": self.time_on_source,
                **json_safe({"expected_mean": float(self.expected.mean()), "expected_min": float(self.expected.min()),
                             "expected_max": float(self.expected.max()), "threshold": self.threshold(),
                             "probability": self.probability(),
                             "time_for_90_percent_min": self.time_for_probability(0.9)})}

    def __repr__(self) -> str:
        return (f"Forecast({self.template.get('name', 'planet')} at r_p = {self.r_p:.3g} arcsec, "
                f"{self.setup.get('name', 'set-up')} {self.time_on_source:.0f} min, N = {self.n_data}, "
                f"E[dchi2] = {float(self.expected.mean()):.1f}, P = {self.probability():.2f})")


def forecast(disc, template, r_p: float, setup="fiducial", *, settings: ForecastSettings | None = None,
             geometry: DiscGeometry | None = None, distance: float | None = None, coverage=None,
             **overrides) -> Forecast:
    """E[Δχ²], its spread and P(ΔBIC > 10) for a planet observed with a set-up.

    Parameters
    ----------
    disc : DiscModel, AxisymmetricModel or callable
        The disc (the package's power-law disc, a frank profile, or ``I(r [arcsec])`` [Jy/sr]).
    template : SpiralTemplate
        The planet's spiral.
    r_p : float
        Planet radius [arcsec].
    setup : str or Preset
        A Table 1 preset name or a :class:`~spiralbayes.simulate.Preset`.
    settings : ForecastSettings, optional
        ``n_phi`` (planet azimuths averaged over), ``time_on_source`` (total time on source [min]:
        rebuilds the tracks for that time, noise ∝ t^-1/2 unless ``sensitivity`` [Jy/beam] is given)
        and ``nthreads``; default ``ForecastSettings()``.
    geometry : DiscGeometry
        Default ``DiscGeometry(30, 60)`` (as :func:`~spiralbayes.simulate.simulate_observation`).
    distance : float, optional
        [pc], for text output in au (default the DiscModel's).
    coverage : UVCoverage, optional
        Reuse a coverage of the same set-up.
    **overrides
        Fields of :class:`ForecastSettings` replacing those of ``settings`` (e.g. ``n_phi=18``).

    Returns
    -------
    Forecast
        E[Δχ²] over the planet azimuths, its spread, the threshold and P(ΔBIC > 10); ``summary()``
        says the time on source a 90 % detection needs.
    """
    s = with_overrides(settings, ForecastSettings, overrides, "forecast")
    time_on_source, sensitivity, n_phi, nthreads = s.time_on_source, s.sensitivity, s.n_phi, s.nthreads
    preset = setup_for_time(setup, time_on_source, sensitivity)
    _check_overlap(_profile(disc, preset.wavelength), template, r_p)
    context = _setup_context(preset, r_p, geometry, n_phi, coverage, nthreads)
    return _forecast(context, preset, disc, template, distance)


def _check_overlap(profile, template, r_p) -> None:
    """Refuse a planet whose template lies where the disc has no flux (before any transform)."""
    if not r_p > 0:
        raise InputError(f"r_p must be a positive radius [arcsec], got {r_p!r}")
    x = np.asarray(template.x, dtype=float)
    r = np.geomspace(x[0], x[-1], 400) * float(r_p)
    if not np.any(np.asarray(profile(r), dtype=float) > 0):
        raise InputError(f"at r_p = {r_p:.3g} arcsec the template ({r[0]:.3g}-{r[-1]:.3g} arcsec) lies outside "
                         "the disc (no flux under it): choose r_p inside the disc's bright extent")


def _setup_context(preset: Preset, r_p, geometry, n_phi, coverage, nthreads) -> ScanContext:
    """The scan context of a set-up's uv coverage and weights (zero residual; profile set per disc)."""
    if not r_p > 0:
        raise InputError(f"r_p must be a positive radius [arcsec], got {r_p!r}")
    geometry = DiscGeometry(30.0, 60.0) if geometry is None else geometry
    cov = preset.coverage() if coverage is None else coverage
    sigma = sigma_for_sensitivity(preset.sensitivity, cov.n)
    vis = Visibilities(cov.u, cov.v, np.zeros(cov.n, complex), np.full(cov.n, sigma ** -2), wavelength=cov.wavelength)
    zero = np.zeros(cov.n, complex)
    return ScanContext.build(vis, (lambda r: np.zeros_like(np.asarray(r, dtype=float)), zero), geometry,
                             [float(r_p)], n_phi, nthreads=nthreads)


def _forecast(context: ScanContext, preset: Preset, disc, template, distance) -> Forecast:
    tw = getattr(template, "wavelength", None)
    if tw and np.isfinite(tw) and not np.isclose(tw, preset.wavelength, rtol=0.02):
        warnings.warn(f"the template was made for {tw * 1e3:.2f} mm, the set-up observes at "
                      f"{preset.wavelength * 1e3:.2f} mm (make_template(wavelength=...))", DataWarning, stacklevel=3)
    context = dataclasses.replace(context, profile=_profile(disc, preset.wavelength))
    _, power = scan_template(context, template)
    r_p = float(context.r_p[0])
    if not np.any(power > 0):
        raise InputError(f"at r_p = {r_p:.3g} arcsec the template lies outside the disc (no flux under it): "
                         "choose r_p inside the disc's bright extent")
    if distance is None and isinstance(disc, DiscModel):
        distance = disc.distance
    return Forecast(template_metadata(template), r_p, 2 * np.pi * np.arange(context.n_phi_p) / context.n_phi_p,
                    power[0], int(context.u.size), preset.total_time_on_source,
                    {**preset.to_dict(), "name": preset.name}, distance=distance)


def compare_setups(disc_for, templates, r_p: float, setups=("fiducial", "high_sensitivity"), *,
                   geometry: DiscGeometry | None = None, n_phi: int = ForecastSettings.n_phi,
                   nthreads: int = ForecastSettings.nthreads) -> list[dict]:
    """E[Δχ²] and P(ΔBIC > 10) of several templates under several set-ups (one row per template).

    ``disc_for(template)`` gives the disc for a template (e.g. a DiscModel whose optical depth at
    ``r_p`` is the template's tau0); pass ``lambda t: disc`` for one disc. Each set-up's uv
    weights are computed once.
    """
    contexts = {}
    for name in setups:
        preset = setup_for_time(name)
        contexts[name] = (preset, _setup_context(preset, r_p, geometry, n_phi, None, nthreads))
    rows = []
    for t in templates:
        row = {"template": t.name, "mass": t.mass, "tau0": t.tau0, "beta": t.beta}
        for name, (preset, context) in contexts.items():
            fc = _forecast(context, preset, disc_for(t), t, None)
            row[f"E_{name}"] = float(fc.expected.mean())
            row[f"threshold_{name}"] = fc.threshold()
            row[f"P_{name}"] = fc.probability()
        rows.append(row)
    return rows


def detectable_mass(masses, expected, threshold: float) -> tuple[float, bool]:
    """The mass [same unit as ``masses``] at which E[Δχ²] reaches ``threshold`` (P(ΔBIC > 10) = 50 %).

    ``ln E`` is interpolated linearly in ``ln M`` between the bank's masses, and extrapolated
    with the slope of the nearest pair beyond them (the second value is True then).
    """
    m = np.log(np.asarray(masses, dtype=float))
    e = np.log(np.maximum(np.asarray(expected, dtype=float), 1e-300))
    order = np.argsort(m)
    m, e = m[order], e[order]
    t = np.log(threshold)
    if e[0] <= t <= e[-1]:
        return float(np.exp(np.interp(t, e, m))), False
    i = 0 if t < e[0] else m.size - 2
    slope = (e[i + 1] - e[i]) / (m[i + 1] - m[i])
    return float(np.exp(m[i] + (t - e[i]) / slope)), True


def format_minutes(minutes: float) -> str:
    """A time on source for people: "not reachable", "< 1 min", "12 min" or "95 min (1.6 h)"."""
    if not np.isfinite(minutes):
        return "not reachable (beyond 10^6 min)"
    if minutes < 1:
        return "< 1 min"
    text = f"{minutes:.0f} min"
    return text + (f" ({minutes / 60:.1f} h)" if minutes >= 60 else "")
