"""Sanity checks run when visibilities are loaded: units of u, v and statistical weights.

Both guard against results that would be silently wrong, and both decide from the data:

* :func:`check_uv_units` — u, v in metres read as wavelengths make every baseline ~1000 times too
  short. Antennas are at least ~6 m across, so no real baseline is shorter than a few metres,
  and no (sub)mm interferometer has baselines beyond a few tens of km. If u, v taken as
  wavelengths would mean baselines shorter than :data:`MIN_BASELINE_M` (at the known
  wavelength, or at 1 cm when it is unknown) while as metres they lie in the physical range,
  the file is clearly in metres: :class:`~spiralbayes.exceptions.InputError` with the fix.
  When only the wavelength could tell (it is unknown and the numbers fit both), a
  :class:`~spiralbayes.exceptions.DataWarning` says so.
* :func:`check_weights` — weights are ``1/σ²`` of Re V and Im V. The factor ``f`` by which they
  should be multiplied is measured from the scatter of each visibility about the plane through
  its three nearest uv neighbours (:func:`~spiralbayes.visibilities.neighbour_weight_factor`,
  which needs no model and no geometry). Structure can only add scatter (bias ``f`` low), so a
  large ``f`` (weights too small, e.g. CASA's simobserve writing WEIGHT = SIGMA = 1, or uvplot's
  halved weights) is a reliable finding; a small one is reported with that caveat. Weights that
  are all exactly 1 or 2 (CASA's values when none were set) are reported too.
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass

import numpy as np

from ..exceptions import DataWarning, InputError
from ..visibilities import Visibilities, neighbour_weight_factor

__all__ = ["MAX_BASELINE_M", "MIN_BASELINE_M", "WeightCheck", "check_uv_units", "check_weights"]

log = logging.getLogger("spiralbayes.io")

MIN_BASELINE_M = 3.0
"""Shortest plausible projected baseline [m] (half the smallest ALMA dish; shadowed data are flagged)."""
MAX_BASELINE_M = 5e4
"""Longest plausible baseline [m] of a (sub)mm interferometer (ALMA: 16 km, VLA: 36 km)."""
LONGEST_WAVELENGTH_M = 1e-2
"""Longest observing wavelength assumed when the file does not state it [m] (ALMA band 1: 8.6 mm)."""
SHORTEST_WAVELENGTH_M = 3e-4
"""Shortest observing wavelength assumed when the file does not state it [m] (ALMA band 10: 0.35 mm)."""
WEIGHT_FACTOR_LIMITS = (1.0 / 3.0, 1.5)
"""Weights are reported when the scatter says they should be multiplied by a factor outside this range."""


def check_uv_units(u, v, wavelength=None, source: str = "data", *, warn_ambiguous: bool = True) -> None:
    """Refuse u, v that are clearly metres, and warn when only the wavelength could tell.

    Parameters
    ----------
    u, v : array_like
        Baselines as read, believed to be in wavelengths.
    wavelength : float or array_like, optional
        Observing wavelength [m], when known (the mean is used for one per row).
    source : str
        The file, for the messages.
    warn_ambiguous : bool
        Warn when only the wavelength could tell (False when the user stated the units).

    Raises
    ------
    InputError
        u, v taken as wavelengths would need baselines shorter than any antenna, while as
        metres they are plausible baselines.
    """
    q = np.hypot(np.asarray(u, dtype=float), np.asarray(v, dtype=float))
    q = q[np.isfinite(q) & (q > 0)]
    if q.size == 0:
        return
    q_lo, q_hi = float(np.quantile(q, 0.01)), float(q.max())
    as_metres = q_lo >= MIN_BASELINE_M / 3 and q_hi <= MAX_BASELINE_M
    known = wavelength is not None and np.all(np.isfinite(wavelength))
    if known:
        wle = float(np.mean(wavelength))
        as_wavelengths = q_lo * wle >= MIN_BASELINE_M and q_hi * wle <= MAX_BASELINE_M
    else:  # some (sub)mm wavelength must make both the shortest and the longest baselines physical
        wle = LONGEST_WAVELENGTH_M
        shortest_ok, longest_ok = MIN_BASELINE_M / q_lo, MAX_BASELINE_M / q_hi  # bounds on the wavelength
        as_wavelengths = shortest_ok <= min(longest_ok, LONGEST_WAVELENGTH_M) and longest_ok >= SHORTEST_WAVELENGTH_M
    fix = ("pass uv_units='m' (and wavelength=<metres> if the file does not state it; in a configuration: "
           "[data] uv_units = \"m\")")
    if not as_wavelengths and as_metres:
        at = f"at the wavelength {wle:.4g} m" if known else f"even at a wavelength of {wle:g} m"
        raise InputError(
            f"{source}: u, v look like metres, not wavelengths: {at} the shortest baselines would be "
            f"{q_lo * wle:.3g} m, shorter than any antenna; {fix}")
    if not as_wavelengths:
        warnings.warn(f"{source}: u, v (longest {q_hi:.4g}, 1st percentile {q_lo:.4g}) look neither like "
                      "wavelengths nor like metres of a (sub)mm interferometer; check the file's units",
                      DataWarning, stacklevel=3)
    elif as_metres and not known and warn_ambiguous:
        warnings.warn(
            f"{source}: the longest baseline is only {q_hi:.4g} wavelengths, which could also be metres, and "
            "the file states no wavelength; if u, v are in metres, " + fix + "; if they are wavelengths, "
            "pass uv_units='lambda' to say so", DataWarning, stacklevel=3)


@dataclass(frozen=True)
class WeightCheck:
    """Outcome of :func:`check_weights`.

    Attributes
    ----------
    factor : float
        The weights should be multiplied by about this, judging by the scatter
        (:func:`~spiralbayes.visibilities.neighbour_weight_factor`; NaN if too few data).
    all_equal : bool
        Every weight has the same value.
    suspicious : bool
        A warning was (or would be) issued.
    message : str
        The warning's text ('' when none).
    """

    factor: float
    all_equal: bool
    suspicious: bool
    message: str


def check_weights(vis: Visibilities, source: str = "data", *, warn: bool = True) -> WeightCheck:
    """Warn (:class:`~spiralbayes.exceptions.DataWarning`) when the weights do not look statistical.

    Two findings are reported: a scatter factor
    (:func:`~spiralbayes.visibilities.neighbour_weight_factor`) outside
    :data:`.WEIGHT_FACTOR_LIMITS`, and weights all exactly 1 or 2 (the values CASA leaves when
    weights were never set: simobserve writes WEIGHT = SIGMA = 1 per polarisation, and Stokes I
    sums the two) unless the scatter confirms them. The fix is in the message: re-estimate them
    (:func:`~spiralbayes.visibilities.estimate_weights` with the disc geometry; ``[data]
    estimate_weights = true`` in a configuration), or pass ``weight_factor``.

    Parameters
    ----------
    vis : Visibilities
    source : str
        Where the data came from, for the message.
    warn : bool
        Issue the warning (else only return the finding).
    """
    try:
        factor = neighbour_weight_factor(vis).factor
    except InputError:  # too few visibilities to judge
        factor = float("nan")
    all_equal = bool(np.all(vis.weights == vis.weights[0]))
    default_value = all_equal and float(vis.weights[0]) in (1.0, 2.0)
    low, high = WEIGHT_FACTOR_LIMITS
    findings = []
    if np.isfinite(factor) and factor > high:
        findings.append(f"the scatter between neighbouring visibilities is {1 / np.sqrt(factor):.3g} times the noise "
                        f"the weights claim (the weights look {factor:.3g} times too small)")
    elif np.isfinite(factor) and factor < low:
        findings.append(f"the scatter between neighbouring visibilities is {1 / np.sqrt(factor):.3g} times the noise "
                        f"the weights claim (weights {1 / factor:.3g} times too large, or structure on the scale "
                        "of the uv spacing)")
    confirmed = np.isfinite(factor) and low <= factor <= high
    if default_value and not confirmed:  # CASA's defaults, and the scatter does not vouch for them
        findings.append(f"every weight is exactly {vis.weights[0]:g}, CASA's value when weights were never set "
                        "(e.g. by simobserve)")
    message = ""
    if findings:
        message = (f"{source}: the weights do not look like 1/sigma^2 — " + "; ".join(findings) + ". Chi^2, "
                   "Delta chi^2 and Delta BIC scale with the weights and would be wrong: re-estimate them with "
                   "estimate_weights(vis, method='neighbours') ([data] estimate_weights = true in a configuration) "
                   "or pass weight_factor")
        if warn:
            warnings.warn(message, DataWarning, stacklevel=3)
    else:
        log.debug("%s: weights consistent with the scatter (factor %.3g)", source, factor)
    return WeightCheck(factor, all_equal, bool(findings), message)
