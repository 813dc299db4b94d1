"""Physical constants and planet mass units: thermal mass, Jupiter and Neptune masses.

Every physical constant of the package is defined here, once.

The spiral templates are labelled by the planet mass in units of the *thermal mass*
(Stevenson et al. 2024; Speedie, Booth & Dong 2022):

.. math:: M_{\\rm th}(r_p) = (H/r)_p^3\\, M_*,

with a flared disc ``H/r = h_ref (r / r_ref)**flaring``. For the paper's flaring index 1/4,
``M_th ∝ r_p^{3/4}``. Note that Goodman & Rafikov (2001) and wakeflow use
``M_1 = (2/3) h_p^3 M_*`` instead; :func:`thermal_mass` follows the S22/Stevenson convention.

Check against the paper (Stevenson et al. 2024, sec. 2.3): at 50 au with ``h = 0.07`` and
``M_* = 0.8 M_sun``, ``M_th = 0.287 M_Jup``, so 0.1 M_th ≈ 0.5 M_Nep and 3 M_th ≈ 0.9 M_Jup.

Radii are in au unless ``distance`` [pc] is given, in which case they are in arcsec
(``r[au] = r[arcsec] * distance[pc]``).
"""

from __future__ import annotations

import numpy as np
from astropy import units as _u
from astropy.constants import codata2018 as _codata
from astropy.constants import iau2015 as _iau

from .exceptions import InputError

__all__ = [
    "ARCSEC",
    "TWO_PI",
    "wrap_angle",
    "C_LIGHT",
    "H_PLANCK",
    "K_BOLTZMANN",
    "G_NEWTON",
    "M_HYDROGEN",
    "JY",
    "M_SUN",
    "M_JUP",
    "M_NEP",
    "M_EARTH",
    "AU",
    "MASS_UNITS",
    "aspect_ratio",
    "arcsec_to_au",
    "thermal_mass",
    "mth_to_mass",
    "mass_to_mth",
    "mth_to_mjup",
    "mth_to_mnep",
]

# The constants come from astropy, pinned to CODATA 2018 and the IAU 2015 resolution B3 so that a
# user's astropy science state cannot change the package's numbers (cached banks, data hashes).
ARCSEC = float(_u.arcsec.to(_u.rad))
"""One arcsecond [rad]."""
TWO_PI = 2.0 * np.pi

C_LIGHT = float(_codata.c.value)
"""Speed of light [m/s] (SI, exact)."""
H_PLANCK = float(_codata.h.value)
"""Planck constant [J s] (SI 2019, exact)."""
K_BOLTZMANN = float(_codata.k_B.value)
"""Boltzmann constant [J/K] (SI 2019, exact)."""
G_NEWTON = float(_codata.G.value)
"""Gravitational constant [m^3 kg^-1 s^-2] (CODATA 2018)."""
M_HYDROGEN = 1.6735575e-27
"""Mass of a hydrogen atom [kg]: the standard atomic weight 1.00784 u (not in astropy.constants)."""
JY = float(_u.Jy.to(_u.W / _u.m**2 / _u.Hz))
"""One jansky [W m^-2 Hz^-1]."""

M_SUN = float(_iau.M_sun.value)
"""Solar mass [kg] (IAU 2015 nominal GM_sun divided by CODATA 2018 G)."""
M_JUP = float(_iau.M_jup.value)
"""Jupiter mass [kg] (IAU 2015 nominal GM_Jup divided by CODATA 2018 G)."""
M_NEP = 1.02409e26
"""Neptune mass [kg] (NASA Neptune fact sheet; not in astropy.constants)."""
M_EARTH = float(_iau.M_earth.value)
"""Earth mass [kg] (IAU 2015 nominal GM_Earth divided by CODATA 2018 G)."""
AU = float(_iau.au.value)
"""Astronomical unit [m] (IAU 2012)."""

MASS_UNITS = {"Msun": M_SUN, "Mjup": M_JUP, "Mnep": M_NEP, "Mearth": M_EARTH, "kg": 1.0}
"""Mass units accepted by the ``unit`` arguments, in kg (an astropy mass unit, e.g.
``astropy.units.M_jup``, is accepted too)."""


def _unit_kg(unit) -> float:
    if isinstance(unit, _u.UnitBase):
        if unit.physical_type != "mass":
            raise InputError(f"unit {unit} is not a mass unit: use one of {sorted(MASS_UNITS)} or an astropy mass unit")
        return float(unit.to(_u.kg))
    try:
        return MASS_UNITS[unit]
    except (KeyError, TypeError):
        raise InputError(
            f"unknown mass unit {unit!r}: use one of {sorted(MASS_UNITS)} or an astropy mass unit"
        ) from None


def _positive(name: str, value) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise InputError(f"{name} must be positive and finite, got {value!r}")
    return arr


def arcsec_to_au(r_arcsec, distance: float):
    """Convert an angular radius [arcsec] to au at ``distance`` [pc]."""
    _positive("distance", distance)
    return np.asarray(r_arcsec, dtype=float) * float(distance)


def _radius_au(r, distance):
    r = _positive("r_p", r)
    return r if distance is None else arcsec_to_au(r, distance)


