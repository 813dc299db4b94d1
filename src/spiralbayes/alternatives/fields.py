"""Non-spiral brightness perturbations on top of the axisymmetric profile, with exact Jacobians.

Stevenson et al. (2024, sec. 5) name what besides a planet's spiral can improve on an
axisymmetric fit: arcs and vortices, lopsided or eccentric discs, and geometry errors (the last
is :mod:`spiralbayes.alternatives.geometry_error`). Each model here is a perturbation
``P(r, phi)`` [Jy/sr] of the axisymmetric profile ``I_A(r)`` with a few parameters, evaluated
on a :class:`~spiralbayes.alternatives.grid.DiscGrid`; like the spiral templates (whose ``delta``
has zero azimuthal mean by construction) every field has its mean over azimuth removed on each
ring, because frank's profile already holds the axisymmetric part of the data.

Models (``r`` and radii in arcsec, angles in rad, ``phi`` the disc azimuth of
:mod:`spiralbayes.geometry`; ``W(r) = exp(-(r - r_c)^2 / 2 sigma_r^2)``):

``arc``
    A vortex-like arc (e.g. the dust trap of a Rossby-wave vortex; Birnstiel et al. 2013,
    Marino et al. 2015 model them this way): ``P = A I_A W exp((cos(phi - phi_c) - 1) /
    sigma_phi^2)``, a Gaussian in radius and a von Mises (periodic Gaussian of width
    ``sigma_phi`` <= 1.4 rad) in azimuth; contrast ``A >= 0`` relative to the local ``I_A``.
    Parameters ``(A, r_c, phi_c, sigma_r, sigma_phi)``.
``lopsided``
    An m = 1 brightness modulation with a Gaussian radial profile (a global asymmetry for large
    ``sigma_r``): ``P = I_A W (a_c cos phi + a_s sin phi)``, brightest at
    ``phi_0 = atan2(a_s, a_c)``. Parameters ``(a_c, a_s, r_c, sigma_r)``.
``eccentric_ring``
    The profile near ``r_c`` laid on Keplerian ellipses of eccentricity ``e W(r)`` with the
    star at a focus and pericentre at azimuth ``omega``: the brightness at ``(r, phi)`` is that
    of the circular profile at the semi-major axis ``a = r (1 + e W cos(phi - omega)) /
    (1 - e^2 W^2)`` (from ``r = a (1 - e^2) / (1 + e cos(phi - omega))``), so a ring is both
    displaced towards apocentre and elongated. ``P = I_A(a) - I_A(r)``; parameters
    ``(e_c, e_s, r_c, sigma_r)`` with ``e_c + i e_s = e exp(i omega)``.
``eccentric_excess``
    A ring of excess (contrast > 0) or missing (< 0) brightness whose centre line is a Keplerian
    ellipse of semi-major axis ``r_c`` and eccentricity ``e`` (star at a focus, pericentre at
    ``omega``) over a circular disc: ``P = C I_A(r) exp(-(a - r_c)^2 / 2 w^2)`` with ``a`` as above
    (``W = 1``). Where ``eccentric_ring`` moves the whole profile near ``r_c`` (an eccentric stretch of
    disc, or a cavity edge), this moves only the ring (a dust ring in a disc that stays circular, as
    eccentric rings are often modelled, e.g. MacGregor et al. 2017 for Fomalhaut). Its circular part,
    which frank's profile holds, is removed with the ring means, so what is fitted is the eccentric
    part, to first order ``-C I_A r e cos(phi - omega) (r - r_c) / w^2`` times the Gaussian.
    Parameters ``(e_c, e_s, r_c, width, contrast)``.
``m2``
    A point-symmetric two-armed pattern, the control: a bar (``kappa = 0``) or a two-armed
    logarithmic spiral not driven by a planet (gravitational instability, flybys), ``P = I_A W
    (c_c cos psi + c_s sin psi)``, ``psi = 2 (phi - kappa ln(r / r_c))`` (pitch angle
    ``atan(1 / |kappa|)``). Parameters ``(c_c, c_s, r_c, sigma_r, kappa)``.

Each model gives ``field(theta)`` and its Jacobian ``d field / d theta`` in closed form
(``tests/alternatives/test_fields.py`` checks them against finite differences), so that the
maximum-likelihood fits (:mod:`spiralbayes.inference.detection.alternatives`) get exact gradients from one
adjoint transform.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import InputError
from ..units import wrap_angle
from .grid import DiscGrid, remove_ring_mean

__all__ = ["ArcModel", "EccentricExcessModel", "EccentricRingModel", "FIELD_MODELS", "FieldModel", "LopsidedModel",
           "M2Model", "ProfileContext"]

PROFILE_TABLE_POINTS = 6000
SIGMA_PHI_MAX = 1.4
"""Widest arc [rad] (FWHM 190 deg, about the widest vortex arcs seen); wider ones are lopsided discs."""


@dataclass
class ProfileContext:
    """The axisymmetric profile where the fields need it.

    Attributes
    ----------
    grid : DiscGrid
    I_ring : ndarray
        ``I_A`` at the ring mid-radii [Jy/sr].
    r_table, I_table : ndarray
        ``I_A`` on a fine table out to ``2 grid.r_max`` [arcsec, Jy/sr] (for the eccentric remap).
    """

    grid: DiscGrid
    I_ring: np.ndarray
    r_table: np.ndarray
    I_table: np.ndarray

    @classmethod
    def build(cls, profile, grid: DiscGrid) -> ProfileContext:
        """From a brightness callable ``I_A(r [arcsec]) -> Jy/sr``."""
        r_table = np.linspace(0.0, 2.0 * grid.r_max, PROFILE_TABLE_POINTS)
        I_table = np.asarray(profile(r_table), dtype=float)
        I_ring = np.asarray(profile(grid.r), dtype=float)
        if not (np.all(np.isfinite(I_table)) and np.all(np.isfinite(I_ring))):
            raise InputError("the axisymmetric profile has NaN/inf values inside the asymmetry grid")
        return cls(grid, I_ring, r_table, I_table)

    def interpolate(self, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``I_A(r)`` and ``dI_A/dr`` by piecewise-cubic Hermite interpolation of the table."""
        h = self.r_table[1] - self.r_table[0]
        slope = np.gradient(self.I_table, h)
        s = np.clip(r / h, 0.0, self.r_table.size - 1 - 1e-9)
        k = np.floor(s).astype(np.int64)
        t = s - k
        y0, y1 = self.I_table[k], self.I_table[k + 1]
        m0, m1 = slope[k] * h, slope[k + 1] * h
        t2, t3 = t * t, t * t * t
        value = (2 * t3 - 3 * t2 + 1) * y0 + (t3 - 2 * t2 + t) * m0 + (-2 * t3 + 3 * t2) * y1 + (t3 - t2) * m1
        deriv = ((6 * t2 - 6 * t) * y0 + (3 * t2 - 4 * t + 1) * m0 + (-6 * t2 + 6 * t) * y1
                 + (3 * t2 - 2 * t) * m1) / h
        outside = r >= self.r_table[-1]
        return np.where(outside, 0.0, value), np.where(outside, 0.0, deriv)


