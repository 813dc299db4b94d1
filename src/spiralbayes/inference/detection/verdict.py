"""Detection verdict from a scan: ΔBIC (test 1) and the spatial / handedness test (test 2).

Stevenson et al. (2024, sec. 3-4): a spiral is claimed when the best template's ΔBIC exceeds 10
(very strong evidence) *and* its Δχ² heatmap shows a compact peak whose mirror-image template
(the other hand, same mass, tau0 and beta) fits clearly worse near the same place. Arcs, vortices
and geometry errors (their Appendix A) raise Δχ² for both hands alike and in extended,
one-sided clusters.

Why this module is long: the :class:`Verdict` documents each of its ~30 fields for the API page and
``help()``, and tests 1 and 2 (the peak, its mirror, its localisation) are one procedure whose
helpers are read together; test 3 lives in :mod:`.nested`, :mod:`.explanation` and
:mod:`~spiralbayes.inference.detection.mass`.

Quantities used here (spiralbayes' definitions; thresholds are parameters):

* ``handedness_ratio``: the mirror template's largest Δχ² at radii within ``neighbourhood`` grid
  steps of the best instance (any azimuth: a geometry error places the mirror template's best fit
  at the reflected azimuth), divided by the best Δχ². Test passes when below
  ``max_handedness_ratio``.
* ``localisation``: fraction of the scanned disc area (weights ``r dr dphi``) where the best
  template's Δχ² exceeds half its peak. Test passes when below ``max_localisation``.

Test 3 (spiralbayes' addition, ``docs/verdict.md``): the paper's test 2 asks that the Δχ² structure show the
improvement is "caused by a spiral, not some other asymmetry". Given the maximum-likelihood fits of the
competing models (:func:`spiralbayes.inference.detection.alternatives.fit_alternatives`: geometry error,
arc/vortex, lopsided disc, eccentric ring, eccentric bright ring, m = 2 pattern), the spiral must beat the
best of them by ``ΔBIC_spiral − ΔBIC_alt > alternative_threshold`` (default 10, "very strong" on the scale of
Kass & Raftery 1995, the threshold test 1 uses against the axisymmetric model). Both ΔBIC are against the same
axisymmetric model and data, so their difference is ``BIC_alt − BIC_spiral``. When it fails the verdict names
the alternative.

Given the scanned data too (``vis``, ``axisymmetric``, ``templates``, as the pipeline runs it) test 3
is the **nested** question (:mod:`.nested`): once the best alternatives (``nested_alternatives``,
each on its own) are in the model, fitted jointly with the spiral, does the spiral still lower the
BIC by more than ``nested_threshold``? Then "which single model is best" (the comparison above,
with the planet's compact peak, :mod:`.planet_peak`) is kept as information. An alternative that
is significant on its own and survives the joint fit is named as also present. With a calibration
diagnostic that warns (:func:`spiralbayes.calibration.diagnose_calibration`, measured by default
when the data record their antennas) and no spiral claimed, the verdict names calibration errors, not
a disc asymmetry, as the explanation; a spiral is not claimed while antenna phase errors remain with
it in the model (:mod:`.explanation`).

When the global peak fails test 2, :func:`detect` also looks for the best *handed, compact*
candidate — the highest local maximum of any template that passes test 1 and whose mirror ratio
and local peak area pass test 2 — so that a planet behind a false peak (e.g. from a phase-centre
error) is not hidden.
Its ``localisation`` is the area of its own connected region above half its Δχ² (for the global
peak of a map with one peak this equals the paper's measure above).

The planet's mass is reported as a **range** (:func:`.mass.mass_range`; docs/verdict.md): no template is the true
spiral, and templates of other morphology variants and H/r explain a real spiral almost as well as
the best one, so its single label would claim more than the data say. The range covers every
template of the best one's hand whose best Δχ² near the best instance is within ``mass_band``
(ΔBIC 10 by default) of it; in M_Jup each template's mass uses its own ``h_p``
(``M_th = h_p³ M_*``, Stevenson et al. 2024 eq. 1).
"""

from __future__ import annotations