def aspect_ratio(r, h_ref: float = 0.07, r_ref: float = 50.0, flaring: float = 0.25, distance=None):
    """Disc aspect ratio ``H/r = h_ref (r/r_ref)**flaring``.

    Parameters
    ----------
    r : float or array
        Radius [au], or [arcsec] if ``distance`` is given.
    h_ref : float
        ``H/r`` at ``r_ref``.
    r_ref : float
        Reference radius [au] (always au).
    flaring : float
        Flaring index (``H/r ∝ r**flaring``); 1/4 in Stevenson et al. (2024).
    distance : float, optional
        Distance [pc]; when given, ``r`` is in arcsec.
    """
    _positive("h_ref", h_ref)
    _positive("r_ref", r_ref)
    return h_ref * (_radius_au(r, distance) / r_ref) ** flaring


def thermal_mass(
    r_p,
    mstar: float,
    *,
    h_ref: float = 0.07,
    r_ref: float = 50.0,
    flaring: float = 0.25,
    distance: float | None = None,
    unit: str | _u.UnitBase = "Msun",
):
    """Thermal mass ``M_th = (H/r)_p^3 M_*`` at the planet radius.

    Parameters
    ----------
    r_p : float or array
        Planet radius [au], or [arcsec] if ``distance`` [pc] is given.
    mstar : float
        Stellar mass [M_sun].
    h_ref, r_ref, flaring : float
        Aspect ratio ``h_ref`` at ``r_ref`` [au] and flaring index (see :func:`aspect_ratio`).
    distance : float, optional
        Distance [pc]; when given, ``r_p`` is in arcsec.
    unit : {'Msun', 'Mjup', 'Mnep', 'Mearth', 'kg'} or astropy.units.UnitBase
        Unit of the result (any astropy mass unit, e.g. ``astropy.units.M_jup``).

    Returns
    -------
    float or array
        ``M_th`` in ``unit``; ``∝ r_p**(3 flaring)``.
    """
    _positive("mstar", mstar)
    h = aspect_ratio(r_p, h_ref, r_ref, flaring, distance)
    m = h**3 * mstar * M_SUN / _unit_kg(unit)
    return float(m) if np.ndim(m) == 0 else m


def mth_to_mass(mass_mth, r_p, mstar: float, *, unit: str | _u.UnitBase = "Mjup", **disc) -> float | np.ndarray:
    """Convert a planet mass in thermal masses to ``unit`` at radius ``r_p``.

    ``disc`` takes ``h_ref``, ``r_ref``, ``flaring`` and ``distance`` as in :func:`thermal_mass`.
    """
    mass_mth = np.asarray(mass_mth, dtype=float)
    if np.any(mass_mth < 0) or not np.all(np.isfinite(mass_mth)):
        raise InputError(f"planet mass must be non-negative and finite, got {mass_mth!r}")
    out = mass_mth * thermal_mass(r_p, mstar, unit=unit, **disc)
    return float(out) if np.ndim(out) == 0 else out


def mass_to_mth(mass, r_p, mstar: float, *, unit: str | _u.UnitBase = "Mjup", **disc) -> float | np.ndarray:
    """Convert a planet mass in ``unit`` to thermal masses at radius ``r_p`` (inverse of
    :func:`mth_to_mass`)."""
    mass = np.asarray(mass, dtype=float)
    if np.any(mass < 0) or not np.all(np.isfinite(mass)):
        raise InputError(f"planet mass must be non-negative and finite, got {mass!r}")
    out = mass / thermal_mass(r_p, mstar, unit=unit, **disc)
    return float(out) if np.ndim(out) == 0 else out


def mth_to_mjup(mass_mth, r_p, mstar: float, **disc):
    """Planet mass [M_Jup] of ``mass_mth`` thermal masses at ``r_p`` (see :func:`mth_to_mass`)."""
    return mth_to_mass(mass_mth, r_p, mstar, unit="Mjup", **disc)


def mth_to_mnep(mass_mth, r_p, mstar: float, **disc):
    """Planet mass [M_Nep] of ``mass_mth`` thermal masses at ``r_p`` (see :func:`mth_to_mass`)."""
    return mth_to_mass(mass_mth, r_p, mstar, unit="Mnep", **disc)


def wrap_angle(angle, low=None, period: float = TWO_PI):
    """Angles shifted by whole periods into ``[low, low + period)``.

    The one angle wrap of the package: ``wrap_angle(d)`` is a difference in ``[-pi, pi)``,
    ``wrap_angle(phi, 0.0)`` an azimuth in ``[0, 2 pi)``, ``wrap_angle(phi, mu - np.pi)`` samples
    around their circular mean ``mu``; ``wrap_angle(a, 0.0, 360.0)`` degrees in ``[0, 360)``.

    Parameters
    ----------
    angle : float or array_like
        Angles [rad; or the unit of ``period``].
    low : float or array_like, optional
        Lower end of the output range [same unit], broadcast against ``angle``; default
        ``-period / 2``.
    period : float, optional
        The period [same unit]: ``2 pi`` for radians, ``360`` for degrees.

    Returns
    -------
    numpy.ndarray or numpy.float64
        ``low + (angle - low) mod period``.
    """
    low = -0.5 * period if low is None else low
    return low + np.mod(np.asarray(angle, dtype=float) - low, period)
