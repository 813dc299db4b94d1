"""How the limits are computed: :class:`LimitSettings`, the ``[limits]`` section of the configuration."""

from __future__ import annotations

from dataclasses import dataclass

from ...settings import option

__all__ = ["LimitSettings"]


@dataclass(frozen=True)
class LimitSettings:
    """Options of :func:`~spiralbayes.inference.limits.compute_limits`, of
    :func:`~spiralbayes.inference.limits.completeness` (``n_azimuths``, ``inject_hand``) and of the
    Table 3 outputs (TOML section ``[limits]``).

    Every field's description is its ``metadata["doc"]``; ``--print-config`` shows them.
    ``None`` means automatic (written ``0`` in the TOML file).
    """

    cl: float = option(0.95, "one-sided confidence level of the exclusion limits, in (0.5, 1)")
    method: str = option("all_phi", "'all_phi': excluded at r_p when excluded at every phi_p (the paper's reading); "
                                    "'marginal': phi_p marginalised (uniform prior)")
    hand: str = option("both", "'both': a planet is excluded only when both hands are; 'R' or 'L' when the disc's "
                               "rotation fixes the hand")
    mstar: float = option(0.8, "stellar mass [M_sun], for planet masses in M_Jup (M_th = (H/r)^3 M_*)")
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
    n_azimuths: int = option(8, "injection azimuths per radius, evenly spaced on the scan grid")
    inject_hand: tuple = option(("R",), "hands of the injected planets")
    thresholds: tuple = option((3.0, 1.0), "planet masses [M_th] of the table's columns (the paper's Table 3: 3 "
                                           "and 1)")
    name: str = option("", "disc name in the table (empty: the data file's stem)")
    # code only
    bright_radius: float | None = option(None, "outer radius of the disc's bright part [arcsec] (default: the "
                                               "radius holding extent_fraction of the flux)", config=False)
    planet_beam: float | None = option(None, "radius [arcsec] around a known planet flagged 'near_planet' "
                                             "(default: resolution)", config=False)