import warnings
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...calibration.diagnostics import diagnose_calibration
from ...exceptions import InputError
from ...io.argument_checks import check_scan_result
from ...results import ResultMixin, fields_dict
from ...settings import with_overrides
from .settings import DELTA_BIC_THRESHOLD, AlternativesSettings, DetectionSettings
from .planet_peak import rescore_with_planet_peak
from .explanation import (calibration_sentence, explain, nested_sentence, phase_warns, rediagnose,
                          rediagnose_with_spiral, withhold)
from .kinds import best_by_kind, kind_position_sentence
from .nested import apply_nested
from .mass import mass_range
from .candidate import compact_source

__all__ = ["Verdict", "best_handed_candidate", "detect", "detect_with_planet_peak", "handedness_ratio", "localisation",
           "mass_range", "mirror_index", "one_sidedness"]

ALTERNATIVE_THRESHOLD = AlternativesSettings.threshold
"""Test 3: the spiral's BIC must be lower than the best alternative's by more than this."""
CANDIDATES_PER_TEMPLATE = 5


def mirror_index(result, template: int) -> int | None:
    """Index of the template with the other hand and the same other parameters, if scanned."""
    meta = result.templates[template]
    hand = meta.get("hand")
    if hand not in ("R", "L"):
        return None
    other = {"R": "L", "L": "R"}[hand]
    keys = [k for k in ("mass", "tau0", "beta", "h_p", "flaring", "wavelength", "variant") if k in meta]
    for j, m in enumerate(result.templates):
        if m.get("hand") == other and all(_same(m.get(k), meta[k]) for k in keys):
            return j
    return None


def _same(a, b) -> bool:
    """Equal metadata values; unknown ones (None or NaN, e.g. a FARGO3D run's beta) match each other."""
    unknown = [x is None or (isinstance(x, float) and np.isnan(x)) for x in (a, b)]
    return all(unknown) if any(unknown) else bool(a == b)


def handedness_ratio(result, template: int, i_rp: int, i_phi: int, neighbourhood: int = DetectionSettings.neighbourhood,
                     amplitude=None) -> float:
    """Mirror template's best Δχ² at radii near ``i_rp`` over this template's Δχ² at ``(i_rp, i_phi)``."""
    j = mirror_index(result, template)
    if j is None:
        return float("nan")
    dchi2 = result.delta_chi2(amplitude)
    peak = dchi2[template, i_rp, i_phi]
    rows = slice(max(i_rp - neighbourhood, 0), i_rp + neighbourhood + 1)
    return float(np.max(dchi2[j, rows]) / peak) if peak > 0 else float("nan")


def one_sidedness(result, template: int, amplitude=None) -> float:
    """Resultant length (0-1) of the azimuths where Δχ² > 0, weighted by Δχ² and area.

    Near 1 when the improvement clusters on one side of the disc, as for a planet or for the
    false fits of a phase-centre error (Stevenson et al. 2024, App. A); near 0 for rings.
    """
    dchi2 = result.delta_chi2(amplitude)[template]
    w = np.clip(dchi2, 0, None) * result.r_p[:, None]
    total = w.sum()
    if total <= 0:
        return 0.0
    return float(np.abs(np.sum(w * np.exp(1j * result.phi_p[None, :]))) / total)


def localisation(result, template: int, amplitude=None) -> float:
    """Area fraction of the scanned disc with Δχ² above half the template's peak."""
    dchi2 = result.delta_chi2(amplitude)[template]
    peak = np.max(dchi2)
    if peak <= 0:
        return 1.0
    area = np.broadcast_to(result.r_p[:, None], dchi2.shape)
    return float(area[dchi2 >= 0.5 * peak].sum() / area.sum())



def peak_region_fraction(values: np.ndarray, r_p: np.ndarray, i_rp: int, i_phi: int) -> float:
    """Area fraction of the connected region around ``(i_rp, i_phi)`` where ``values`` >= half its value.

    Neighbours are the four adjacent grid cells, periodic in phi; areas weigh by ``r_p``.
    """
    level = 0.5 * values[i_rp, i_phi]
    if not level > 0:
        return 1.0
    n_r, n_phi = values.shape
    seen = np.zeros(values.shape, dtype=bool)
    seen[i_rp, i_phi] = True
    todo = deque([(i_rp, i_phi)])
    while todo:
        i, j = todo.popleft()
        for a, b in ((i - 1, j), (i + 1, j), (i, (j - 1) % n_phi), (i, (j + 1) % n_phi)):
            if 0 <= a < n_r and not seen[a, b] and values[a, b] >= level:
                seen[a, b] = True
                todo.append((a, b))
    area = np.broadcast_to(r_p[:, None], values.shape)
    return float(area[seen].sum() / area.sum())