def _window(r, r_c, sigma_r):
    return np.exp(-0.5 * ((r - r_c) / sigma_r) ** 2)


class FieldModel:
    """Base class: a named perturbation with parameters ``theta`` (see the module docstring)."""

    name = ""
    label = ""
    param_names: tuple = ()
    amplitude_indices: tuple = ()
    """Parameters on which the field depends (nearly) linearly; zero means no perturbation."""

    @property
    def n_params(self) -> int:
        return len(self.param_names)

    def raw(self, theta, ctx: ProfileContext) -> tuple[np.ndarray, np.ndarray]:
        """The field before the ring means are removed, and its Jacobian (n_params, n_r, n_phi)."""
        raise NotImplementedError

    def field(self, theta, ctx: ProfileContext) -> np.ndarray:
        """``P`` [Jy/sr] on ``ctx.grid``, ring means removed."""
        return remove_ring_mean(self.raw(theta, ctx)[0])

    def field_and_jacobian(self, theta, ctx: ProfileContext) -> tuple[np.ndarray, np.ndarray]:
        """``P`` and ``dP / d theta`` (shape (n_params, n_r, n_phi)), ring means removed from both."""
        P, J = self.raw(theta, ctx)
        return remove_ring_mean(P), remove_ring_mean(J)

    def bounds(self, ctx: ProfileContext, theta0=None) -> list[tuple[float, float]]:
        raise NotImplementedError

    def canonical(self, theta) -> np.ndarray:
        """The same field with angles wrapped to their principal ranges."""
        return np.asarray(theta, dtype=float)

    def describe(self, theta) -> dict:
        """Named physical values: radii [arcsec], angles [deg], amplitudes (dimensionless)."""
        return dict(zip(self.param_names, (float(x) for x in theta)))


def _ellipse(e_c: float, e_s: float) -> dict:
    """Eccentricity and pericentre azimuth [deg, 0-360] of ``e_c + i e_s = e exp(i omega)``."""
    omega = wrap_angle(np.degrees(np.arctan2(e_s, e_c)), 0.0, 360.0)
    return {"e": float(np.hypot(e_c, e_s)), "omega_deg": float(omega)}


def _radial_bounds(ctx: ProfileContext, outer: float = 2.0):
    g = ctx.grid
    return (2 * g.dr, g.r_max), (2 * g.dr, outer * g.r_max)


