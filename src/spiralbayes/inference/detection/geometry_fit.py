"""The disc-geometry alternative's least squares, in memory that does not grow with the data.

The geometry alternative moves the axisymmetric model by four offsets (inclination, position angle,
RA, Dec; :func:`spiralbayes.alternatives.geometry_visibilities`) and fits them to the visibilities
with scipy's trust-region reflective least squares. Written directly, that problem holds a
``2N × 4`` Jacobian and the solver's copies of it (≈ 0.6 kB per visibility, 6 GB at 10^7). Here
the same solver is handed an exactly equivalent five-row problem instead: with the Jacobian ``J``
and the residual ``f`` at ``θ`` accumulated over blocks of visibilities into ``M = JᵀJ``,
``g = Jᵀf`` and ``c = fᵀf``, and ``M = RᵀR`` (``R = diag(√s) Vᵀ`` from ``M``'s eigenpairs)::

    J̃ = [R; 0],   f̃ = [R⁻ᵀ g, √(c − |R⁻ᵀ g|²)],

so that ``J̃ᵀJ̃ = M``, ``J̃ᵀf̃ = g`` and ``|f̃|² = c``. The trust-region reflective method uses the
Jacobian and the residual only through these three (its steps are built from the SVD of the
scaled Jacobian and ``Uᵀf``, its bound scaling from the gradient, its acceptance from the cost),
so the iterates are those of the full problem up to rounding.

Linear terms with free amplitudes (the nested test's spiral and peak) are projected out of the
residual as the full problem would with the QR of their weighted columns ``B``: with ``G = BᵀB``,
``M − (BᵀJ)ᵀG⁻¹BᵀJ``, ``g − (BᵀJ)ᵀG⁻¹Bᵀf`` and ``c − (Bᵀf)ᵀG⁻¹Bᵀf`` take the place of ``M``, ``g``, ``c``.
"""

from __future__ import annotations

import numpy as np

from ...alternatives import geometry_visibilities, offset_geometry

__all__ = ["BLOCK", "GEOMETRY_SCALES", "fit_geometry_offsets", "geometry_bounds", "normal_equations"]

BLOCK = 1 << 18
"""Visibilities per block of the accumulation (≈ 30 MB of temporaries)."""
GEOMETRY_SCALES = (0.5, 0.5, 5.0, 5.0)
"""Typical sizes of the offsets (deg, deg, mas, mas): the solver's ``x_scale``."""


def geometry_bounds(geometry) -> tuple[list[float], list[float]]:
    """Bounds on the offsets: the inclination stays in (0.01°, 89.9°), the centre within 1″."""
    return [0.01 - geometry.inc, -90.0, -1e3, -1e3], [89.9 - geometry.inc, 90.0, 1e3, 1e3]


def _blocks(n: int, block: int):
    for start in range(0, n, block):
        yield slice(start, min(n, start + block))


def normal_equations(table, vis, weights, geometry, theta, *, offset=None, basis=(), block: int = BLOCK):
    """``(M, g, c)`` of the weighted geometry residual at offsets ``theta``, linear ``basis`` projected out.

    Parameters
    ----------
    table : HankelTable
        The axisymmetric model's visibility profile.
    vis : Visibilities
    weights : ndarray
        Per visibility [Jy^-2].
    geometry : DiscGeometry
        The geometry the offsets are added to.
    theta : array_like
        ``(d_inc [deg], d_PA [deg], d_dRA [mas], d_dDec [mas])``.
    offset : ndarray, optional
        Model visibilities subtracted from the data besides the geometry's (a fixed spiral) [Jy].
    basis : sequence of ndarray
        Complex visibilities of linear terms whose best (unconstrained) amplitudes are removed.
    block : int
        Visibilities per block.

    Returns
    -------
    M : ndarray, shape (4, 4)
        ``JᵀJ`` of the real-stacked weighted residual ``f = √w (V − offset − V_geom(θ))``.
    g : ndarray, shape (4,)
        ``Jᵀf``.
    c : float
        ``fᵀf``, the χ².
    """
    g_theta = offset_geometry(geometry, theta)
    k = len(basis)
    M = np.zeros((4, 4))
    g = np.zeros(4)
    c = 0.0
    BJ = np.zeros((k, 4))
    Bf = np.zeros(k)
    BB = np.zeros((k, k))
    for s in _blocks(vis.V.size, block):
        sw = np.sqrt(weights[s])
        V, dV = geometry_visibilities(table, vis.u[s], vis.v[s], g_theta, jacobian=True)
        f = sw * (vis.V[s] - V - (0.0 if offset is None else offset[s]))
        J = -sw * dV
        # for the real stacking [Re x, Im x], x·y = Re Σ conj(x) y
        M += np.real(J.conj() @ J.T)
        g += np.real(J.conj() @ f)
        c += float(np.real(np.vdot(f, f)))
        if k:
            B = np.stack([sw * b[s] for b in basis])
            BJ += np.real(B.conj() @ J.T)
            Bf += np.real(B.conj() @ f)
            BB += np.real(B.conj() @ B.T)
    if k:
        Gi = np.linalg.pinv(BB)
        M = M - BJ.T @ Gi @ BJ
        g = g - BJ.T @ Gi @ Bf
        c = c - float(Bf @ Gi @ Bf)
    return M, g, c


def _compressed(M, g, c):
    """The five-row residual and Jacobian with the same ``JᵀJ``, ``Jᵀf`` and ``|f|²``."""
    s, V = np.linalg.eigh(0.5 * (M + M.T))
    s = np.clip(s, 0.0, None)
    root = np.sqrt(s)
    keep = s > 1e-14 * max(float(s.max()), 1e-300)
    f4 = np.where(keep, (V.T @ g) / np.where(keep, root, 1.0), 0.0)
    f5 = np.sqrt(max(c - float(f4 @ f4), 0.0))
    return np.append(f4, f5), np.vstack([root[:, None] * V.T, np.zeros((1, 4))])


def fit_geometry_offsets(table, vis, weights, geometry, x0, *, offset=None, basis=(), max_nfev: int = 200,
                         counter: dict | None = None, block: int = BLOCK):
    """Least-squares geometry offsets (trust-region reflective, scipy) from the blocked normal equations.

    Parameters are those of :func:`normal_equations`; ``x0`` the starting offsets (clipped to
    :func:`geometry_bounds`), ``max_nfev`` the solver's limit on residual evaluations, ``counter``
    a dict whose ``"n"`` counts them.

    Returns
    -------
    scipy.optimize.OptimizeResult
        ``x`` the offsets; ``cost`` half the χ² at them (the linear terms projected out).
    """
    from scipy.optimize import least_squares

    cache: dict = {}
    counter = {"n": 0} if counter is None else counter

    def evaluate(theta):
        key = np.asarray(theta, dtype=float).tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = _compressed(*normal_equations(table, vis, weights, geometry, theta, offset=offset,
                                                       basis=basis, block=block))
        return cache[key]

    def residuals(theta):
        counter["n"] += 1
        return evaluate(theta)[0]

    def jacobian(theta):
        return evaluate(theta)[1]

    lo, hi = geometry_bounds(geometry)
    x0 = np.clip(np.asarray(x0, dtype=float), lo, hi)
    return least_squares(residuals, x0, jac=jacobian, bounds=(lo, hi), x_scale=list(GEOMETRY_SCALES),
                         method="trf", xtol=1e-10, ftol=1e-12, max_nfev=max_nfev)
