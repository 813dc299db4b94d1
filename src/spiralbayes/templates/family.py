"""A continuous template family: the spiral at any planet mass (and disc aspect ratio) in a range.

The bank holds templates at four masses a factor of three apart; a planet between them is neither.
:class:`TemplateFamily` holds one morphology (variant, τ0, β, hand) on a fine grid of nodes and
returns the template at any ``M_p`` in ``[mass_min, mass_max]`` (and ``H/r`` in its range) by
interpolation:

* **in mass**: 4-point Lagrange (cubic) interpolation in ``ln M_p`` between the neighbouring nodes.
  The weights do not depend on the maps, so the interpolated template — and, since the
  visibilities are linear in ``δ``, its visibilities — is a fixed linear combination of at most
  four node templates (:meth:`TemplateFamily.weights`).
* **in aspect ratio**: the wake's ridge winds as ``φ_wake(x; H/r)``
  (:func:`~spiralbayes.templates.wake.wake_phase`, ``∝ 1/h_p``), so maps at two aspect ratios have
  their arms at different azimuths and a plain average of them holds two faint spirals instead of one.
  Each node map is first rotated, row by row (``x = r/r_p``), by ``φ_wake(x; h) − φ_wake(x; h_k)``
  — an exact shift of each row's Fourier series — and the aligned maps are then interpolated
  (4-point Lagrange in ``h``).

The nodes are made by the built-in generator in the chosen morphology
(:func:`~spiralbayes.templates.variants.variant_template`), which makes any mass and aspect ratio,
so the interpolation can be checked against the exact template at any point. On the fiducial
observation (36,120 visibilities, 50 au, 30° inclination) the default nodes (:data:`N_MASS_NODES`
log-spaced masses over 0.1–3 M_th, :data:`H_NODES` in aspect ratio) keep the χ² lost by using the
interpolated template instead of the exact one below the scan's accuracy tolerance; the table is
in docs/templates.md ("Continuous family").

Masses are in thermal masses ``M_th = h_p³ M_*`` at the node's aspect ratio, as everywhere in
the package.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from ..exceptions import InputError
from .template import SpiralTemplate, template_name, validate_hand
from .wake import WakeSettings, wake_phase

__all__ = ["H_NODES", "MASS_RANGE", "N_MASS_NODES", "TemplateFamily", "lagrange_weights", "shift_rows"]

log = logging.getLogger(__name__)

MASS_RANGE = (0.1, 3.0)
"""Default mass range of a family [M_th]: the paper's bank masses."""

N_MASS_NODES = 49
"""Default number of log-spaced mass nodes over :data:`MASS_RANGE` (a step of 7.3 % in mass)."""

H_NODES = (0.05, 0.0625, 0.075, 0.0875, 0.10)
"""Default aspect-ratio nodes (``H/r`` at ``r_p``) of a family that spans the bank's range."""