class ArcModel(FieldModel):
    name = "arc"
    label = "arc/vortex"
    param_names = ("A", "r_c", "phi_c", "sigma_r", "sigma_phi")
    amplitude_indices = (0,)

    def raw(self, theta, ctx):
        A, r_c, phi_c, s_r, s_phi = theta
        g, r = ctx.grid, ctx.grid.r
        radial = ctx.I_ring * _window(r, r_c, s_r)
        cos_d = np.cos(g.phi - phi_c)
        azim = np.exp((cos_d - 1) / s_phi ** 2)
        shape = radial[:, None] * azim[None, :]
        P = A * shape
        J = np.stack([shape,
                      P * ((r - r_c) / s_r ** 2)[:, None],
                      P * (np.sin(g.phi - phi_c) / s_phi ** 2)[None, :],
                      P * ((r - r_c) ** 2 / s_r ** 3)[:, None],
                      P * (2 * (1 - cos_d) / s_phi ** 3)[None, :]])
        return P, J

    def bounds(self, ctx, theta0=None):
        r_c, s_r = _radial_bounds(ctx, outer=0.5)
        phi0 = 0.0 if theta0 is None else float(theta0[2])
        return [(0.0, 50.0), r_c, (phi0 - 2 * np.pi, phi0 + 2 * np.pi), s_r, (0.05, SIGMA_PHI_MAX)]

    def canonical(self, theta):
        t = np.asarray(theta, dtype=float).copy()
        t[2] = wrap_angle(t[2], 0.0)
        return t

    def describe(self, theta):
        A, r_c, phi_c, s_r, s_phi = self.canonical(theta)
        return {"contrast": float(A), "r_c": float(r_c), "phi_c_deg": float(np.degrees(phi_c)),
                "sigma_r": float(s_r), "sigma_phi_deg": float(np.degrees(s_phi))}


class _CosSinModel(FieldModel):
    """``I_A W (a cos(m psi) + b sin(m psi))`` with the amplitudes first."""

    m = 1

    def _phase(self, theta, r, phi):
        return self.m * phi[None, :] + 0 * r[:, None], None

    def raw(self, theta, ctx):
        a_c, a_s, r_c, s_r = theta[:4]
        g, r = ctx.grid, ctx.grid.r
        radial = ctx.I_ring * _window(r, r_c, s_r)
        psi, dpsi = self._phase(theta, r, g.phi)
        cos_b = radial[:, None] * np.cos(psi)
        sin_b = radial[:, None] * np.sin(psi)
        P = a_c * cos_b + a_s * sin_b
        dP_dpsi = -a_c * sin_b + a_s * cos_b
        d_rc = P * ((r - r_c) / s_r ** 2)[:, None]
        J = [cos_b, sin_b, d_rc, P * ((r - r_c) ** 2 / s_r ** 3)[:, None]]
        if dpsi is not None:
            J[2] = d_rc + dP_dpsi * dpsi["r_c"]
            J.append(dP_dpsi * dpsi["kappa"])
        return P, np.stack(J)


class LopsidedModel(_CosSinModel):
    name = "lopsided"
    label = "m = 1 lopsided disc"
    param_names = ("a_c", "a_s", "r_c", "sigma_r")
    amplitude_indices = (0, 1)
    m = 1

    def bounds(self, ctx, theta0=None):
        r_c, s_r = _radial_bounds(ctx)
        return [(-5.0, 5.0), (-5.0, 5.0), (0.0, ctx.grid.r_max), s_r]

    def describe(self, theta):
        a_c, a_s, r_c, s_r = theta
        return {"amplitude": float(np.hypot(a_c, a_s)),
                "phi_0_deg": float(wrap_angle(np.degrees(np.arctan2(a_s, a_c)), 0.0, 360.0)),
                "r_c": float(r_c), "sigma_r": float(s_r)}


class M2Model(_CosSinModel):
    name = "m2"
    label = "m = 2 bar / two-armed pattern"
    param_names = ("c_c", "c_s", "r_c", "sigma_r", "kappa")
    amplitude_indices = (0, 1)
    m = 2

    def _phase(self, theta, r, phi):
        r_c, kappa = theta[2], theta[4]
        log_r = np.log(r / r_c)
        psi = 2 * (phi[None, :] - kappa * log_r[:, None])
        return psi, {"r_c": np.full((r.size, 1), 2 * kappa / r_c), "kappa": (-2 * log_r)[:, None]}

    def bounds(self, ctx, theta0=None):
        r_c, s_r = _radial_bounds(ctx)
        return [(-5.0, 5.0), (-5.0, 5.0), r_c, s_r, (-4.0, 4.0)]

    def describe(self, theta):
        c_c, c_s, r_c, s_r, kappa = theta
        pitch = 90.0 if kappa == 0 else float(np.degrees(np.arctan(1 / abs(kappa))))
        return {"amplitude": float(np.hypot(c_c, c_s)),
                "phi_0_deg": float(np.degrees(0.5 * np.arctan2(c_s, c_c)) % 180), "r_c": float(r_c),
                "sigma_r": float(s_r), "kappa": float(kappa), "pitch_deg": pitch}


