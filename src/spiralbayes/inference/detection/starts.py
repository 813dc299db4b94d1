"""Starting points for the alternative fits, read off the residual dirty image.

For a field ``P`` (ring means removed) the cross term of Δχ² is ``Re sum_k w_k R_k* ΔV_k =
sum_c P_c S_c`` with ``S`` the weighted residual dirty image on the disc grid
(:meth:`.FieldTransform.gradient_map` of ``w R``, ring means removed). Correlating ``S`` with each
model's shape over its position parameters is cheap (FFTs along azimuth, a small matrix in
radius) and, divided by the shape's root-sum-square flux, ranks candidate positions as a matched
filter would for uniform uv coverage. The best ``n_candidates`` (well apart) then get their
amplitudes and Δχ² exactly from one batched transform (:func:`linear_amplitudes`); the best of
those start the optimiser.
"""

from __future__ import annotations

import numpy as np

from ...alternatives import FIELD_MODELS, FieldTransform, ProfileContext

__all__ = ["candidate_starts", "linear_amplitudes"]

SIGMA_PHI_STARTS = (0.3, 0.8)  # rad


START_ECCENTRICITY = 0.05
"""Eccentricity an ``eccentric_excess`` start takes (with the contrast that gives the fitted first order)."""


def _radial_matrix(r, centres, sigma):
    """``W[i, j] = exp(-(r_j - c_i)^2 / 2 sigma^2)``."""
    return np.exp(-0.5 * ((r[None, :] - centres[:, None]) / sigma) ** 2)


def _widths(ctx: ProfileContext, beam: float, broad: bool) -> list[float]:
    widths = [1.0 * beam, 3.0 * beam]
    if broad:
        widths += [0.25 * ctx.grid.r_max, 1.0 * ctx.grid.r_max]
    return [max(w, 2 * ctx.grid.dr) for w in widths]


def _peaks_2d(score: np.ndarray, top: int):
    """Indices of the ``top`` highest local maxima of a (radius, periodic azimuth) map."""
    padded = np.pad(score, ((1, 1), (0, 0)), constant_values=-np.inf)
    is_max = np.ones(score.shape, dtype=bool)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            if di or dj:
                is_max &= score >= np.roll(padded, -dj, axis=1)[1 + di:1 + di + score.shape[0]]
    idx = np.argwhere(is_max)
    order = np.argsort(score[is_max])[::-1][:top]
    return [tuple(idx[o]) for o in order]


def _peaks_1d(score: np.ndarray, top: int):
    padded = np.pad(score, 1, constant_values=-np.inf)
    is_max = (score >= padded[:-2]) & (score >= padded[2:])
    idx = np.flatnonzero(is_max)
    return idx[np.argsort(score[idx])[::-1][:top]]


def _arc_candidates(S, ctx, beam):
    g, r = ctx.grid, ctx.grid.r
    area = g.cell_area
    out = []
    centres = r[(r > 2 * g.dr) & (r < 0.95 * g.r_max)]
    for s_r in _widths(ctx, beam, broad=False):
        Wm = _radial_matrix(r, centres, s_r) * ctx.I_ring[None, :]
        for s_phi in SIGMA_PHI_STARTS:
            kernel = np.exp((np.cos(g.phi) - 1) / s_phi ** 2)
            # correlation over phi_c, sum_phi S(r, phi) k(phi - phi_c), by FFTs along phi
            corr_phi = np.fft.irfft(np.fft.rfft(S, axis=1) * np.conj(np.fft.rfft(kernel))[None, :],
                                    n=g.n_phi, axis=1)
            norm = np.sqrt((Wm ** 2 @ area ** 2) * np.sum(kernel ** 2))
            score = (Wm @ corr_phi) / np.where(norm > 0, norm, np.inf)[:, None]
            for i, j in _peaks_2d(score, 6):
                out.append((float(score[i, j]), np.array([1.0, centres[i], g.phi[j], s_r, s_phi])))
    return out


