"""Posterior odds between a planet and the competing explanations of the same structure.

With ``alternatives=("arc", "eccentric_ring")`` (:func:`~.sampler.sample_posterior`, ``[sample]
alternatives``), each competing explanation is sampled beside the planet as a family of templates
(:mod:`spiralbayes.templates.asymmetry`): its own position and shape, the disc geometry, its
amplitude integrated out exactly and the profile marginalised, its evidence by the same importance
sampling as a planet's (:mod:`.evidence`). Hypotheses and prior weights:

==================  ==================================================  =========================
hypothesis          parameters                                          prior weight
==================  ==================================================  =========================
no asymmetry        geometry                                            ``1 − planet_prior``
planet              each template's (or family's) ``r_p, φ_p, A``       ``planet_prior``
arc/vortex          ``r_c, φ_c``, contrast, shape on a grid             ``planet_prior``
eccentric ring      ``r_c``, pericentre, ``e``, width on a grid         ``planet_prior``
==================  ==================================================  =========================

so a planet and each competing explanation have even prior odds, and the planet's odds against
the disc alone are as without alternatives; within a hypothesis its templates share its weight
equally. ``P(h | data) = w_h Σ_t Z_t / n_h / Σ_h' (...)``. The Monte Carlo error of each
probability propagates every run's ``ln Z`` error to first order,
``σ_P(h)² = Σ_t (w_t Z_t / W)² (1[t ∈ h] − P(h))² σ_ln Z_t²``; a run whose evidence has no error
estimate (Laplace) contributes none.
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from ...exceptions import InputError
from ...templates.asymmetry import ASYMMETRY_KINDS, RingProfile, asymmetry_templates

__all__ = ["NO_ASYMMETRY", "check_alternatives", "hypothesis_weights", "model_probabilities", "scan_alternatives"]

log = logging.getLogger(__name__)

NO_ASYMMETRY = "no asymmetry"
ALT_REFINE = 4
"""The competing explanations are scanned on radii this many times finer than the planet's scan."""
PLANET = "planet"


def check_alternatives(alternatives) -> tuple[str, ...]:
    """``alternatives`` as a tuple of known names (:data:`~spiralbayes.templates.asymmetry.ASYMMETRY_KINDS`)."""
    if alternatives is None:
        return ()
    if isinstance(alternatives, str):
        alternatives = (alternatives,)
    out = tuple(str(a) for a in alternatives)
    unknown = [a for a in out if a not in ASYMMETRY_KINDS]
    if unknown or len(set(out)) != len(out):
        raise InputError(f"alternatives = {list(out)!r}: name each of {', '.join(map(repr, ASYMMETRY_KINDS))} at "
                         "most once")
    return out


def scan_alternatives(vis, axisymmetric, kinds, scan_result, wavelength: float):
    """The competing explanations' templates by kind, and their scan over ``scan_result``'s radii on a grid
    :data:`ALT_REFINE` times finer in radius and at least twice as fine in azimuth (None without a scan):
    the arc with the disc's brightness, the ring with :class:`RingProfile`."""
    from ..scan.run import scan

    templates = {kind: asymmetry_templates(kind, wavelength) for kind in kinds}
    if scan_result is None:
        return templates, None
    geometry = scan_result.geometry
    # the scan-grid evidence of a template whose peak is narrower than a cell is off by several in ln Z; the
    # narrowest arc is ~0.04 r_c wide: four times the planet scan's radii, twice its azimuths
    step = float(np.median(np.diff(scan_result.r_p))) / ALT_REFINE if scan_result.r_p.size > 1 else None
    r_p = (scan_result.r_p if step is None else
           np.arange(scan_result.r_p[0], scan_result.r_p[-1] + 0.5 * step, step))
    n_phi = max(2 * len(scan_result.phi_p), 180)
    parts = []
    for kind, temps in templates.items():
        if kind == "eccentric_ring":
            model = (RingProfile(axisymmetric).brightness, axisymmetric.visibilities(vis.u, vis.v, geometry))
        else:
            model = axisymmetric
        parts.append(scan(vis, model, temps, geometry, r_p=r_p, n_phi_p=n_phi,
                          distance=scan_result.distance, progress=False, allow_other_data=True))
    def stacked(name: str) -> np.ndarray:
        return np.concatenate([getattr(p, name) for p in parts])

    merged = replace(parts[0], templates=[t for p in parts for t in p.templates], cross=stacked("cross"),
                     power=stacked("power"), cross_error=stacked("cross_error"), power_error=stacked("power_error"))
    return templates, merged


def hypothesis_weights(kinds, planet_prior: float) -> dict:
    """Prior weight of each hypothesis (module docs), normalised."""
    w = {NO_ASYMMETRY: 1.0 - planet_prior, PLANET: planet_prior, **{ASYMMETRY_KINDS[k]: planet_prior for k in kinds}}
    total = sum(w.values())
    return {k: v / total for k, v in w.items()}


def model_probabilities(groups: dict, null, weights: dict) -> tuple[dict, dict]:
    """``(P(h | data), its Monte Carlo error)`` for every hypothesis.

    Parameters
    ----------
    groups : dict
        Hypothesis name -> its runs (each with ``ln_evidence`` and ``ln_evidence_err``) and, for the
        planet, the templates' prior within it (``(runs, prior)``; prior None: uniform).
    null : NullRun
    weights : dict
        :func:`hypothesis_weights`.
    """
    terms = [np.log(weights[NO_ASYMMETRY]) + null.ln_evidence]
    err, labels = [null.ln_evidence_err], [NO_ASYMMETRY]
    for h, (runs, prior) in groups.items():
        if not runs:
            continue
        p = np.full(len(runs), 1.0 / len(runs)) if prior is None else np.asarray(prior, float) / np.sum(prior)
        for r, q in zip(runs, p):
            terms.append(np.log(weights[h]) + np.log(q) + r.ln_evidence)
            err.append(r.ln_evidence_err)
            labels.append(h)
    ln_w = np.asarray(terms, float)
    share = np.exp(ln_w - np.max(ln_w))
    share /= share.sum()
    sigma = np.nan_to_num(np.asarray(err, float), nan=0.0)
    labels_arr = np.array(labels)
    probs, errors = {}, {}
    for h in [NO_ASYMMETRY, *groups]:
        inside = labels_arr == h
        p_h = float(share[inside].sum())
        probs[h] = p_h
        errors[h] = float(np.sqrt(np.sum((share * (inside - p_h) * sigma) ** 2)))
    return probs, errors
