"""Disc geometry: inclination, position angle and phase-centre offset.

Conventions (identical to frank's ``frank.geometry``; see ``docs/conventions.md``):

* ``inc`` and ``PA`` in degrees, ``PA`` measured east of north; ``dRA`` and ``dDec``
  in arcsec, ``dRA > 0`` towards the east.
* Visibilities follow ``V(u, v) = sum I(l, m) exp(+2 pi i (u l + v m))`` with ``l`` the RA
  offset (east positive) and ``m`` the Dec offset, so a source displaced by
  ``(dRA, dDec)`` multiplies ``V`` by ``exp(+2 pi i (u dRA + v dDec))``.
* Deprojected baselines: ``u' = (u cos PA - v sin PA) cos i``, ``v' = u sin PA + v cos PA``
  (frank's ``deproject``). In the deprojected disc frame ``x'`` runs along the minor axis
  (east for ``PA = 0``) and ``y'`` along the major axis.
* Disc azimuth ``phi`` (Stevenson et al. 2024, sec. 2.2): in the usual display (north up,
  east left) rotated so that the major axis is vertical, ``phi = 0`` is the right-hand
  arm of the minor axis and ``phi`` increases anticlockwise. In frank's deprojected frame
  that is ``xi = -x'``, ``eta = y'``, ``phi = atan2(eta, xi)``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .exceptions import InputError
from .units import ARCSEC

__all__ = ["ARCSEC", "DiscGeometry", "arcsec_to_rad", "rad_to_arcsec"]



def arcsec_to_rad(x):
    """Convert arcsec to radians."""
    return np.asarray(x) * ARCSEC


def rad_to_arcsec(x):
    """Convert radians to arcsec."""
    return np.asarray(x) / ARCSEC


@dataclass(frozen=True)
class DiscGeometry:
    """Projection of a thin, circular disc onto the sky.

    Parameters
    ----------
    inc : float
        Inclination [deg], in [0, 90). 0 is face on.
    PA : float
        Position angle of the major axis [deg], east of north.
    dRA, dDec : float
        Offset of the disc centre from the phase centre [arcsec]; ``dRA > 0`` is east.
    """

    inc: float = 0.0
    PA: float = 0.0
    dRA: float = 0.0
    dDec: float = 0.0

    def __post_init__(self):
        for name in ("inc", "PA", "dRA", "dDec"):
            value = getattr(self, name)
            if not np.isfinite(value):
                raise InputError(f"DiscGeometry.{name} must be finite, got {value!r}")
            object.__setattr__(self, name, float(value))
        if not 0.0 <= self.inc < 90.0:
            raise InputError(
                f"DiscGeometry.inc = {self.inc} deg is outside [0, 90): give the "
                "inclination in degrees (0 = face on); a disc seen edge on cannot be deprojected"
            )

    @property
    def cos_inc(self) -> float:
        return float(np.cos(np.radians(self.inc)))

    def to_dict(self) -> dict:
        return asdict(self)

    def replace(self, **changes) -> DiscGeometry:
        return DiscGeometry(**{**self.to_dict(), **changes})

    # --- uv plane -------------------------------------------------------------
    def rotate_uv(self, u, v):
        """Rotate baselines by PA into the frame of the unrotated image (no inclination)."""
        pa = np.radians(self.PA)
        c, s = np.cos(pa), np.sin(pa)
        u = np.asarray(u, dtype=float)
        v = np.asarray(v, dtype=float)
        return u * c - v * s, u * s + v * c

    def deproject_uv(self, u, v):
        """Deprojected baselines ``(u', v')`` [lambda], as ``frank.geometry.deproject``."""
        ur, vr = self.rotate_uv(u, v)
        return ur * self.cos_inc, vr

    def reproject_uv(self, up, vp):
        """Inverse of :meth:`deproject_uv`."""
        pa = np.radians(self.PA)
        c, s = np.cos(pa), np.sin(pa)
        ur = np.asarray(up, dtype=float) / self.cos_inc
        vp = np.asarray(vp, dtype=float)
        return ur * c + vp * s, -ur * s + vp * c

    def phase_factor(self, u, v):
        """``exp(+2 pi i (u dRA + v dDec))``: the factor that moves a source to ``(dRA, dDec)``."""
        phase = 2 * np.pi * (np.asarray(u) * self.dRA + np.asarray(v) * self.dDec) * ARCSEC
        return np.exp(1j * phase)

    def phase_shift(self, u, v, V, inverse: bool = False):
        """Move the source by ``(dRA, dDec)`` (or back, with ``inverse``); frank's sign."""
        factor = self.phase_factor(u, v)
        return np.asarray(V) * (np.conj(factor) if inverse else factor)

    def apply_correction(self, u, v, V):
        """Re-centre and deproject visibilities, as ``frank.geometry.SourceGeometry.apply_correction``.

        Returns ``(u', v', V')``; the flux is not rescaled by ``cos i``.
        """
        up, vp = self.deproject_uv(u, v)
        return up, vp, self.phase_shift(u, v, V, inverse=True)

    def disc_frame_uv(self, u, v):
        """Baselines in the disc frame ``(xi, eta)`` used for ``phi``: ``(-u', v')`` [lambda]."""
        up, vp = self.deproject_uv(u, v)
        return -up, vp

    # --- image plane ------------------------------------------------------------
    def disc_to_sky(self, r, phi):
        """Sky offsets ``(l, m)`` [arcsec] of disc-plane points.

        Parameters
        ----------
        r : array_like
            Radius in the disc plane [arcsec].
        phi : array_like
            Disc azimuth [rad] (see the module docstring).
        """
        r = np.asarray(r, dtype=float)
        phi = np.asarray(phi, dtype=float)
        xf = -r * np.cos(phi) * self.cos_inc
        yf = r * np.sin(phi)
        pa = np.radians(self.PA)
        c, s = np.cos(pa), np.sin(pa)
        return self.dRA + xf * c + yf * s, self.dDec - xf * s + yf * c

    def sky_to_disc(self, l, m):
        """Disc-plane ``(r [arcsec], phi [rad])`` of sky offsets ``(l, m)`` [arcsec]."""
        dl = np.asarray(l, dtype=float) - self.dRA
        dm = np.asarray(m, dtype=float) - self.dDec
        pa = np.radians(self.PA)
        c, s = np.cos(pa), np.sin(pa)
        xf = (dl * c - dm * s) / self.cos_inc
        yf = dl * s + dm * c
        return np.hypot(xf, yf), np.arctan2(yf, -xf)