def _fourier_candidates(S, ctx, beam, model_name):
    """Candidates of the cos/sin models from the m = 1 or 2 azimuthal coefficient of ``S``."""
    g, r = ctx.grid, ctx.grid.r
    m = 2 if model_name == "m2" else 1
    S_m = np.fft.fft(S, axis=1)[:, m] / g.n_phi  # sum_phi S e^{-i m phi} / n_phi
    # dP/de at e = 0: r I_A' W cos(phi - omega) (eccentric_ring), -C I_A r (r - r_c) / w^2 G cos(phi - omega)
    # (eccentric_excess: a narrow ring's, whose width the beam sets)
    radial = r * ctx.interpolate(r)[1] if model_name == "eccentric_ring" else ctx.I_ring
    kappas = (-2.0, 0.0, 2.0) if model_name == "m2" else (0.0,)
    out = []
    centres = r[r > 2 * g.dr]
    excess = model_name == "eccentric_excess"
    for s_r in _widths(ctx, beam, broad=not excess):
        Wm = _radial_matrix(r, centres, s_r) * radial[None, :]
        if excess:
            Wm = -Wm * r[None, :] * (r[None, :] - centres[:, None]) / s_r ** 2
        norm = np.sqrt(0.5 * g.n_phi * (Wm ** 2 @ g.cell_area ** 2))
        for kappa in kappas:
            twist = np.exp(2j * kappa * np.log(r / centres[:, None]))  # (n_c, n_r)
            c = np.sum(Wm * twist * S_m[None, :], axis=1) * g.n_phi
            score = np.abs(c) / np.where(norm > 0, norm, np.inf)
            for i in _peaks_1d(score, 4):
                phase = np.angle(c[i])  # the amplitudes are set exactly by linear_amplitudes
                theta = [np.cos(phase), -np.sin(phase), centres[i], s_r]
                if model_name == "m2":
                    theta.append(kappa)
                if excess:
                    theta.append(1.0)   # contrast: only contrast x e is set to first order
                out.append((float(score[i]), np.array(theta)))
    return out


def _same_place(a, b, name: str, min_sep: float) -> bool:
    """Whether two candidate shapes are too alike to be worth separate starts."""
    if name == "arc":
        return abs(a[1] * np.exp(1j * a[2]) - b[1] * np.exp(1j * b[2])) < min_sep and 0.5 < a[3] / b[3] < 2
    near = abs(a[2] - b[2]) < min_sep and 0.5 < a[3] / b[3] < 2
    return near and (name != "m2" or a[4] == b[4])


def _distinct(cands, name, top: int, min_sep: float):
    """The ``top`` best candidates, skipping any too close (:func:`_same_place`) to a better one."""
    chosen: list = []
    for _score, theta in sorted(cands, key=lambda c: -c[0]):
        if any(_same_place(theta, t, name, min_sep) for t in chosen):
            continue
        chosen.append(theta)
        if len(chosen) == top:
            break
    return chosen


def linear_amplitudes(model, thetas, ctx: ProfileContext, transform: FieldTransform, R, weights):
    """Best amplitudes and Δχ² for each shape in ``thetas`` (one batched transform).

    The model's amplitude parameters are set by weighted linear least squares with the others
    held (from the Jacobian at zero amplitude: exact for ``arc``, ``lopsided`` and ``m2``, first
    order in ``e`` for ``eccentric_ring``); the arc's contrast is kept >= 0.
    """
    idx = list(model.amplitude_indices)
    basis = []
    for theta in thetas:
        t0 = np.array(theta, dtype=float)
        t0[idx] = 0.0
        if model.name == "arc":
            t0[0] = 1.0  # the arc's Jacobian in A is its shape at any A
        if model.name == "eccentric_excess":
            t0[4] = 1.0  # contrast 1: the amplitudes found are contrast x e
        J = model.field_and_jacobian(t0, ctx)[1]
        basis.append(J[idx])
    dV = transform.visibilities(np.concatenate(basis)).reshape(len(thetas), len(idx), -1)
    out = []
    for theta, V in zip(thetas, dV):
        M = np.einsum("ik,jk,k->ij", V.conj(), V, weights).real
        c = np.einsum("ik,k->i", V.conj(), weights * R).real
        try:
            a = np.linalg.solve(M, c)
        except np.linalg.LinAlgError:
            a = np.zeros(len(idx))
        if model.name == "arc":
            a = np.maximum(a, 0.0)
        t = np.array(theta, dtype=float)
        t[idx] = a
        if model.name == "eccentric_ring":
            e = np.hypot(*a)
            if e > 0.8 * model.E_MAX:  # beyond first order: start at a safe eccentricity
                t[idx] = a * 0.8 * model.E_MAX / e
        if model.name == "eccentric_excess":
            # split contrast x e, first order's only combination, at a typical e of a disc's ring (0.05)
            contrast = float(np.clip(np.hypot(*a) / START_ECCENTRICITY, 0.05, 3.0))
            t[idx], t[4] = a / contrast, contrast
        out.append((float(2 * a @ c - a @ M @ a), t))
    return out


def candidate_starts(name: str, S, ctx: ProfileContext, transform, R, weights, beam: float,
                     n_starts: int, n_candidates: int = 6):
    """Starting parameters for model ``name``: the ``n_starts`` best of ``n_candidates`` shapes."""
    model = FIELD_MODELS[name]
    cands = _arc_candidates(S, ctx, beam) if name == "arc" else _fourier_candidates(S, ctx, beam, name)
    shapes = _distinct(cands, name, n_candidates, min_sep=2 * beam)
    if not shapes:
        return []
    scored = linear_amplitudes(model, shapes, ctx, transform, R, weights)
    scored.sort(key=lambda s: -s[0])
    return [t for _, t in scored[:n_starts]]