def lagrange_weights(nodes: np.ndarray, value: float, order: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Indices and weights of ``order``-point Lagrange interpolation at ``value``.

    The points are the ``order`` nodes nearest the interval holding ``value`` (fewer when there
    are fewer nodes); ``sum(weights * f[indices])`` interpolates ``f`` given at ``nodes``.

    Parameters
    ----------
    nodes : (n,) array
        Strictly increasing node positions.
    value : float
        Where to interpolate, within ``[nodes[0], nodes[-1]]``.
    order : int
        Number of points (2: linear, 4: cubic).

    Returns
    -------
    indices : (k,) int array
    weights : (k,) float array
        Summing to 1.
    """
    nodes = np.asarray(nodes, dtype=float)
    n = nodes.size
    if n == 1:
        return np.array([0]), np.array([1.0])
    k = int(np.clip(np.searchsorted(nodes, value) - 1, 0, n - 2))
    m = min(order, n)
    lo = int(np.clip(k - (m // 2 - 1), 0, n - m))
    idx = np.arange(lo, lo + m)
    x = nodes[idx]
    w = np.array([np.prod([(value - x[i]) / (x[j] - x[i]) for i in range(m) if i != j]) for j in range(m)])
    return idx, w


def shift_rows(delta: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """``δ(x, φ − shift(x))`` for a periodic map on a uniform azimuth grid (Fourier shift per row)."""
    F = np.fft.rfft(delta, axis=1)
    m = np.arange(F.shape[1])
    return np.fft.irfft(F * np.exp(-1j * m[None, :] * shift[:, None]), n=delta.shape[1], axis=1)


@dataclass(frozen=True, eq=False)
class _NodeMaker:
    """Makes a family's hand-R node template at ``(mass, h_p)`` (a plain object, so families pickle
    for worker processes)."""

    tau0: float
    beta: float
    variant: object
    options: dict

    def __call__(self, mass: float, h_p: float) -> SpiralTemplate:
        from .variants import variant_template  # the variants module imports the bank; keep this light

        return variant_template(mass, self.tau0, self.beta, "R", self.variant, h_p=h_p, **self.options)


@dataclass(eq=False)
class TemplateFamily:
    """One morphology's templates on a grid of masses (and aspect ratios), interpolated between.

    Build one with :meth:`build`; :meth:`at` gives the template at any mass and aspect ratio in
    range.

    Parameters
    ----------
    masses : (n_m,) array
        Mass nodes [M_th], strictly increasing.
    h_ps : (n_h,) array
        Aspect-ratio nodes (``H/r`` at ``r_p``), strictly increasing; one node fixes ``H/r``.
    nodes : list of list of SpiralTemplate, or callable
        ``nodes[j][k]`` is the hand-R template at ``masses[j]``, ``h_ps[k]``; all on one grid. A
        callable ``nodes(mass, h_p)`` makes them when first needed (what :meth:`build` does), so
        a template costs at most 16 node templates, made once.
    variant, tau0, beta : str, float, float
        The morphology, initial optical depth and cooling time shared by the nodes.
    hand : {'R', 'L'}
        The hand of the templates :meth:`at` returns.
    wake_options : dict
        :class:`~spiralbayes.templates.wake.WakeSettings` fields used for the wake ridge (those
        the nodes were made with).
    """

    masses: np.ndarray
    h_ps: np.ndarray
    nodes: list | Callable
    variant: str = "compromise"
    tau0: float = 3.0
    beta: float = 0.0
    hand: str = "R"
    wake_options: dict = field(default_factory=dict)

    def __post_init__(self):
        self.masses = np.asarray(self.masses, dtype=float)
        self.h_ps = np.asarray(self.h_ps, dtype=float)
        self.hand = validate_hand(self.hand)
        for name, a in (("masses", self.masses), ("h_ps", self.h_ps)):
            if a.ndim != 1 or a.size < 1 or np.any(np.diff(a) <= 0) or np.any(a <= 0):
                raise InputError(f"TemplateFamily.{name} must be positive and strictly increasing, got {a}")
        self._made: dict[tuple[int, int], SpiralTemplate] = {}
        self._ridges: dict[float, np.ndarray] = {}
        if callable(self.nodes):
            return
        if len(self.nodes) != self.masses.size or any(len(row) != self.h_ps.size for row in self.nodes):
            raise InputError(f"TemplateFamily.nodes must be {self.masses.size} x {self.h_ps.size} templates")
        for j, row in enumerate(self.nodes):
            for k, t in enumerate(row):
                self._add(j, k, t)

    def _add(self, j: int, k: int, t: SpiralTemplate) -> SpiralTemplate:
        if t.hand != "R":
            raise InputError(f"TemplateFamily nodes are hand-R templates; {t.name!r} is hand {t.hand}")
        if self._made:
            first = next(iter(self._made.values()))
            if t.delta.shape != first.delta.shape or not np.array_equal(t.x, first.x):
                raise InputError("TemplateFamily nodes must share one (x, phi) grid")
        self._made[(j, k)] = t
        return t

    def node(self, j: int, k: int = 0) -> SpiralTemplate:
        """The hand-R node template at ``masses[j]``, ``h_ps[k]`` (made on first use)."""
        if (j, k) not in self._made:
            assert callable(self.nodes)  # a full grid was added in __post_init__
            self._add(j, k, self.nodes(float(self.masses[j]), float(self.h_ps[k])))
        return self._made[(j, k)]

    # ------------------------------------------------------------------ construction
    @classmethod
    def build(cls, tau0: float = 3.0, beta: float = 0.0, variant: str = "compromise", hand: str = "R", *,
              h_p: float | Sequence[float] = 0.07, masses: Sequence[float] | None = None,
              mass_range: tuple[float, float] = MASS_RANGE, n_masses: int = N_MASS_NODES,
              **options) -> TemplateFamily:
        """Make the node templates with the generator in one morphology.

        Parameters
        ----------
        tau0, beta : float
            Initial optical depth at ``r_p`` and cooling time ``β = t_c Ω`` of the family.
        variant : str
            Morphology: ``"compromise"``, ``"hydro"`` or ``"wakeflow"``
            (:mod:`spiralbayes.templates.variants`).
        hand : {'R', 'L'}
        h_p : float or sequence of float
            One aspect ratio (fixed ``H/r``), or the aspect-ratio nodes (:data:`H_NODES` spans
            the bank's range).
        masses : sequence of float, optional
            Mass nodes [M_th]; default :data:`N_MASS_NODES` log-spaced over ``mass_range``.
        mass_range : (float, float)
            ``(M_min, M_max)`` [M_th] when ``masses`` is not given.
        n_masses : int
            Number of mass nodes when ``masses`` is not given (at least 2).
        **options
            Grid and disc settings for :func:`~spiralbayes.templates.generator.make_template`.

        Returns
        -------
        TemplateFamily
            Node templates are made when :meth:`at` first needs them.
        """
        nodes_m: np.ndarray
        if masses is None:
            lo, hi = (float(m) for m in mass_range)
            if not (0 < lo < hi and np.isfinite(hi)):
                raise InputError(f"mass_range must be (M_min, M_max) with 0 < M_min < M_max [M_th], got {mass_range}")
            if int(n_masses) < 2:
                raise InputError(f"n_masses must be at least 2, got {n_masses}")
            nodes_m = np.geomspace(lo, hi, int(n_masses))
        else:
            nodes_m = np.asarray(masses, dtype=float)
        h_ps = np.atleast_1d(np.asarray(h_p, dtype=float))

        make = _NodeMaker(float(tau0), float(beta), variant, dict(options))
        first = make(float(nodes_m[0]), float(h_ps[0]))  # bad settings fail here, not at the first at()
        wake = {k: v for k, v in options.items() if k in WakeSettings.__dataclass_fields__ and k != "h_p"}
        log.info("template family %s tau0=%g beta=%g: %d masses x %d H/r nodes", variant, tau0, beta,
                 nodes_m.size, h_ps.size)
        family = cls(nodes_m, h_ps, make, variant=str(variant), tau0=float(tau0), beta=float(beta), hand=hand,
                     wake_options=wake)
        family._add(0, 0, first)
        return family

    # ------------------------------------------------------------------ interpolation
    @property
    def mass_range(self) -> tuple[float, float]:
        """``(M_min, M_max)`` [M_th] that :meth:`at` accepts."""
        return float(self.masses[0]), float(self.masses[-1])

    @property
    def h_range(self) -> tuple[float, float]:
        """``(h_min, h_max)`` of ``H/r`` at ``r_p`` that :meth:`at` accepts (equal: fixed)."""
        return float(self.h_ps[0]), float(self.h_ps[-1])

    def _check(self, mass: float, h_p: float | None) -> float:
        lo, hi = self.mass_range
        if not (np.isfinite(mass) and lo * (1 - 1e-12) <= mass <= hi * (1 + 1e-12)):
            raise InputError(f"mass {mass!r} M_th is outside the family's range [{lo:g}, {hi:g}] M_th: "
                             "build the family with a wider mass_range")
        if h_p is None:
            if self.h_ps.size > 1:
                raise InputError(f"this family spans H/r {self.h_range[0]:g}-{self.h_range[1]:g}: give h_p=")
            return float(self.h_ps[0])
        a, b = self.h_range
        if not (np.isfinite(h_p) and a - 1e-12 <= h_p <= b + 1e-12):
            raise InputError(f"h_p {h_p!r} is outside the family's H/r range [{a:g}, {b:g}]")
        return float(h_p)

    def weights(self, mass: float, h_p: float | None = None) -> list[tuple[int, int, float]]:
        """The nodes and weights whose (ridge-aligned) sum is the template at ``mass``, ``h_p``.

        Returns
        -------
        list of (j, k, weight)
            Node ``nodes[j][k]`` (mass ``masses[j]``, aspect ratio ``h_ps[k]``) and its weight.
        """
        h = self._check(float(mass), h_p)
        jm, wm = lagrange_weights(np.log(self.masses), float(np.log(mass)))
        jh, wh = lagrange_weights(self.h_ps, h)
        return [(int(j), int(k), float(a * b)) for j, a in zip(jm, wm) for k, b in zip(jh, wh) if a * b != 0.0]

    def _ridge(self, h: float) -> np.ndarray:
        key = round(float(h), 12)
        if key not in self._ridges:
            st = WakeSettings(h_p=float(h), **self.wake_options)
            self._ridges[key] = wake_phase(self.node(0, 0).x, self.beta, st)
        return self._ridges[key]

    def at(self, mass: float, h_p: float | None = None) -> SpiralTemplate:
        """The template at ``mass`` [M_th] (and ``h_p``, ``H/r`` at ``r_p``) in the family's hand.

        Parameters
        ----------
        mass : float
            Planet mass [M_th], within :attr:`mass_range`.
        h_p : float, optional
            Aspect ratio at ``r_p``, within :attr:`h_range` (required when the family spans one).

        Returns
        -------
        SpiralTemplate
            Named like the bank's templates (e.g. ``wake_m0.5_tau3_b0_h0.07_R``), with the nodes
            and weights in its ``provenance["family"]``.
        """
        h = self._check(float(mass), h_p)
        terms = self.weights(mass, h)
        first = self.node(*terms[0][:2])
        delta = np.zeros(first.delta.shape)
        for j, k, w in terms:
            node = np.asarray(self.node(j, k).delta, dtype=float)
            if self.h_ps[k] != h:  # rotate the node's arms onto the ridge at h before adding it
                node = shift_rows(node, self._ridge(h) - self._ridge(float(self.h_ps[k])))
            delta += w * node
        prefix = "wake" if self.variant == "compromise" else self.variant
        prov = {**first.provenance, "family": {
            "variant": self.variant, "interpolation": "Lagrange-4 in ln M; ridge-aligned Lagrange-4 in H/r",
            "nodes": [[float(self.masses[j]), float(self.h_ps[k]), w] for j, k, w in terms]}}
        t = replace(first, delta=delta, mass=float(mass), h_p=h, brightness=None, provenance=prov,
                    name=template_name(float(mass), self.tau0, self.beta, "R", prefix=prefix, h_p=h))
        return t if self.hand == "R" else t.mirror()

    def __repr__(self) -> str:
        lo, hi = self.mass_range
        return (f"TemplateFamily({self.variant}, tau0={self.tau0:g}, beta={self.beta:g}, hand={self.hand}, "
                f"M_p {lo:g}-{hi:g} M_th on {self.masses.size} nodes, H/r {self.h_range[0]:g}-{self.h_range[1]:g} "
                f"on {self.h_ps.size})")
