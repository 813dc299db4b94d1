"""An independent reference for the spiral perturbation's visibilities ΔV (the exactness suite).

The continuous model is ``I_A(r) delta(ln(r / r_p), phi - phi_p)`` with ``delta`` the template's
bilinear interpolant in ``(ln x, phi)``. Inside every template cell (one radial interval in ``ln x``
times one azimuth interval) that integrand is smooth, so a tensor Gauss-Legendre rule per cell
(``order_r`` x ``order_phi`` nodes) converges spectrally; the cell containing the profile's edge
(frank's ``Rmax``) is split there. Nothing is shared with :mod:`spiralbayes.quadrature` (no
Fourier series in phi, no kernel interpolation): ``delta`` is evaluated at the nodes directly. The
sum over nodes is sent to the baselines by a double-precision type-3 NUFFT at 1e-12, in chunks of
radial intervals; several planet azimuths are served at once by rotating the baselines.

:func:`reference_terms` turns it into ``cross`` and ``power``; call it at two orders to show the
reference converged.
"""

from __future__ import annotations

import numpy as np
from scipy.special import roots_legendre

from spiralbayes.units import ARCSEC

EPSILON = 1e-12


def _radial_pieces(template, r_p: float, support: float | None):
    """``(s_lo, s_hi, t)`` for every radial piece: template interval ``t`` in ``s = ln x``, cut at the
    profile's edge."""
    s_t = np.log(np.asarray(template.x, dtype=float))
    edge = np.inf if support is None else np.log(support / r_p)
    out = []
    for t in range(s_t.size - 1):
        lo, hi = s_t[t], min(s_t[t + 1], edge)
        if hi > lo:
            out.append((lo, hi, t))
    return out


def _chunk_nodes(profile, template, r_p, pieces, order_r, order_phi):
    """Fluxes [Jy] (face on, planet at phi = 0) and positions [rad] of the nodes of ``pieces``."""
    s_t = np.log(np.asarray(template.x, dtype=float))
    delta = np.asarray(template.delta, dtype=float)
    n_t = delta.shape[1]
    dphi = 2 * np.pi / n_t
    gr, wr = roots_legendre(order_r)
    gp, wp = roots_legendre(order_phi)
    lo = np.array([p[0] for p in pieces])
    hi = np.array([p[1] for p in pieces])
    t = np.array([p[2] for p in pieces])
    s = (0.5 * (lo + hi)[:, None] + 0.5 * (hi - lo)[:, None] * gr[None, :]).ravel()
    ws = (0.5 * (hi - lo)[:, None] * wr[None, :]).ravel()
    t = np.repeat(t, order_r)
    f = (s - s_t[t]) / (s_t[t + 1] - s_t[t])
    rows = (1 - f)[:, None] * delta[t] + f[:, None] * delta[t + 1]  # (n_s, n_t): linear in s
    g = 0.5 * (gp + 1.0)  # position inside an azimuth interval
    vals = (1 - g)[None, None, :] * rows[:, :, None] + g[None, None, :] * np.roll(rows, -1, axis=1)[:, :, None]
    phi = (float(template.phi[0]) + dphi * (np.arange(n_t)[:, None] + g[None, :])).ravel()
    x = np.exp(s)
    weight = np.asarray(profile(r_p * x), dtype=float) * x * x * ws * (r_p * ARCSEC) ** 2
    flux = (vals.reshape(s.size, -1) * weight[:, None] * np.tile(0.5 * dphi * wp, n_t)[None, :]).ravel()
    r = (r_p * ARCSEC * x)[:, None]
    pos = np.stack([(r * np.cos(phi)[None, :]).ravel(), (r * np.sin(phi)[None, :]).ravel()], axis=-1)
    return flux, pos


def reference_visibilities(u, v, geometry, profile, template, r_p: float, phi_p, *, order_r: int = 4,
                           order_phi: int = 3, support: float | None = None, chunk_nodes: int = 2_000_000):
    """ΔV [Jy] at baselines ``(u, v)`` for planet azimuths ``phi_p`` (scalar or array): shape
    ``(n_phi, N)`` (or ``(N,)`` for a scalar)."""
    import ducc0

    u, v = np.asarray(u, dtype=float), np.asarray(v, dtype=float)
    phis = np.atleast_1d(np.asarray(phi_p, dtype=float))
    xi, eta = geometry.disc_frame_uv(u, v)
    c, s = np.cos(phis)[:, None], np.sin(phis)[:, None]
    q = np.stack([(c * xi + s * eta).ravel(), (-s * xi + c * eta).ravel()], axis=-1)  # R(-phi_p) q
    pieces = _radial_pieces(template, r_p, support)
    per_piece = order_r * order_phi * np.asarray(template.delta).shape[1]
    step = max(1, chunk_nodes // per_piece)
    out = np.zeros(q.shape[0], dtype=complex)
    for start in range(0, len(pieces), step):
        flux, pos = _chunk_nodes(profile, template, r_p, pieces[start:start + step], order_r, order_phi)
        out += ducc0.nufft.experimental.nu2nu(points_in=flux.astype(complex), coord_in=2 * np.pi * pos,
                                              coord_out=q, forward=False, epsilon=EPSILON, nthreads=1)
    out = out.reshape(phis.size, u.size) * (geometry.cos_inc * geometry.phase_factor(u, v))[None, :]
    return out if np.ndim(phi_p) else out[0]


def reference_terms(vis, residual, geometry, profile, template, r_p: float, phi_p, **kwargs):
    """``cross = Re sum w R* ΔV`` and ``power = sum w |ΔV|^2`` from :func:`reference_visibilities`
    (``residual = V_O - V_A`` at the data), one value per planet azimuth."""
    dV = np.atleast_2d(reference_visibilities(vis.u, vis.v, geometry, profile, template, r_p, phi_p, **kwargs))
    cross = (dV.real * residual.real + dV.imag * residual.imag) @ vis.weights
    power = (dV.real ** 2 + dV.imag ** 2) @ vis.weights
    return cross, power