class EccentricRingModel(FieldModel):
    name = "eccentric_ring"
    label = "eccentric ring"
    param_names = ("e_c", "e_s", "r_c", "sigma_r")
    amplitude_indices = (0, 1)
    E_MAX = 0.5

    def raw(self, theta, ctx):
        e_c, e_s, r_c, s_r = theta
        g, r = ctx.grid, ctx.grid.r
        W = _window(r, r_c, s_r)[:, None]
        cos_p, sin_p = np.cos(g.phi)[None, :], np.sin(g.phi)[None, :]
        c = e_c * cos_p + e_s * sin_p
        e2 = e_c ** 2 + e_s ** 2
        D = 1 - W ** 2 * e2
        num = 1 + W * c
        rr = r[:, None]
        a = rr * num / D
        I_a, dI_a = ctx.interpolate(a)
        P = I_a - ctx.I_ring[:, None]
        da_de = [rr * (W * trig * D + num * 2 * W ** 2 * e) / D ** 2 for trig, e in ((cos_p, e_c), (sin_p, e_s))]
        da_dW = rr * (c * D + num * 2 * W * e2) / D ** 2
        dW_drc = W * ((r - r_c) / s_r ** 2)[:, None]
        dW_ds = W * ((r - r_c) ** 2 / s_r ** 3)[:, None]
        J = np.stack([dI_a * da_de[0], dI_a * da_de[1], dI_a * da_dW * dW_drc, dI_a * da_dW * dW_ds])
        return P, J

    def bounds(self, ctx, theta0=None):
        r_c, s_r = _radial_bounds(ctx)
        return [(-self.E_MAX, self.E_MAX), (-self.E_MAX, self.E_MAX), r_c, s_r]

    def describe(self, theta):
        e_c, e_s, r_c, s_r = theta
        return {**_ellipse(e_c, e_s), "r_c": float(r_c), "sigma_r": float(s_r)}


class EccentricExcessModel(FieldModel):
    name = "eccentric_excess"
    label = "eccentric bright ring"
    param_names = ("e_c", "e_s", "r_c", "width", "contrast")
    amplitude_indices = (0, 1)
    E_MAX = EccentricRingModel.E_MAX
    CONTRAST_RANGE = (-1.0, 10.0)
    """A deficit cannot remove more than the disc's brightness; an excess of 10 is a ring in a faint gap."""

    def raw(self, theta, ctx):
        e_c, e_s, r_c, w, C = theta
        g = ctx.grid
        cos_p, sin_p = np.cos(g.phi)[None, :], np.sin(g.phi)[None, :]
        rr = g.r[:, None]
        D = 1 - (e_c ** 2 + e_s ** 2)
        num = 1 + e_c * cos_p + e_s * sin_p
        a = rr * num / D
        u, u0 = (a - r_c) / w ** 2, (rr - r_c) / w ** 2
        ring = ctx.I_ring[:, None] * np.exp(-0.5 * (a - r_c) * u)
        circle = ctx.I_ring[:, None] * np.exp(-0.5 * (rr - r_c) * u0)
        # the circular ring subtracted here would go with the ring means anyway; this way e = 0 gives exactly 0
        P = C * (ring - circle)
        dP_da = -C * ring * u
        J = np.stack([dP_da * rr * (cos_p * D + num * 2 * e_c) / D ** 2,
                      dP_da * rr * (sin_p * D + num * 2 * e_s) / D ** 2,
                      C * (ring * u - circle * u0), C * (ring * (a - r_c) * u - circle * (rr - r_c) * u0) / w,
                      ring - circle])
        return P, J

    def bounds(self, ctx, theta0=None):
        r_c, _ = _radial_bounds(ctx)
        return [(-self.E_MAX, self.E_MAX), (-self.E_MAX, self.E_MAX), r_c, (ctx.grid.dr, 0.5 * ctx.grid.r_max),
                self.CONTRAST_RANGE]

    def describe(self, theta):
        e_c, e_s, r_c, w, C = theta
        return {**_ellipse(e_c, e_s), "r_c": float(r_c), "width": float(w), "contrast": float(C)}


FIELD_MODELS = {m.name: m for m in (ArcModel(), LopsidedModel(), EccentricRingModel(), EccentricExcessModel(),
                                    M2Model())}
"""The brightness-perturbation alternatives by name."""
