"""Detection verdict from a scan: ΔBIC (test 1) and the spatial / handedness test (test 2).

Stevenson et al. (2024, sec. 3-4): a spiral is claimed when the best template's ΔBIC exceeds 10
(very strong evidence) *and* its Δχ² heatmap shows a compact peak whose mirror-image template
(the other hand, same mass, tau0 and beta) fits clearly worse near the same place. Arcs, vortices
and geometry errors (their Appendix A) raise Δχ² for both hands alike and in extended,
one-sided clusters.

Quantities used here (spiralbayes' definitions; thresholds are parameters):

* ``handedness_ratio``: the mirror template's largest Δχ² at radii within ``neighbourhood`` grid
  steps of the best instance (any azimuth: a geometry error places the mirror template's best fit
  at the reflected azimuth), divided by the best Δχ². Test passes when below
  ``max_handedness_ratio``.
* ``localisation``: fraction of the scanned disc area (weights ``r dr dphi``) where the best
  template's Δχ² exceeds half its peak. Test passes when below ``max_localisation``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .._provenance import json_safe

__all__ = ["Verdict", "detect", "handedness_ratio", "localisation", "mirror_index", "one_sidedness"]

DELTA_BIC_THRESHOLD = 10.0


def mirror_index(result, template: int) -> int | None:
    """Index of the template with the other hand and the same other parameters, if scanned."""
    meta = result.templates[template]
    hand = meta.get("hand")
    if hand not in ("R", "L"):
        return None
    other = {"R": "L", "L": "R"}[hand]
    keys = [k for k in ("mass", "tau0", "beta", "h_p", "flaring", "wavelength") if k in meta]
    for j, m in enumerate(result.templates):
        if m.get("hand") == other and all(_same(m.get(k), meta[k]) for k in keys):
            return j
    return None


def _same(a, b) -> bool:
    """Equal metadata values; unknown ones (None or NaN, e.g. a FARGO3D run's beta) match each other."""
    unknown = [x is None or (isinstance(x, float) and np.isnan(x)) for x in (a, b)]
    return all(unknown) if any(unknown) else bool(a == b)


def handedness_ratio(result, template: int, i_rp: int, i_phi: int, neighbourhood: int = 2,
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


@dataclass
class Verdict:
    """Outcome of :func:`detect`."""

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

    @property
    def r_p_au(self) -> float | None:
        return None if self.distance is None else self.r_p * self.distance

    def to_dict(self) -> dict:
        """The fields as strict-JSON values (NaN, e.g. no mirror template scanned, becomes None)."""
        return json_safe(asdict(self))

    def summary(self) -> str:
        """A sentence or two a user could paste into a paper."""
        where = f"r_p = {self.r_p:.3f} arcsec" + (f" ({self.r_p_au:.0f} au)" if self.distance else "")
        where += f", phi_p = {self.phi_p_deg:.0f} deg"
        head = (f"The best-fitting spiral template ({self.template}) at {where} improves chi^2 by "
                f"{self.delta_chi2:.1f} over the axisymmetric model (Delta BIC = {self.delta_bic:.1f}; "
                f"Delta chi^2 (Delta BIC = 0) = 6 ln N = {self.threshold_6lnN:.1f}).")
        if not self.test1_passed:
            return head + " This is not significant evidence for a planet-driven spiral (Delta BIC <= 10)."
        hand = (f"the mirror-image template's best Delta chi^2 at that radius is {self.handedness_ratio:.2f} "
                f"times the peak, and the peak covers {100 * self.localisation:.1f} % of the scanned area")
        if self.test2_passed:
            return head + f" The peak is compact and handed ({hand}): a planet-driven spiral is detected."
        return head + (f" However {hand}, so the improvement is not attributed to a planet-driven spiral "
                       "(e.g. an arc or a geometry error).")


def detect(result, amplitude=None, *, neighbourhood: int = 2, max_handedness_ratio: float = 0.5,
           max_localisation: float = 0.1, bic_threshold_value: float = DELTA_BIC_THRESHOLD) -> Verdict:
    """Decide whether a scan detects a planet-driven spiral (tests 1 and 2 of the paper)."""
    best = result.best(amplitude=amplitude)
    t = best["template_index"]
    ratio = handedness_ratio(result, t, best["i_rp"], best["i_phi"], neighbourhood, amplitude)
    loc = localisation(result, t, amplitude)
    test1 = best["delta_bic"] > bic_threshold_value
    test2 = bool(np.isfinite(ratio) and ratio < max_handedness_ratio and loc < max_localisation)
    return Verdict(
        detected=bool(test1 and test2), delta_bic=best["delta_bic"], test1_passed=bool(test1),
        handedness_ratio=ratio, localisation=loc, test2_passed=test2, template=best["template"],
        r_p=best["r_p"], phi_p_deg=float(np.degrees(best["phi_p"])), delta_chi2=best["delta_chi2"],
        threshold_6lnN=best["delta_chi2"] - best["delta_bic"], distance=result.distance)