def _local_maxima(values: np.ndarray, top: int) -> list[tuple[int, int]]:
    """Indices of the ``top`` highest positive local maxima (8 neighbours, periodic in phi)."""
    padded = np.pad(values, ((1, 1), (0, 0)), constant_values=-np.inf)
    is_max = values > 0
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            if di or dj:
                shifted = np.roll(padded, -dj, axis=1)[1 + di:1 + di + values.shape[0]]
                is_max &= values >= shifted
    idx = np.argwhere(is_max)
    order = np.argsort(values[is_max])[::-1][:top]
    return [(int(idx[o][0]), int(idx[o][1])) for o in order]


def best_handed_candidate(result, amplitude=None, *, neighbourhood: int = DetectionSettings.neighbourhood,
                          max_handedness_ratio: float = DetectionSettings.max_handedness_ratio,
                          max_localisation: float = DetectionSettings.max_localisation,
                          min_delta_bic: float = -np.inf) -> dict | None:
    """The highest local Δχ² maximum of any template that passes test 2 on its own, or None.

    For each template with a mirror image, its ``CANDIDATES_PER_TEMPLATE`` highest local maxima
    with ΔBIC above ``min_delta_bic`` are tried: a candidate passes when the mirror template's best
    Δχ² at nearby radii is below ``max_handedness_ratio`` times its Δχ² and its own peak region
    (:func:`.peak_region_fraction`) is smaller than ``max_localisation`` of the scanned area.
    """
    dchi2 = result.delta_chi2(amplitude)
    threshold = result.peak(amplitude=amplitude)
    offset = threshold.delta_chi2 - threshold.delta_bic
    best = None
    for t in range(len(result.templates)):
        if mirror_index(result, t) is None or not np.all(np.isfinite(dchi2[t])):
            continue
        for i, j in _local_maxima(dchi2[t], CANDIDATES_PER_TEMPLATE):
            value = float(dchi2[t, i, j])
            if (best is not None and value <= best["delta_chi2"]) or value - offset <= min_delta_bic:
                break
            ratio = handedness_ratio(result, t, i, j, neighbourhood, amplitude)
            area = peak_region_fraction(dchi2[t], result.r_p, i, j)
            if np.isfinite(ratio) and ratio < max_handedness_ratio and area < max_localisation:
                best = {"template": result.templates[t]["name"], "template_index": t, "r_p": float(result.r_p[i]),
                        "phi_p_deg": float(np.degrees(result.phi_p[j])), "delta_chi2": value,
                        "delta_bic": value - offset, "handedness_ratio": ratio, "localisation": area}
                break
    return best


def _alternatives_summary(alternatives, spiral_delta_bic: float) -> dict:
    """Each alternative's Δχ², ΔBIC against the axisymmetric model and against the best spiral."""
    n = alternatives.n_data
    return {name: {"label": f.label, "delta_chi2": float(f.delta_chi2), "delta_bic": float(f.delta_bic(n)),
                   "spiral_delta_bic_minus_this": float(spiral_delta_bic - f.delta_bic(n)),
                   "n_params": int(f.n_params), "params": dict(f.params)}
            for name, f in alternatives.fits.items()}


