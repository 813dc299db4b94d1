"""Non-spiral asymmetries to inject into synthetic discs, and their exact axisymmetric part.

Perturbations ``delta(r [arcsec], phi [rad])`` for :func:`~spiralbayes.simulate.simulate_observation`
(the brightness becomes ``I(r) (1 + delta)``), modelled on what Stevenson et al. (2024, sec. 5)
name as possible impostors of a planet's spiral:

* :func:`vortex_arc` — a crescent of *added* brightness ``B exp(-(r - r_c)^2 / 2 w_r^2 -
  dphi^2 / 2 w_phi^2)`` with ``B = contrast I(r_c)`` (a Gaussian in azimuth, as fits to observed
  vortex candidates use; e.g. Marino et al. 2015, Casassus et al. 2013);
* :func:`lopsided_disc` — ``a cos(phi - phi_0)`` times a Gaussian in radius (or 1);
* :func:`eccentric_ring` — a fractional brightening ``contrast exp(-(a - r_0)^2 / 2 w^2)`` that
  follows a Keplerian ellipse of eccentricity ``e``, pericentre azimuth ``omega`` and semi-major
  axis ``r_0`` with the star at a focus (``a = r (1 + e cos(phi - omega)) / (1 - e^2)``).

:class:`ExactAxisymmetric` is the azimuthal average of such a disc with exact (Hankel)
visibilities: what a perfect frank fit would return, for injection tests without frank's own
errors and cost. It offers the ``brightness`` and ``visibilities`` of an ``AxisymmetricModel``.
"""

from __future__ import annotations

import numpy as np

from ..exceptions import InputError
from ..geometry import DiscGeometry
from ..units import wrap_angle
from .discs import DiscModel, hankel_visibilities

__all__ = ["ExactAxisymmetric", "eccentric_ring", "lopsided_disc", "vortex_arc"]


def vortex_arc(profile, r_c: float, phi_c: float, width_r: float, width_phi: float, contrast: float):
    """``delta`` of an added Gaussian crescent of peak brightness ``contrast * profile(r_c)``.

    Parameters
    ----------
    profile : callable
        The disc's brightness ``I(r [arcsec])`` [Jy/sr] (``DiscModel.profile(wavelength)``).
    r_c, width_r : float
        Radius and radial width (sigma) [arcsec].
    phi_c, width_phi : float
        Azimuth and azimuthal width (sigma) [rad].
    contrast : float
        Peak added brightness relative to the disc's at ``r_c``.
    """
    peak = contrast * float(profile(np.array([r_c]))[0])
    if not peak > 0:
        raise InputError(f"vortex_arc: the disc has no brightness at r_c = {r_c} arcsec to scale the arc by")

    def delta(r, phi):
        added = peak * np.exp(-0.5 * ((r - r_c) / width_r) ** 2 - 0.5 * (wrap_angle(phi - phi_c) / width_phi) ** 2)
        I = np.asarray(profile(r), dtype=float)
        return np.where(I > 0, added / np.where(I > 0, I, 1.0), 0.0)

    return delta


def lopsided_disc(amplitude: float, phi_0: float, r_c: float | None = None, width: float | None = None):
    """``delta = amplitude cos(phi - phi_0)`` [times ``exp(-(r - r_c)^2 / 2 width^2)`` if given]."""

    def delta(r, phi):
        radial = 1.0 if r_c is None else np.exp(-0.5 * ((r - r_c) / width) ** 2)
        return amplitude * radial * np.cos(phi - phi_0)

    return delta


def eccentric_ring(r_0: float, width: float, e: float, omega: float, contrast: float):
    """``delta`` of a ring brightened by ``contrast`` along an ellipse (semi-major axis ``r_0``)."""
    if not 0 <= e < 1:
        raise InputError(f"eccentric_ring: e = {e} must lie in [0, 1)")

    def delta(r, phi):
        a = r * (1 + e * np.cos(phi - omega)) / (1 - e ** 2)
        return contrast * np.exp(-0.5 * ((a - r_0) / width) ** 2)

    return delta


class ExactAxisymmetric:
    """The exact azimuthal average of ``DiscModel x (1 + delta)`` under a given geometry.

    Parameters
    ----------
    disc : DiscModel
    wavelength : float
        [m].
    geometry : DiscGeometry
        The geometry the model is used with (as an ``AxisymmetricModel``'s).
    delta : callable, optional
        The perturbation whose azimuthal mean joins the profile.
    n_r, n_phi : int
        Table resolution of the averaged profile (linearly interpolated).
    """

    def __init__(self, disc: DiscModel, wavelength: float, geometry: DiscGeometry, delta=None, *,
                 n_r: int = 8000, n_phi: int = 1440):
        self.disc, self.wavelength, self.geometry = disc, float(wavelength), geometry
        self.Rmax = 1.1 * disc.r_max
        self.breaks = (disc.r_min, disc.r_max)  # the brightness jumps at the edges (the quadrature splits there)
        self._r = np.linspace(disc.r_min, disc.r_max, n_r)
        mean = np.zeros(n_r)
        if delta is not None:
            phi = 2 * np.pi * np.arange(n_phi) / n_phi
            mean = np.asarray(delta(self._r[:, None], phi[None, :]), dtype=float).mean(axis=1)
        self._I = disc.brightness(self._r, self.wavelength) * (1 + mean)

    def brightness(self, r) -> np.ndarray:
        """Face-on brightness [Jy/sr] at radii ``r`` [arcsec]."""
        r = np.asarray(r, dtype=float)
        inside = (r >= self.disc.r_min) & (r <= self.disc.r_max)
        return np.where(inside, np.interp(r, self._r, self._I), 0.0)

    def visibilities(self, u, v, geometry: DiscGeometry | None = None) -> np.ndarray:
        """Exact visibilities [Jy] (Hankel transform between the disc's edges)."""
        return hankel_visibilities(self.brightness, u, v, geometry or self.geometry, self.disc.r_min, self.disc.r_max)
