"""The product rule itself: nodes, the exact integrals of template and profile against the radial
basis, node fluxes and the error bound (:mod:`spiralbayes.quadrature`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .._threads import blas_threads
from ..units import ARCSEC, TWO_PI
from .angular import PHI_TOLERANCE, TemplateSpectrum, _angular_n, bessel_tail
from .radial import KERNEL_TOLERANCE, GaussPanels, SincGrid, choose_radial_basis

__all__ = ["FINE_ORDER", "ProductQuadrature", "make_product_quadrature"]

FINE_ORDER = 10
"""Gauss-Legendre nodes per piece for the integrals C (their error is estimated with FINE_ORDER - 2)."""


# --- the rule -------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class ProductQuadrature:
    """Nodes of the product rule for one planet radius: rings ``x_a`` (units of r_p), each with
    ``n_phi`` azimuths ``2 pi j / n_phi`` from its group.

    Rings are grouped: consecutive rings that need the same number of azimuths (the angular
    rule's count grows with the ring's radius, :func:`.angular_count`) form one group, so inner
    rings carry fewer nodes. Arrays over all nodes (fluxes, positions) are flat, group after
    group, ring-major inside a group (:meth:`split`).

    Attributes
    ----------
    r_p : float
        Planet radius [arcsec].
    x_template : ndarray
        The template's radial grid (``x = r / r_p``), integrated exactly.
    x : ndarray
        Radial nodes (units of r_p; sinc nodes may lie outside the template's range, and below
        zero: the opposite side of the ray).
    groups : tuple of (start, stop, n_phi, tail)
        Rings ``start:stop`` have ``n_phi`` azimuths (a multiple of the scan's azimuth count);
        ``tail`` is their angular rule's error bound per unit L1 norm.
    basis : GaussPanels or SincGrid
        The radial basis interpolating the kernel.
    kernel_bound : float
        Error bound of the kernel interpolation per unit L1 norm.
    uv_max : float
        Longest baseline [lambda] the rule is exact for.
    support : float or None
        Radius [arcsec] beyond which the profile vanishes (frank's ``Rmax``), or None.
    x_cover : float
        The basis interpolates the kernel on ``[x_template[0], x_cover]``; the integration may not
        reach beyond.
    breaks : tuple of float
        Radii [arcsec] where the profile jumps inside the support (a model disc's edges): the fine
        rule is split there, so that the jump is integrated exactly too.
    """

    r_p: float
    x_template: np.ndarray
    x: np.ndarray
    groups: tuple
    basis: GaussPanels | SincGrid
    kernel_bound: float
    uv_max: float
    support: float | None = None
    fine_order: int = FINE_ORDER
    x_cover: float = np.inf
    breaks: tuple = ()
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    kind = "product"

    @property
    def x_end(self) -> float:
        """Outer edge of the integration in x: ``min(x_template[-1], support / r_p)``."""
        end = float(self.x_template[-1])
        if self.support is not None and self.r_p > 0:
            end = min(end, max(self.support / self.r_p, float(self.x_template[0]) * (1 + 1e-12)))
        return end

    @property
    def r(self) -> np.ndarray:
        """Ring radii [arcsec] (negative for sinc nodes below x = 0)."""
        return self.r_p * self.x

    @property
    def n_phi(self) -> int:
        """The largest azimuth count of a ring."""
        return max(g[2] for g in self.groups)

    @property
    def phi_bound(self) -> float:
        return max(g[3] for g in self.groups)

    @property
    def blocks(self) -> list[tuple[int, int, int]]:
        """``(start, stop, n_phi)`` of each group of rings."""
        return [(int(a), int(b), int(n)) for a, b, n, _ in self.groups]

    @property
    def size(self) -> int:
        return sum((b - a) * n for a, b, n in self.blocks)

    @property
    def extent(self) -> float:
        """Largest ``|x|`` of a node (units of r_p)."""
        return float(np.max(np.abs(self.x)))

    @property
    def key(self) -> tuple:
        """Identifies the node set (for caches of plans and dirty images)."""
        return ("product", self.r_p, self.x.size, float(self.x[0]), float(self.x[-1]), self.x_end,
                tuple(self.blocks))

    def split(self, flat: np.ndarray) -> list[np.ndarray]:
        """A flat array over the nodes as one ``(rings, n_phi)`` view per group."""
        out, offset = [], 0
        for a, b, n in self.blocks:
            out.append(flat[offset: offset + (b - a) * n].reshape(b - a, n))
            offset += (b - a) * n
        return out

    def positions_x(self) -> np.ndarray:
        """Node positions in units of r_p, shape ``(size, 2)`` (flat order)."""
        parts = []
        for a, b, n in self.blocks:
            phi = TWO_PI * np.arange(n) / n
            xa = self.x[a:b, None]
            parts.append(np.stack([(xa * np.cos(phi)).ravel(), (xa * np.sin(phi)).ravel()], axis=-1))
        return np.concatenate(parts)

    @cached_property
    def _positions(self) -> np.ndarray:
        return self.positions_x() * (self.r_p * ARCSEC)

    def positions(self) -> np.ndarray:
        """Node positions ``(xi, eta)`` [rad], shape ``(size, 2)`` (flat order, cached)."""
        return self._positions

    def at(self, r_p: float, support: float | None = None) -> ProductQuadrature:
        """The same nodes in ``x`` at a planet radius ``r_p <= self.r_p`` (still exact: the kernel's
        phase per unit x and the angular bandwidth only shrink), for a profile vanishing beyond
        ``support`` [arcsec] (default: this rule's). Build the rule without ``support`` when it
        serves smaller radii: a profile edge at ``support / r_p`` moves outwards as ``r_p`` shrinks,
        and the nodes must cover it."""
        if r_p > self.r_p * (1 + 1e-12):
            raise ValueError(f"the rule was built for r_p <= {self.r_p} arcsec, asked for {r_p}")
        other = ProductQuadrature(float(r_p), self.x_template, self.x, self.groups, self.basis, self.kernel_bound,
                                  self.uv_max, self.support if support is None else float(support),
                                  self.fine_order, self.x_cover, self.breaks)
        if other.x_end > self.x_cover * (1 + 1e-12):
            raise ValueError(f"at r_p = {r_p} arcsec the profile reaches x = {other.x_end:.4g}, beyond the nodes "
                             f"(x <= {self.x_cover:.4g}): build the rule without support")
        if other.x_end == self.x_end and not self.breaks and "_fine" in self.__dict__:
            other.__dict__["_fine"] = self._fine  # profile-independent, in units of x
        return other

    # -- the fine rule for the integrals C (profile-independent part) -------------------------------
    @cached_property
    def _fine(self) -> dict:
        """Per order: fine nodes ``x``, weights ``x^2 ds``, template interval ``t``, fraction in it,
        first basis index and basis values."""
        from scipy.special import roots_legendre

        s_t = np.log(self.x_template)
        s_end = np.log(self.x_end)
        cuts = [np.log(b) for b in np.asarray(self.basis.breakpoints, dtype=float) if b > 0]
        if self.r_p > 0:
            cuts += [np.log(b / self.r_p) for b in self.breaks if b > 0]
        s = np.union1d(s_t[s_t <= s_end], [c for c in cuts if s_t[0] < c < s_end] + [s_end])
        pieces = np.maximum(np.ceil(np.diff(np.exp(s)) / self.basis.fine_width).astype(int), 1)
        s = np.concatenate([s[:1]] + [s[i] + (s[i + 1] - s[i]) * np.arange(1, k + 1) / k
                                      for i, k in enumerate(pieces)])
        out = {}
        for order in (self.fine_order, self.fine_order - 2):
            g, gw = roots_legendre(order)
            a, b = s[:-1, None], s[1:, None]
            sf = (0.5 * (a + b) + 0.5 * (b - a) * g[None, :]).ravel()
            wf = (0.5 * (b - a) * gw[None, :]).ravel()
            x = np.exp(sf)
            t = np.clip(np.searchsorted(s_t, sf, side="right") - 1, 0, s_t.size - 2)
            frac = (sf - s_t[t]) / (s_t[t + 1] - s_t[t])
            start, values = self.basis.evaluate(x)
            out[order] = (x, x * x * wf, t, frac, start, values)
        return out

    def _integrals(self, profile, order: int, brightness: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        _, w, t, frac, start, values = self._fine[order]
        base = brightness * w
        n_x, n_t = self.x.size, self.x_template.size
        cols = start[:, None] + np.arange(values.shape[1])[None, :]
        keep = (cols >= 0) & (cols < n_x)
        index = (np.where(keep, cols, 0) * n_t + t[:, None])[keep]
        lower = ((base * (1 - frac))[:, None] * values)[keep]
        upper = ((base * frac)[:, None] * values)[keep]
        C = (np.bincount(index, lower, minlength=n_x * n_t)
             + np.bincount(index + 1, upper, minlength=n_x * n_t)).reshape(n_x, n_t)
        A = np.bincount(t, np.abs(base) * (1 - frac), minlength=n_t) + np.bincount(t + 1, np.abs(base) * frac,
                                                                                     minlength=n_t)
        return C, A

    def radial_matrix(self, profile) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``C[a, t] = int I_A(r_p x) b_t(x) l_a(x) x dx`` (dense, ``(n_x, n_t)``), its error estimate
        ``|C - C_low|`` (fine rule two orders lower) and ``A_t = int |I_A| b_t x dx`` (cached for the
        last profile)."""
        cached = self._cache.get("C")
        if cached is None or cached[0] is not profile:
            hi, lo = self.fine_order, self.fine_order - 2
            x_hi, x_lo = self._fine[hi][0], self._fine[lo][0]
            bright = np.asarray(profile(self.r_p * np.concatenate([x_hi, x_lo])), dtype=float)
            C, A = self._integrals(profile, hi, bright[: x_hi.size])
            C_low, _ = self._integrals(profile, lo, bright[x_hi.size:])
            self._cache["C"] = cached = (profile, C, np.abs(C - C_low), A)
        return cached[1], cached[2], cached[3]

    # -- the template on the rule ----------------------------------------------------------------------
    def weights(self, profile, spectrum: TemplateSpectrum) -> np.ndarray:
        """Node weights in units of ``r_p^2``: ``(2 pi / n_phi) sum_t C[a, t] delta~_t(phi_j)`` [Jy/sr],
        flat; :meth:`flux` is this times ``r_p^2`` [sr]."""
        C, _, _ = self.radial_matrix(profile)
        # one BLAS thread: a threaded product may round differently, and the same inputs must give
        # the same bits in every process (data hashes, resumed runs)
        with blas_threads(1):
            return np.concatenate([((C[a:b] @ spectrum.rows(n)) * (TWO_PI / n)).ravel() for a, b, n in self.blocks])

    def flux(self, profile, spectrum: TemplateSpectrum) -> np.ndarray:
        """Node fluxes [Jy] (face on), planet at ``phi = 0``, flat (:meth:`split` gives the groups)."""
        return self.weights(profile, spectrum) * (self.r_p * ARCSEC) ** 2

    def error_bound(self, profile, spectrum: TemplateSpectrum) -> dict:
        """Bounds [Jy] on ``|ΔV_rule(q) - ΔV_exact(q)|`` at every ``|q| <= uv_max`` and planet azimuth
        (face on: multiply by cos i).

        ``l1``: the perturbation's L1 norm ``int |I_A delta| dA``; ``kernel``: the radial kernel
        interpolation (``kernel_bound * l1``); ``phi``: the angular rule; ``fine``: the integrals
        C (their change two orders lower, an estimate); ``total``: the sum.
        """
        C, dC, A = self.radial_matrix(profile)
        scale = TWO_PI * (self.r_p * ARCSEC) ** 2
        phi = fine = 0.0
        m_max = spectrum.abs_mean
        for a, b, n, tail in self.groups:
            m_rows = spectrum.rows_abs_mean(n)
            m_max = np.maximum(m_max, m_rows)
            phi += tail * float(np.sum(np.abs(C[a:b]) @ m_rows))
            fine += float(np.sum(dC[a:b] @ m_rows))
        l1 = scale * float(A @ m_max)
        out = {"l1": l1, "kernel": self.kernel_bound * l1, "phi": scale * phi, "fine": scale * fine}
        out["total"] = out["kernel"] + out["phi"] + out["fine"]
        return out


def _ring_groups(z: np.ndarray, multiple: int, tolerance: float) -> tuple:
    """Consecutive rings with equal azimuth counts for their ``z = kappa |x_a|``."""
    counts = [_angular_n(float(zi), multiple, tolerance) for zi in z]
    groups, start = [], 0
    for a in range(1, len(counts) + 1):
        if a == len(counts) or counts[a] != counts[start]:
            n = counts[start]
            groups.append((start, a, int(n), 4 * bessel_tail(float(np.max(z[start:a])), n // 2)))
            start = a
    return tuple(groups)


def make_product_quadrature(template, r_p: float, uv_max: float, *, phi_multiple: int = 90,
                            support: float | None = None, radial: str = "auto",
                            kernel_tolerance: float = KERNEL_TOLERANCE,
                            phi_tolerance: float = PHI_TOLERANCE, breaks=()) -> ProductQuadrature:
    """The product rule for ``template``'s radial grid at planet radius ``r_p`` [arcsec].

    Parameters
    ----------
    template : SpiralTemplate (or its radial grid ``x``)
    r_p : float
        Planet radius [arcsec].
    uv_max : float
        Longest (deprojected) baseline [lambda] the rule must serve.
    phi_multiple : int
        ``n_phi`` is a multiple of it (the scan's planet azimuth count).
    support : float, optional
        Radius [arcsec] beyond which the profile vanishes (frank's ``Rmax``): nodes stop there.
    breaks : sequence of float
        Radii [arcsec] where the profile jumps inside the support (``ProductQuadrature.breaks``).
    radial : {"auto", "gauss", "sinc"}
        The radial basis; "auto" takes the one with fewer nodes.
    """
    x_t = np.asarray(getattr(template, "x", template), dtype=float)
    x0 = float(x_t[0])
    x1 = float(x_t[-1]) if support is None else min(float(x_t[-1]), max(support / r_p, x0 * (1 + 1e-12)))
    kappa = TWO_PI * uv_max * r_p * ARCSEC
    basis, kernel_bound = choose_radial_basis(x0, x1, kappa, radial, kernel_tolerance)
    x = basis.nodes()
    groups = _ring_groups(kappa * np.abs(x), phi_multiple, phi_tolerance)
    return ProductQuadrature(float(r_p), x_t, x, groups, basis, float(kernel_bound), float(uv_max),
                             None if support is None else float(support), FINE_ORDER, x1,
                             tuple(float(b) for b in breaks))
