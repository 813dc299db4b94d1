"""The planet's mass as a range: every template that explains the best instance nearly as well.

No template is the true spiral, and templates of other morphology variants and H/r explain a real
spiral almost as well as the best one, so its single label would claim more than the data say
(docs/verdict.md). The range covers every template of the best one's hand whose best Δχ² near the
best instance is within ``band`` (ΔBIC 10 by default) of it; in M_Jup each template's mass uses its
own ``h_p`` (``M_th = h_p³ M_*``, Stevenson et al. 2024 eq. 1).
"""

from __future__ import annotations

import numpy as np

from ...exceptions import InputError
from ...templates.template import metadata_variant
from ...units import M_JUP, M_SUN
from .settings import MASS_BAND, DetectionSettings

__all__ = ["mass_range"]


def mass_range(result, amplitude=None, *, band: float = MASS_BAND, window: tuple = (2, 3),
               mstar: float = DetectionSettings.mstar) -> dict | None:
    """Planet masses of every template that explains the best instance nearly as well as the best one.

    A template belongs to the range when it has the best template's hand and its largest Δχ² within
    ``window`` = (radius, azimuth) grid steps of the best instance is at least the best Δχ² minus
    ``band`` (all templates have the same number of parameters, so this is a ΔBIC band).

    Parameters
    ----------
    result : ScanResult
    amplitude : None or "free"
    band : float
        Width of the ΔBIC band.
    window : (int, int)
        Half-widths of the neighbourhood in radius and azimuth steps (azimuth periodic): templates
        of other morphologies peak a step or two apart at the same planet.
    mstar : float
        Stellar mass [M_sun] for Jupiter masses.

    Returns
    -------
    dict or None
        ``mth`` [min, max] M_p/M_th; ``mjup`` [min, max] M_Jup (each template's own ``h_p``; None when
        no member has one); ``band``, ``mstar``; ``members``: name, mass, h_p, variant and ΔBIC below
        the best of each member. None when the best template has no mass.
    """
    if not np.isfinite(band) or band < 0:
        raise InputError(f"mass band must be a non-negative ΔBIC, got {band!r}")
    dchi2 = result.delta_chi2(amplitude)
    best = result.peak(amplitude=amplitude)
    meta = result.templates[best.template_index]
    if meta.get("mass") is None:
        return None
    n_phi = len(result.phi_p)
    rows = slice(max(best.i_rp - window[0], 0), best.i_rp + window[0] + 1)
    cols = [(best.i_phi + d) % n_phi for d in range(-window[1], window[1] + 1)]
    members = []
    for t, m in enumerate(result.templates):
        if m.get("mass") is None or m.get("hand") != meta.get("hand"):
            continue
        local = np.nanmax(dchi2[t, rows][:, cols])
        if local >= best.delta_chi2 - band:
            h_p = m.get("h_p")
            mjup = (float(m["mass"]) * float(h_p) ** 3 * mstar * M_SUN / M_JUP
                    if h_p is not None and np.isfinite(h_p) else None)
            members.append({"template": m["name"], "mass": float(m["mass"]), "h_p": h_p,
                            "variant": metadata_variant(m),
                            "mjup": mjup, "below_best": float(best.delta_chi2 - local)})
    masses = [x["mass"] for x in members]
    mjups = [x["mjup"] for x in members if x["mjup"] is not None]
    return {"mth": [min(masses), max(masses)], "mjup": [min(mjups), max(mjups)] if mjups else None,
            "band": float(band), "mstar": float(mstar),
            "variants": sorted({str(x["variant"] or "compromise") for x in members}),
            "h_ps": sorted({float(x["h_p"]) for x in members if x["h_p"] is not None}),
            "members": sorted(members, key=lambda x: x["below_best"])}