@dataclass(repr=False)
class Verdict(ResultMixin):
    """Outcome of :func:`detect`: tests 1 and 2 of the paper and test 3 (competing models).

    With the scanned data, test 3 is the nested test (:mod:`.nested`): ``test3_method`` is
    "nested" (else "best model"), ``nested_delta_bic`` the smallest ``BIC(alt) − BIC(alt + spiral)``
    over the alternatives tried, ``nested`` each joint fit (:class:`~.nested.NestedFit` as dicts),
    ``nested_template`` the template it was scored with (the best template, or with maps from simulations
    and generator templates in one bank the best of the other kind at the same place when that scores
    higher: :func:`~.nested.nested_candidates`), ``also_present`` the phrase naming an alternative that is
    significant and survives the joint fit;
    ``best_alternative`` and ``delta_bic_vs_alternative`` are then information ("which single model
    is best"). ``calibration`` holds the calibration diagnostic's numbers when one was given, and
    ``explanation`` what the verdict names as the cause of the residual structure ("spiral",
    "calibration", an alternative's name, or None). The other fields are listed below.

    Attributes
    ----------
    detected : bool
        All tests passed (test 3 only when alternatives were given).
    delta_bic : float
        ΔBIC of the best spiral against the axisymmetric model (test 1 passes above the threshold, 10).
    test1_passed, test2_passed : bool
        Tests 1 (ΔBIC) and 2 (a handed, compact peak).
    handedness_ratio : float
        The mirror template's best Δχ² at the peak's radius over the peak's Δχ².
    localisation : float
        Fraction of the scanned area within the peak.
    template : str
        Name of the best template.
    r_p : float
        Its radius [arcsec].
    phi_p_deg : float
        Its azimuth [deg].
    delta_chi2 : float
        Its Δχ².
    threshold_6lnN : float
        ``6 ln N``, the Δχ² at ΔBIC = 0.
    distance : float or None
        Distance [pc] for the au values.
    test3_passed : bool or None
        Test 3 (the competing asymmetry models); None when not run.
    best_alternative, best_alternative_label : str or None
        The best competing model's key and its name in words.
    alternative_delta_bic : float or None
        Its ΔBIC against the axisymmetric model.
    delta_bic_vs_alternative : float or None
        ``ΔBIC_spiral − ΔBIC_alternative`` (positive favours the spiral).
    alternative_threshold : float
        The margin test 3 requires (10).
    alternatives, candidate, planet_peak, mass_range : dict or None
        Every alternative's scores; the best handed compact candidate when the global peak fails test 2;
        the compact-peak score of test 3; the masses [M_th] within a ΔBIC band of the best.
    test3_spiral_model : str or None
        Which spiral hypothesis test 3 scored.
    test3_method, nested_delta_bic, nested_threshold, nested, nested_template, also_present, calibration, explanation
        The nested test 3 and the explanation (above).
    gains_solved : str or None
        What was done to the data's calibration before the scan (set by the pipeline, e.g.
        ``antenna gains solved (phase, 60 s intervals, 9.8 deg rms)``).
    best_by_kind : dict or None
        With the generator's templates and simulated maps in one scan, the best of each kind, where it
        peaks and how many grid steps from the verdict's position
        (:func:`~spiralbayes.inference.detection.kinds.best_by_kind`); the summary says so when the two
        kinds place a significant spiral in different places.
    compact_source : dict or None
        Where no spiral is claimed but a compact source is in the data that a planet and another model
        both explain (:func:`~spiralbayes.inference.detection.candidate.compact_source`): its place
        (``r`` [arcsec], ``r_au``, ``phi_deg``), flux (``flux_mJy``), ``origin``, the models in
        ``explained_by`` and ``next_steps``; then :attr:`outcome` is "candidate".
    """

    detected: bool
    delta_bic: float
    test1_passed: bool
    handedness_ratio: float
    localisation: float
    test2_passed: bool
    template: str
    r_p: float
    phi_p_deg: float
    delta_chi2: float
    threshold_6lnN: float
    distance: float | None = None
    test3_passed: bool | None = None
    best_alternative: str | None = None
    best_alternative_label: str | None = None
    alternative_delta_bic: float | None = None
    delta_bic_vs_alternative: float | None = None
    alternative_threshold: float = ALTERNATIVE_THRESHOLD
    alternatives: dict | None = None
    candidate: dict | None = None
    test3_spiral_model: str | None = None
    planet_peak: dict | None = None
    mass_range: dict | None = None
    test3_method: str | None = None
    nested_delta_bic: float | None = None
    nested_threshold: float | None = None
    nested: list | None = None
    nested_template: str | None = None
    also_present: str | None = None
    calibration: dict | None = None
    explanation: str | None = None
    gains_solved: str | None = None
    best_by_kind: dict | None = None
    compact_source: dict | None = None

    KIND = "spiralbayes.Verdict"
    WHAT = "verdict"

    @property
    def r_p_au(self) -> float | None:
        return None if self.distance is None else self.r_p * self.distance

    @property
    def outcome(self) -> str:
        """"detected" (tests 1-3 pass), "candidate" (a compact source is named, :attr:`compact_source`) or
        "not detected" (a handed compact peak other than the global one, ``candidate``, has not been
        through test 3 and does not make a candidate: the summary suggests following it up)."""
        if self.detected:
            return "detected"
        return "candidate" if self.compact_source else "not detected"

    def to_dict(self) -> dict:
        """The fields as strict-JSON values (NaN, e.g. no mirror template scanned, becomes None), with
        the :attr:`outcome`."""
        return {**fields_dict(self), "outcome": self.outcome}

    def __repr__(self) -> str:
        test3 = "" if self.test3_passed is None else f", test 3 {'passed' if self.test3_passed else 'failed'}"
        return (f"Verdict({'detected' if self.detected else 'not detected'}: {self.template} at r_p = {self.r_p:.3g} "
                f"arcsec, phi_p = {self.phi_p_deg:.0f} deg, Delta BIC = {self.delta_bic:.1f}, test 1 "
                f"{'passed' if self.test1_passed else 'failed'}, test 2 {'passed' if self.test2_passed else 'failed'}"
                f"{test3})")

    def _where(self, r_p: float, phi_deg: float) -> str:
        where = f"r_p = {r_p:.3f} arcsec" + (f" ({r_p * self.distance:.0f} au)" if self.distance else "")
        return where + f", phi_p = {phi_deg:.0f} deg"

    def summary(self) -> str:
        """A few sentences a user could paste into a paper."""
        text = (f"The best-fitting spiral template ({self.template}) at {self._where(self.r_p, self.phi_p_deg)} "
                f"improves chi^2 by {self.delta_chi2:.1f} over the axisymmetric model (Delta BIC = "
                f"{self.delta_bic:.1f}; Delta chi^2 (Delta BIC = 0) = 6 ln N = {self.threshold_6lnN:.1f}).")
        if not self.test1_passed:
            text += " This is not significant evidence for a planet-driven spiral (Delta BIC <= 10)."
        else:
            hand = (f"the mirror-image template's best Delta chi^2 at that radius is {self.handedness_ratio:.2f} "
                    f"times the peak, and the peak covers {100 * self.localisation:.1f} % of the scanned area")
            text += (f" The peak is compact and handed ({hand})." if self.test2_passed else
                     f" However {hand}, so the improvement is not attributed to a planet-driven spiral "
                     "(e.g. an arc or a geometry error).")
        text += self._mass_sentence() + kind_position_sentence(self) if self.test1_passed else ""
        text += nested_sentence(self) if self.test3_method == "nested" else self._test3_sentence()
        text += calibration_sentence(self)
        if self.candidate is not None:
            text += self._candidate_sentence(self.candidate)
        text += " A planet-driven spiral is detected." if self.detected else " No planet-driven spiral is claimed."
        if self.compact_source:
            text += self._compact_source_sentence(self.compact_source)
        return text + (f" The data were corrected first: {self.gains_solved}." if self.gains_solved else "")

    def _mass_sentence(self) -> str:
        m = self.mass_range
        if not m:
            return ""
        mth = _span(m["mth"], "M_th")
        mjup = "" if m["mjup"] is None else f" ({_span(m['mjup'], 'M_Jup', '.2g')} for M_* = {m['mstar']:g} M_sun)"
        h = "/".join(f"{h:g}" for h in m["h_ps"])
        near = f"of that hand within Delta BIC {m['band']:g} of the best near its position"
        if len(m["members"]) == 1:
            return (f" Planet mass {mth}{mjup}: the only template {near} (morphology {m['variants'][0]}; "
                    f"H/r {h}, its own M_th).")
        return (f" Planet mass {mth}{mjup}: the range of the {len(m['members'])} templates {near} (morphologies "
                f"{', '.join(m['variants'])}; H/r {h}, each its own M_th), not a single template's label.")

    def _test3_sentence(self) -> str:
        if self.test3_passed is None:
            return " Test 3 (competing asymmetry models, sb.fit_alternatives) was not run."
        label, margin, thr = self.best_alternative_label, self.delta_bic_vs_alternative, self.alternative_threshold
        if margin is None:
            raise InputError("Verdict: test3_passed is set but delta_bic_vs_alternative is None (test 3's margin)")
        own = f"Delta BIC = {self.alternative_delta_bic:.1f} against the axisymmetric model"
        if self.test3_spiral_model == "spiral + compact peak at the planet":
            own += ("; the spiral hypothesis scored as spiral + compact peak at the planet "
                    "(inference.detection.planet_peak)")
        if self.test3_passed:
            return (f" Test 3: the spiral is preferred over the best competing asymmetry model ({label}, {own}) "
                    f"by Delta BIC = {margin:.1f} (> {thr:g}).")
        alternative_significant = (self.alternative_delta_bic is not None
                                   and self.alternative_delta_bic > DELTA_BIC_THRESHOLD)
        if margin < 0 and alternative_significant:
            text = (f" Test 3: the {label} model explains the data better than any spiral template "
                    f"(by Delta BIC = {-margin:.1f}; {own}).")
        elif margin < 0:  # the best alternative is itself no better than the axisymmetric disc
            text = (f" Test 3: no competing asymmetry model explains the data either: the best, {label}, is not "
                    f"significant against the axisymmetric disc ({own}, <= {DELTA_BIC_THRESHOLD:g}), though it "
                    f"scores Delta BIC = {-margin:.1f} above the best spiral template.")
        else:
            text = (f" Test 3: the spiral is not clearly preferred over the {label} model "
                    f"(Delta BIC = {margin:.1f} <= {thr:g}; {own}).")
        if self.best_alternative == "geometry" and alternative_significant:
            text += " Refit the geometry and scan again (sb.rescan_at_fitted_geometry)."
        return text

    def _candidate_sentence(self, c: dict) -> str:
        return (f" The best handed, compact candidate is {c['template']} at {self._where(c['r_p'], c['phi_p_deg'])} "
                f"(Delta chi^2 = {c['delta_chi2']:.1f}, Delta BIC = {c['delta_bic']:.1f}, mirror ratio "
                f"{c['handedness_ratio']:.2f}, {100 * c['localisation']:.1f} % of the area); follow it up with the "
                "posterior over planet position and free geometry (sb.sample_posterior).")


    def _compact_source_sentence(self, c: dict) -> str:
        where = f"r = {c['r']:.3f} arcsec" + (f" ({c['r_au']:.0f} au)" if c.get("r_au") is not None else "")
        flux = "" if c.get("flux_mJy") is None else f", {c['flux_mJy']:.3g} mJy"
        models = ", ".join(c["explained_by"][:-1]) + f" or {c['explained_by'][-1]}"
        if c["origin"] == "spiral":
            why = (f"tests 1 and 2 find it, and test 3 cannot tell a spiral from the alternatives (statistic "
                   f"{c['nested_delta_bic']:.1f} <= {self.nested_threshold:g})")
        else:
            why = (f"the arc/vortex model finds it (Delta BIC = {c['delta_bic']:.1f} against the axisymmetric "
                   "disc), and no spiral template explains it as well")
        return (f" Candidate: a compact source at {where}, phi = {c['phi_deg']:.0f} deg{flux}, explained by "
                f"{models}: {why}. {c['next_steps']}")


