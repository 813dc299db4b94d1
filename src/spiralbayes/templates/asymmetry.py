"""Competing explanations as templates: an arc/vortex and an eccentric ring for the posterior odds.

The posterior weighs a planet against the structures that explain the same compact peak
(docs/verdict.md, "Candidates"). Each competing explanation is written as a family of templates
on the same footing as a planet's spiral, ``I_S = I_A + A p(r) δ(r / r_c, φ − φ_c)``, so that the
scan, the profile-marginalised likelihood, the sampler and the evidence treat it exactly as they
treat a planet (:mod:`spiralbayes.inference.posterior`): ``r_p`` plays ``r_c``, ``φ_p`` the arc's
centre or the ring's pericentre, and the amplitude ``A`` (uniform on ``[0, amplitude_max]``) the
contrast or the eccentricity. Each family's shape parameters form a small grid whose members share
the family's prior probability.

``arc``
    The arc/vortex of :class:`~spiralbayes.alternatives.fields.ArcModel` (a Gaussian in radius, a
    von Mises in azimuth, its ring mean removed) with the width in radius a fraction of ``r_c``:
    ``δ = c_ref W(x) [exp((cos φ − 1) / σ_φ²) − mean]``, ``W = exp(−(x − 1)² / 2 s²)``, with
    ``p = I_A``; contrast ``A c_ref`` (``c_ref`` = :data:`ARC_CONTRAST`).
``eccentric_ring``
    :class:`~spiralbayes.alternatives.fields.EccentricRingModel` to first order in the eccentricity:
    the profile laid on ellipses ``a = r (1 + e W cos(φ − ω))`` changes the brightness by
    ``I_A(a) − I_A(r) ≈ e W r (dI_A/dr) cos(φ − ω)``, so ``p = r dI_A/dr`` (:class:`RingProfile`) and
    ``δ = e_ref W(x) cos φ``; eccentricity ``A e_ref`` (``e_ref`` = :data:`RING_ECCENTRICITY`). The
    neglected second-order term is ``(e W r)² I_A'' cos² / 2``, a fraction ``~ e r / 2ℓ`` of the first
    for a profile that varies on a scale ``ℓ``: 9 % at ``e = 0.02`` for a ring 0.05 arcsec wide at
    0.45 arcsec (``tests/templates/test_asymmetry.py``), so the family stands for mildly eccentric
    rings (a strongly eccentric narrow ring is test 3's exact model's, not the posterior's).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..exceptions import InputError
from .template import SpiralTemplate

__all__ = ["ARC_CONTRAST", "ARC_SIGMA_PHI_DEG", "ARC_WIDTHS", "ASYMMETRY_KINDS", "RING_ECCENTRICITY", "RING_WIDTHS",
           "RingProfile", "arc_template", "asymmetry_kind", "asymmetry_templates", "perturbation_profile",
           "ring_template"]

ASYMMETRY_KINDS = {"arc": "arc/vortex", "eccentric_ring": "eccentric ring"}
"""The competing explanations the posterior can weigh against a planet, and their names in words."""
ARC_CONTRAST = 0.5
"""Arc contrast at amplitude 1: with ``amplitude_max`` 2 the prior spans contrasts 0-1 (the disc's brightness)."""
ARC_WIDTHS = (0.04, 0.1)
"""Radial widths σ_r / r_c of the arc family (a planet's near-planet peak is ~H/r ≈ 0.05-0.1 of r_p wide)."""
ARC_SIGMA_PHI_DEG = (8.0, 20.0, 45.0)
"""Azimuthal widths σ_φ [deg] of the arc family (compact peaks to wide vortices, FWHM ~110°)."""
RING_ECCENTRICITY = 0.05
"""Eccentricity at amplitude 1: with ``amplitude_max`` 2 the prior spans e = 0-0.1."""
RING_WIDTHS = (0.1, 0.3)
"""Radial widths σ_r / r_c of the eccentric part of the ring family."""
N_X, N_PHI = 161, 512


def _grid(width: float) -> tuple[np.ndarray, np.ndarray]:
    x = np.geomspace(max(1.0 - 6.0 * width, 0.05), 1.0 + 6.0 * width, N_X)
    phi = -np.pi + 2 * np.pi * np.arange(N_PHI) / N_PHI
    return x, phi


def _check_width(name: str, value: float, upper: float) -> float:
    value = float(value)
    if not (np.isfinite(value) and 0 < value <= upper):
        raise InputError(f"{name} = {value!r} must lie in (0, {upper:g}]")
    return value


def arc_template(width: float, sigma_phi_deg: float, *, contrast: float = ARC_CONTRAST,
                 wavelength: float = 0.87e-3) -> SpiralTemplate:
    """One member of the arc family (module docs): radial width ``width`` = σ_r / r_c, azimuthal width
    ``sigma_phi_deg`` [deg], contrast ``contrast`` at amplitude 1; wavelength [m] for the metadata."""
    width = _check_width("width", width, 0.5)
    s_phi = np.radians(_check_width("sigma_phi_deg", sigma_phi_deg, 80.0))
    x, phi = _grid(width)
    azim = np.exp((np.cos(phi) - 1) / s_phi ** 2)
    radial = np.exp(-0.5 * ((x - 1) / width) ** 2)
    delta = contrast * radial[:, None] * (azim - azim.mean())[None, :]
    name = f"arc_w{width:g}_s{sigma_phi_deg:g}deg"
    return SpiralTemplate(x, phi, delta, wavelength=wavelength, name=name, provenance={
        "asymmetry": "arc", "sigma_r_over_r": width, "sigma_phi_deg": float(sigma_phi_deg),
        "contrast_per_amplitude": float(contrast), "profile": "brightness"})


def ring_template(width: float, *, eccentricity: float = RING_ECCENTRICITY,
                  wavelength: float = 0.87e-3) -> SpiralTemplate:
    """One member of the eccentric-ring family (module docs): the eccentricity's radial window
    ``width`` = σ_r / r_c, eccentricity ``eccentricity`` at amplitude 1. Its perturbation profile is
    :class:`RingProfile`, not the brightness (:func:`perturbation_profile`)."""
    width = _check_width("width", width, 2.0)
    x, phi = _grid(width)
    delta = eccentricity * np.exp(-0.5 * ((x - 1) / width) ** 2)[:, None] * np.cos(phi)[None, :]
    return SpiralTemplate(x, phi, delta, wavelength=wavelength, name=f"ring_w{width:g}", provenance={
        "asymmetry": "eccentric_ring", "sigma_r_over_r": width, "e_per_amplitude": float(eccentricity),
        "profile": "r dI/dr"})


def asymmetry_templates(kind: str, wavelength: float = 0.87e-3) -> list[SpiralTemplate]:
    """The family of one competing explanation (:data:`ASYMMETRY_KINDS`) on its default shape grid."""
    if kind == "arc":
        return [arc_template(w, s, wavelength=wavelength) for w in ARC_WIDTHS for s in ARC_SIGMA_PHI_DEG]
    if kind == "eccentric_ring":
        return [ring_template(w, wavelength=wavelength) for w in RING_WIDTHS]
    raise InputError(f"unknown competing explanation {kind!r}: choose from {', '.join(map(repr, ASYMMETRY_KINDS))}")


def asymmetry_kind(template) -> str | None:
    """The competing explanation a template (or its metadata) stands for, None for a planet's spiral."""
    if isinstance(template, Mapping):
        kind = template.get("kind")
    else:
        kind = (getattr(template, "provenance", None) or {}).get("asymmetry")
    return str(kind) if kind in ASYMMETRY_KINDS else None


class RingProfile:
    """``r dI_A/dr`` [Jy/sr] of an axisymmetric model: the eccentric ring's perturbation profile.

    The derivative is a central difference of the model's band-limited series (step
    ``STEP`` arcsec; relative error ~1e-7 for profiles varying on 0.01 arcsec), zero from
    ``Rmax`` on like the model's brightness, whose jump there is left out.
    """

    STEP = 1e-5

    def __init__(self, model):
        self.model = model
        self.Rmax = float(model.Rmax)

    def brightness(self, r) -> np.ndarray:
        """``r dI/dr`` at disc radii ``r`` [arcsec]."""
        r = np.asarray(r, dtype=float)
        h = self.STEP
        up = self.model.brightness(r + h, truncate=False)
        down = self.model.brightness(np.abs(r - h), truncate=False)
        out = r * (up - down) / (2 * h)
        return np.where(r < self.Rmax, out, 0.0)


def perturbation_profile(template, model):
    """The radial profile ``p(r)`` [Jy/sr] that multiplies ``template``'s δ: ``model.brightness`` for a
    planet's spiral and an arc, :class:`RingProfile` for the eccentric ring."""
    if (getattr(template, "provenance", None) or {}).get("profile") == "r dI/dr":
        return RingProfile(model).brightness
    return model.brightness
