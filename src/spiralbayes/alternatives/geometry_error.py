"""The geometry-error alternative: the same axisymmetric profile seen under another geometry.

Stevenson et al. (2024, App. A) show that a wrong phase centre gives one-sided false spiral fits
and a wrong inclination or PA two-sided streaks. The alternative model is the axisymmetric
profile ``I_A`` unchanged, seen under ``(inc + d_inc, PA + d_PA, dRA + d_dRA, dDec + d_dDec)``:

    V(u, v) = cos i' · H(q') · exp(2 pi i (u dRA' + v dDec')),

with ``q'`` the baseline deprojected with the new geometry and ``H`` the profile's face-on
Hankel transform (frank's, :meth:`.AxisymmetricModel.visibilities`). ``H`` is tabulated once on a
grid of ``points_per_period`` points per ``1 / r_max`` in ``q`` and interpolated with a cubic
spline (relative error ~1e-7, measured in ``tests/alternatives/test_geometry_error.py``), so one
evaluation at 36k baselines costs about a millisecond; the Jacobian with respect to the four
offsets is analytic (``dq'/d inc = -u_r^2 sin i cos i / q'``, ``dq'/d PA = u_r v_r sin^2 i / q'``
with ``(u_r, v_r)`` the PA-rotated baselines).

Parameters ``theta = (d_inc [deg], d_PA [deg], d_dRA [mas], d_dDec [mas])``, offsets from the
geometry the scan used.
"""

from __future__ import annotations

import numpy as np

from ..exceptions import InputError
from ..geometry import DiscGeometry
from ..units import ARCSEC

__all__ = ["GEOMETRY_PARAMS", "HankelTable", "geometry_visibilities", "offset_geometry"]

GEOMETRY_PARAMS = ("d_inc", "d_PA", "d_dRA", "d_dDec")
MAS = 1e-3  # arcsec


class HankelTable:
    """``H(q)``, the face-on Hankel transform of an axisymmetric model, splined in ``q``.

    Parameters
    ----------
    axisymmetric : object
        Anything with ``visibilities(u, v, geometry)`` (an :class:`~spiralbayes.axisymmetric.model.AxisymmetricModel`).
    q_max : float
        Largest deprojected baseline needed [lambda].
    r_max : float
        Radius [arcsec] beyond which the brightness is negligible (sets the q spacing).
    """

    def __init__(self, axisymmetric, q_max: float, r_max: float, points_per_period: float = 40.0):
        from scipy.interpolate import CubicSpline

        if not (q_max > 0 and r_max > 0):
            raise InputError(f"HankelTable needs q_max > 0 [lambda] and r_max > 0 [arcsec], got {q_max}, {r_max}")
        n = int(np.ceil(q_max * r_max * ARCSEC * points_per_period)) + 16
        self.q = np.linspace(0.0, 1.05 * q_max, n)
        face_on = DiscGeometry()
        self.H = np.asarray(axisymmetric.visibilities(self.q, np.zeros_like(self.q), face_on)).real
        self._spline = CubicSpline(self.q, self.H)
        self._deriv = self._spline.derivative()

    def __call__(self, q) -> np.ndarray:
        return self._spline(q)

    def derivative(self, q) -> np.ndarray:
        return self._deriv(q)


def offset_geometry(geometry: DiscGeometry, theta) -> DiscGeometry:
    """``geometry`` moved by ``theta = (d_inc [deg], d_PA [deg], d_dRA [mas], d_dDec [mas])``."""
    d_inc, d_pa, d_ra, d_dec = (float(x) for x in theta)
    return DiscGeometry(geometry.inc + d_inc, geometry.PA + d_pa, geometry.dRA + d_ra * MAS,
                        geometry.dDec + d_dec * MAS)


def geometry_visibilities(table: HankelTable, u, v, geometry: DiscGeometry, jacobian: bool = False):
    """Axisymmetric visibilities [Jy] under ``geometry``; with ``jacobian``, also their derivatives.

    Returns ``V`` or ``(V, dV)`` with ``dV`` of shape (4, n) holding ``dV/d inc`` [Jy/deg],
    ``dV/d PA`` [Jy/deg], ``dV/d dRA`` and ``dV/d dDec`` [Jy/mas].
    """
    u = np.asarray(u, dtype=float)
    v = np.asarray(v, dtype=float)
    ur, vr = geometry.rotate_uv(u, v)
    cos_i = geometry.cos_inc
    sin_i = float(np.sin(np.radians(geometry.inc)))
    q = np.hypot(ur * cos_i, vr)
    H = table(q)
    phase = geometry.phase_factor(u, v)
    V = cos_i * H * phase
    if not jacobian:
        return V
    q_safe = np.where(q > 0, q, 1.0)
    dH = table.derivative(q)
    dq_dinc = -ur ** 2 * sin_i * cos_i / q_safe
    dq_dpa = ur * vr * sin_i ** 2 / q_safe
    deg = np.pi / 180
    dV = np.stack([(-sin_i * H + cos_i * dH * dq_dinc) * phase * deg,
                   cos_i * dH * dq_dpa * phase * deg,
                   V * (2j * np.pi * u * ARCSEC * MAS),
                   V * (2j * np.pi * v * ARCSEC * MAS)])
    return V, dV