def _span(values, unit: str, fmt: str = "g") -> str:
    lo, hi = (format(v, fmt) for v in values)
    return f"{lo} {unit}" if lo == hi else f"{lo}-{hi} {unit}"


def _check_same_data(result, alternatives) -> None:
    same_n = alternatives.n_data == result.n_data
    if not same_n or not np.isclose(alternatives.chi2_AO, result.chi2_AO, rtol=1e-6, atol=1e-6):
        raise InputError(
            "the alternatives were fitted to other data or another axisymmetric model than the scan "
            f"(N = {alternatives.n_data} vs {result.n_data}, chi2_AO = {alternatives.chi2_AO:.6g} vs "
            f"{result.chi2_AO:.6g}): fit them with the scan's visibilities and axisymmetric model")


def detect(scan_result=None, amplitude=None, *, settings: DetectionSettings | None = None, alternatives=None,
           vis=None, axisymmetric=None, templates=None, geometry=None, calibration=None, **overrides) -> Verdict:
    """Decide whether a scan detects a planet-driven spiral.

    Tests 1 and 2 are the paper's (module docstring). With ``alternatives`` (an
    :class:`~spiralbayes.inference.detection.alternatives.AlternativesResult` fitted to the same data and
    axisymmetric model) test 3 is applied too, and a detection needs all three.

    Parameters
    ----------
    scan_result : ScanResult
        The scan to judge (the keyword ``result=`` is accepted with a FutureWarning).
    amplitude : None or "free"
        The spiral amplitude convention of the scan's Δχ² (fixed A = 1, or a free amplitude with
        one more BIC parameter).
    settings : DetectionSettings, optional
        The thresholds of tests 1-3, the mass band and the stellar mass [M_sun] (default
        ``DetectionSettings()``, the paper's tests).
    alternatives : AlternativesResult, optional
        Competing asymmetry models (:func:`spiralbayes.inference.detection.alternatives.fit_alternatives`).
    vis, axisymmetric, templates : Visibilities, AxisymmetricModel, sequence of SpiralTemplate, optional
        The scanned data, model and templates (in the scan's order). Given with ``alternatives``, test 3
        is the nested test (:mod:`.nested`: the best alternatives fitted jointly with the spiral), as
        ``spiralbayes scan`` does, and the single-model comparison scores the spiral with the planet's
        own compact peak against the arc alternative (:mod:`.planet_peak`); without them test 3 is
        that single-model comparison with the bare spiral.
    geometry : DiscGeometry, optional
        Where the joint fits place the models (default: the axisymmetric model's).
    calibration : CalibrationDiagnostic or False, optional
        :func:`spiralbayes.calibration.diagnose_calibration` of the same data and model; when it
        warns and no spiral is claimed, the verdict names calibration as the explanation. By
        default it is measured here when ``vis`` records its antennas (a Measurement Set, a
        spiralbayes HDF5 file, a simulation) and ``axisymmetric`` is given; ``False`` skips it.
    **overrides
        Fields of :class:`DetectionSettings` replacing those of ``settings`` (e.g.
        ``bic_threshold_value=15``, ``mstar=1.2``).

    Returns
    -------
    Verdict
        The outcome of tests 1-3, the best template and position, and ``summary()``'s sentence.

    Examples
    --------
    >>> import spiralbayes as sb
    >>> vis = sb.simulate_observation("taurus", seed=1)  # the Taurus survey's set-up, no planet
    >>> disc = sb.fit_axisymmetric(vis, sb.DiscGeometry(inc=30, PA=60), progress=False, N=100)
    >>> templates = [sb.make_template(mass=3.0, tau0=3.0, beta=10.0, hand=h, wavelength=1.33e-3) for h in "RL"]
    >>> result = sb.scan(vis, disc, templates, r_p=[0.2, 0.3, 0.4], distance=140.0, progress=False)
    >>> verdict = sb.detect(result)
    >>> verdict.detected, verdict.test1_passed
    (False, False)

    With the competing asymmetry models, test 3 is applied too:
    ``sb.detect(result, alternatives=sb.fit_alternatives(vis, disc))``.
    """
    if "result" in overrides:
        if scan_result is not None:
            raise TypeError("detect() got both scan_result and result: pass the ScanResult once, as scan_result")
        warnings.warn("detect(result=...) is renamed detect(scan_result=...)", FutureWarning, stacklevel=2)
        scan_result = overrides.pop("result")
    s = with_overrides(settings, DetectionSettings, overrides, "detect")
    check_scan_result(scan_result)
    result = scan_result
    neighbourhood, max_handedness_ratio, max_localisation = s.neighbourhood, s.max_handedness_ratio, s.max_localisation
    bic_threshold_value, alternative_threshold = s.bic_threshold_value, s.alternative_threshold
    mass_band, mstar = s.mass_band, s.mstar
    best = result.peak(amplitude=amplitude)
    t = best.template_index
    ratio = handedness_ratio(result, t, best.i_rp, best.i_phi, neighbourhood, amplitude)
    loc = localisation(result, t, amplitude)
    test1 = bool(best.delta_bic > bic_threshold_value)
    test2 = bool(np.isfinite(ratio) and ratio < max_handedness_ratio and loc < max_localisation)
    # a mass is worth reporting only for a significant spiral
    extra: dict[str, Any] = {
        "alternative_threshold": float(alternative_threshold),
        "mass_range": mass_range(result, amplitude, band=mass_band, mstar=mstar) if test1 else None,
        "best_by_kind": best_by_kind(result, amplitude, bic_threshold_value)}
    if alternatives is not None:
        _check_same_data(result, alternatives)
        alt = alternatives.best
        alt_bic = float(alt.delta_bic(alternatives.n_data))
        margin = float(best.delta_bic) - alt_bic
        extra.update(test3_passed=bool(margin > alternative_threshold), test3_spiral_model="spiral",
                     best_alternative=alt.name,
                     best_alternative_label=alt.label, alternative_delta_bic=alt_bic,
                     delta_bic_vs_alternative=margin,
                     alternatives=_alternatives_summary(alternatives, float(best.delta_bic)))
    if not test2:
        extra["candidate"] = best_handed_candidate(result, amplitude, neighbourhood=neighbourhood,
                                                   max_handedness_ratio=max_handedness_ratio,
                                                   max_localisation=max_localisation,
                                                   min_delta_bic=bic_threshold_value)
    detected = test1 and test2 and extra.get("test3_passed") is not False
    verdict = Verdict(
        detected=bool(detected), delta_bic=best.delta_bic, test1_passed=test1,
        handedness_ratio=ratio, localisation=loc, test2_passed=test2, template=best.template,
        r_p=best.r_p, phi_p_deg=float(np.degrees(best.phi_p)), delta_chi2=best.delta_chi2,
        threshold_6lnN=best.delta_chi2 - best.delta_bic, distance=result.distance,
        test3_method=None if alternatives is None else "best model", **extra)
    data = {"vis": vis, "axisymmetric": axisymmetric, "templates": templates}
    missing = [k for k, v in data.items() if v is None]
    if len(missing) != 3 and missing:
        raise InputError(f"detect: give vis, axisymmetric and templates together (missing {', '.join(missing)}) "
                         "so that test 3 can fit the spiral jointly with the alternatives, or none of them")
    if calibration is None and not missing and getattr(vis, "has_antennas", False):
        calibration = diagnose_calibration(vis, axisymmetric)
    calibration = calibration or None
    if not missing and alternatives is not None:
        verdict = rescore_with_planet_peak(verdict, result, vis, axisymmetric, templates, geometry,
                                           alternatives=alternatives)
        verdict = apply_nested(verdict, result, vis, axisymmetric, templates, geometry, alternatives, s)
        if calibration is not None and verdict.detected and phase_warns(calibration):
            again = rediagnose_with_spiral(vis, axisymmetric, list(templates)[t], best.r_p, best.phi_p, geometry)
            if phase_warns(again):
                return explain(withhold(verdict), calibration, again, "spiral", withheld=True)
        if calibration is not None and calibration.warning and not verdict.detected:
            again = rediagnose(calibration, vis, axisymmetric, geometry, alternatives)
            verdict = explain(verdict, calibration, again, alternatives.best.name)
        else:
            verdict = explain(verdict, calibration)
        verdict.compact_source = compact_source(verdict, axisymmetric, s)
        return verdict
    verdict = explain(verdict, calibration)
    if alternatives is not None:
        verdict.compact_source = compact_source(verdict, axisymmetric, s)
    return verdict


def detect_with_planet_peak(result, vis, axisymmetric, templates, geometry=None, amplitude=None, *,
                            alternatives=None, **detect_kwargs) -> Verdict:
    """:func:`detect` with the scanned data: test 3 is the nested test (:mod:`.nested`), and the
    single-model comparison scores the spiral with the planet's compact peak at ``geometry``
    (:func:`~.planet_peak.rescore_with_planet_peak`; default: the axisymmetric model's geometry).

    Both fits are made only when there are alternatives and test 1 passes (otherwise test 3 cannot
    change the verdict); ``detect_kwargs`` go to :func:`detect` (e.g. ``calibration=``).
    """
    return detect(result, amplitude, alternatives=alternatives, vis=vis, axisymmetric=axisymmetric,
                  templates=templates, geometry=geometry, **detect_kwargs)
