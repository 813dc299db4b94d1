"""The disc's physics given a planet: ``P(H/r, p, α, age, M_p | data)`` on a fine lattice of a learned model.

A learned model (:class:`~spiralbayes.templates.learned.LearnedTemplateModel`) predicts a template at
any aspect ratio ``h_p = H/r``, surface-density slope ``p``, viscosity ``α``, age and mass, so the
posterior of those parameters need not stop at a bank's few values. :func:`physics_posterior`
predicts the templates on a lattice (by default ``H/r`` every 0.005 across the model's box, the
learned bank's slopes and viscosities, ages 20, 200 and 1000 orbits, 12 masses), scans them, and reads each
template's Bayes factor against no planet from the scan's terms (:func:`~.position.position_ln_bayes`: the
amplitude integrated over its prior, ``ln L`` interpolated between the scanned positions and
``(r_p, φ_p)`` integrated over the prior, at the scan's geometry). With uniform priors in ``H/r``, ``p``,
``log10 α``, ``ln age``, ``ln M_p`` and the hand, each lattice value stands for the interval of
values nearest to it (half intervals at the ends), and

    P(cell | data, planet) ∝ prior mass of the cell × B(template at the cell's value),

i.e. the posterior density is taken constant across a cell. :class:`PhysicsPosterior` gives the
marginals, draws from that piecewise-uniform density, and the medians and credible intervals of
every parameter (also ``M_p`` in M_Jup, each draw converted with its own ``H/r``; the template
mismatch's scatter in ``ln M_p`` and the stellar mass's prior as in :class:`~.mass.MassPrior`).

The slope, viscosity and age intervals are the posterior of the model's templates, and the templates are not
the planet: on held-out hydrodynamic planets (``tests/inference/posterior/test_physics_held_out.py``) H/r fell
inside its interval in every case measured and M_p in all but one (a viscosity beyond the training runs'), the
slope and viscosity in only some, and the summary says so. What it leaves out, stated: the geometry is the
scan's, not integrated (``sample_posterior`` does that, for the bank's discs); a credible interval narrower
than about three lattice steps is not resolved (:meth:`PhysicsPosterior.resolved` says so, and the summary
asks for a finer lattice around the peak, ``h_p=np.arange(...)``); and a position grid too coarse for the
planet's likelihood peak is detected by comparing with every other radius and azimuth
(:meth:`PhysicsPosterior.position_resolved`) and refined around the peak (``refine``,
:mod:`~spiralbayes.inference.posterior.position`).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.special import logsumexp

from ..._provenance import provenance_record
from ...exceptions import InputError
from ...results import ResultMixin
from ...units import M_JUP, M_SUN
from .mass import MassPrior
from .priors import Priors
from .position import REFINE_LN_B_RANGE, PositionLevel, composite_ln_bayes, grid_log_likelihood, peak_window
from .scan_evidence import _nearest_cells

__all__ = ["DEFAULT_AGES", "DEFAULT_H_STEP", "DEFAULT_N_MASSES", "DEFAULT_REFINE", "GRID_FACTOR", "PHYSICS_AXES",
           "RESOLUTION_TOLERANCE", "PhysicsPosterior", "default_ages", "physics_posterior"]

log = logging.getLogger(__name__)

PHYSICS_AXES = ("h_p", "slope", "alpha", "orbits", "mass")
"""The lattice's axes, in the order of a :class:`PhysicsPosterior`'s ``ln_bayes`` (the hand between
``orbits`` and ``mass``)."""

_PRIOR_COORDINATE: dict[str, tuple[Callable, Callable]] = {
    "h_p": (np.asarray, np.asarray), "slope": (np.asarray, np.asarray), "alpha": (np.log10, lambda c: 10.0 ** c),
    "orbits": (np.log, np.exp), "mass": (np.log, np.exp)}
"""Each axis's coordinate in which its prior is uniform (forward, inverse)."""

DEFAULT_H_STEP = 0.005
"""Step of the default ``H/r`` lattice (across the model's training box)."""

DEFAULT_N_MASSES = 12
"""Log-spaced masses of the default lattice over the mass prior's range."""

DEFAULT_AGES = (20.0, 200.0, 1000.0)
"""Ages [orbits] of the default lattice: the two the training runs hold at many masses and aspect ratios,
and the oldest (a planet's age moves its H/r and mass in the posterior, and a planet between two of
these ages is fitted by the nearer one's templates at a shifted H/r unless the lattice brackets it)."""

GRID_FACTOR = 4
"""The scan's default position grid here is this many times finer in r_p and φ_p than the scan's own
default (:class:`~spiralbayes.inference.scan.ScanSettings`: 100 radii and 360 azimuths). A strong
planet's likelihood peak can be narrower than the scan's default cells, and then a change of ``H/r``
(which turns the arms) trades against the grid's azimuth offsets, so that the lattice's ``ln B`` jumps
from one ``H/r`` to the next; :func:`~.position.position_ln_bayes` interpolates ``ln L`` between the cells, which
needs the cells to be no wider than about the peak."""

RESOLUTION_TOLERANCE = 0.1
"""Largest total-variation distance between the ``H/r`` (and mass) marginals from the scan's grid and
from every other radius and azimuth of it for which the position grid counts as resolved. Measured on
a planet planted at H/r 0.0725 in the tests' weak observation (χ² 400): 0.55 from 16 radii over
0.2–0.5″ and 90 azimuths (whose H/r marginal is off by 0.2), 0.016 from 41 radii over 0.25–0.45″ and
360 azimuths (whose marginal agrees with 81 radii and 720 azimuths' within 0.001); 21 radii and
180 azimuths give the right marginal (within 0.02) but are flagged, their half grid being the first's."""

DEFAULT_REFINE = 3
"""How many times :func:`physics_posterior` may refine the position grid around the peak by default."""


def _cell_log_mass(values: np.ndarray, axis: str) -> np.ndarray:
    """``ln`` of each lattice value's share of a prior uniform in the axis's coordinate between the ends."""
    if values.size == 1:
        return np.zeros(1)
    c = _PRIOR_COORDINATE[axis][0](values)
    edges = _nearest_cells(c, float(c[0]), float(c[-1]))
    return np.log((edges[:, 1] - edges[:, 0]) / (c[-1] - c[0]))


@dataclass(repr=False)
class PhysicsPosterior(ResultMixin):
    """``P(H/r, p, α, age, hand, M_p | data, planet)`` on a lattice (see the module docs).

    Attributes
    ----------
    h_p, slope, alpha, orbits, mass : ndarray
        The lattice's values: aspect ratio at r_p, surface-density slope ``p`` (Σ ∝ r^-p), viscosity
        α at r_p, age [orbits] and the template's mass [M_th]; each increasing.
    hands : list of str
        The hands scanned.
    ln_bayes : ndarray, shape (n_h, n_slope, n_alpha, n_orbits, n_hands, n_mass)
        ``ln B`` against no planet of the template at each lattice point (:func:`~.position.position_ln_bayes`).
    tau0 : float
        The templates' optical depth at r_p.
    ln_bayes_coarse : ndarray or None
        The same from every other radius and azimuth of the finest grid each template was scanned on
        (:meth:`position_resolved` compares them).
    mass_prior : dict
        ``MassPrior.to_dict()`` of the prior that converts masses (stellar mass, template
        mismatch).
    provenance : dict
    """

    h_p: np.ndarray
    slope: np.ndarray
    alpha: np.ndarray
    orbits: np.ndarray
    mass: np.ndarray
    hands: list
    ln_bayes: np.ndarray
    tau0: float
    ln_bayes_coarse: np.ndarray | None = None
    mass_prior: dict = field(default_factory=dict)
    provenance: dict = field(default_factory=dict)

    KIND = "spiralbayes.PhysicsPosterior"
    WHAT = "physics posterior"

    def __post_init__(self):
        for axis in PHYSICS_AXES:
            values = np.atleast_1d(np.asarray(getattr(self, axis), dtype=float))
            if values.size > 1 and not np.all(np.diff(values) > 0):
                raise InputError(f"the {axis} lattice must increase, got {values.tolist()}")
            setattr(self, axis, values)
        self.hands = [str(h) for h in self.hands]
        self.ln_bayes = np.asarray(self.ln_bayes, dtype=float)
        shape = (*(getattr(self, a).size for a in PHYSICS_AXES[:4]), len(self.hands), self.mass.size)
        if self.ln_bayes.shape != shape:
            raise InputError(f"ln_bayes has shape {self.ln_bayes.shape}, the lattice {shape}")
        if self.ln_bayes_coarse is not None:
            self.ln_bayes_coarse = np.asarray(self.ln_bayes_coarse, dtype=float).reshape(shape)

    # -- the posterior on the lattice --------------------------------------------------------------
    def _log_prior(self) -> np.ndarray:
        """``ln`` prior mass of each lattice cell (broadcastable to :attr:`ln_bayes`; sums to one)."""
        lp = np.zeros((1,) * self.ln_bayes.ndim)
        for k, axis in enumerate(PHYSICS_AXES[:4]):
            shape = [1] * lp.ndim
            shape[k] = -1
            lp = lp + _cell_log_mass(getattr(self, axis), axis).reshape(shape)
        return lp + _cell_log_mass(self.mass, "mass") - np.log(len(self.hands))

    @property
    def log_probability(self) -> np.ndarray:
        """Normalised ``ln P`` of each lattice cell (the shape of ``ln_bayes``)."""
        return self._normalised(self.ln_bayes)

    def _normalised(self, ln_bayes: np.ndarray) -> np.ndarray:
        lp = ln_bayes + self._log_prior()
        return lp - logsumexp(lp)

    def position_resolved(self) -> bool | None:
        """Whether the scan's position grid resolves the planet: the ``H/r`` and mass marginals from every
        other radius and azimuth of the finest grid differ from the full grid's by at most
        :data:`RESOLUTION_TOLERANCE` in total variation (None when not measured)."""
        if self.ln_bayes_coarse is None:
            return None
        fine, coarse = np.exp(self.log_probability), np.exp(self._normalised(self.ln_bayes_coarse))
        for k in (0, 5):
            other = tuple(i for i in range(fine.ndim) if i != k)
            if 0.5 * np.abs(fine.sum(axis=other) - coarse.sum(axis=other)).sum() > RESOLUTION_TOLERANCE:
                return False
        return True

    @property
    def ln_bayes_factor(self) -> float:
        """``ln B`` of a planet (anywhere on the lattice, with the priors above) against none."""
        return float(logsumexp(self.ln_bayes + self._log_prior()))

    def marginal(self, axis: str) -> dict:
        """``{value: P(value | data, planet)}`` of one axis (or ``"hand"``), summed over the others."""
        p = np.exp(self.log_probability)
        if axis == "hand":
            return {h: float(x) for h, x in zip(self.hands, p.sum(axis=(0, 1, 2, 3, 5)))}
        k = self._axis(axis)
        other = tuple(i for i in range(p.ndim) if i != k)
        return {float(v): float(x) for v, x in zip(getattr(self, axis), p.sum(axis=other))}

    def _axis(self, axis: str) -> int:
        if axis not in PHYSICS_AXES:
            raise InputError(f"unknown axis {axis!r}: choose from {', '.join(PHYSICS_AXES)} or 'hand'")
        return PHYSICS_AXES.index(axis) + (1 if axis == "mass" else 0)

    def draw(self, n: int = 20000, seed: int = 0) -> dict:
        """``n`` draws from the piecewise-uniform posterior.

        Returns
        -------
        dict
            ``h_p``, ``slope``, ``alpha``, ``orbits``, ``template_mass`` [M_th] (uniform within each
            drawn cell in the prior's coordinate), ``hand``, and the planet's ``M_p`` [M_th] (the
            template's, scattered by the template mismatch) and ``M_p_MJup`` [M_Jup] (converted with
            each draw's own ``H/r`` and a stellar mass drawn from its prior).
        """
        rng = np.random.default_rng(seed)
        p = np.exp(self.log_probability).ravel()
        cells = np.unravel_index(rng.choice(p.size, size=int(n), p=p / p.sum()), self.ln_bayes.shape)
        out: dict = {}
        for axis, index in zip(PHYSICS_AXES[:4] + ("mass",), (*cells[:4], cells[5])):
            values = getattr(self, axis)
            fwd, inv = _PRIOR_COORDINATE[axis]
            if values.size == 1:
                out[axis] = np.full(int(n), values[0])
                continue
            c = fwd(values)
            edges = _nearest_cells(c, float(c[0]), float(c[-1]))[index]
            out[axis] = inv(edges[:, 0] + (edges[:, 1] - edges[:, 0]) * rng.uniform(size=int(n)))
        out["template_mass"] = out.pop("mass")
        out["hand"] = np.asarray(self.hands)[cells[4]]
        prior = MassPrior.from_metadata(self.mass_prior) if self.mass_prior else MassPrior()
        mass = out["template_mass"] * np.exp(prior.systematic * rng.standard_normal(int(n)))
        out["M_p"] = mass
        out["M_p_MJup"] = mass * out["h_p"] ** 3 * prior.draw_mstar(int(n), rng) * M_SUN / M_JUP
        return out

    def intervals(self, level: float = 0.95, n: int = 20000, seed: int = 0) -> dict:
        """Median and central credible interval of every parameter.

        Returns
        -------
        dict
            ``{name: {"median", "lo", "hi"}}`` for ``h_p``, ``slope``, ``alpha``, ``orbits``,
            ``template_mass``, ``M_p`` [M_th] and ``M_p_MJup``; ``lo``/``hi`` the ``(1 ∓ level)/2``
            quantiles.
        """
        if not 0 < level < 1:
            raise InputError(f"credible level must be in (0, 1), got {level!r}")
        d = self.draw(n, seed)
        q = [0.5 * (1 - level), 0.5, 0.5 * (1 + level)]
        return {k: dict(zip(("lo", "median", "hi"), (float(x) for x in np.quantile(v, q))))
                for k, v in d.items() if k != "hand"}

    def resolved(self, axis: str, level: float = 0.95) -> bool:
        """Whether the ``level`` interval of ``axis`` spans at least three lattice steps (else the lattice,
        not the data, sets its width); True for an axis with one value (nothing to resolve)."""
        values = getattr(self, PHYSICS_AXES[self._axis(axis) - (axis == "mass")])
        if values.size == 1:
            return True
        fwd = _PRIOR_COORDINATE[axis][0]
        c = fwd(values)
        ci = self.intervals(level)["template_mass" if axis == "mass" else axis]
        return bool(fwd(ci["hi"]) - fwd(ci["lo"]) >= 3 * float(np.median(np.diff(c))) * (1 - 1e-9))

    @property
    def best(self) -> dict:
        """The most probable lattice point (``h_p``, ``slope``, ``alpha``, ``orbits``, ``hand``, ``mass``)."""
        idx = np.unravel_index(int(np.argmax(self.log_probability)), self.ln_bayes.shape)
        point = {a: float(getattr(self, a)[i]) for a, i in zip(PHYSICS_AXES[:4], idx[:4])}
        return {**point, "hand": self.hands[idx[4]], "mass": float(self.mass[idx[5]])}

    def summary(self, level: float = 0.95) -> str:
        ci = self.intervals(level)
        pct = f"{100 * level:g} %"
        lines = [f"Physics posterior given a planet ({self.ln_bayes.size} templates, τ0 = {self.tau0:g}; "
                 f"ln B = {self.ln_bayes_factor:.1f} against no planet):"]
        units = {"h_p": "H/r", "slope": "slope p", "alpha": "alpha", "orbits": "age [orbits]",
                 "M_p": "M_p [M_th]", "M_p_MJup": "M_p [M_Jup]"}
        for key, label in units.items():
            axis = {"M_p": "mass", "M_p_MJup": "mass"}.get(key, key)
            values = getattr(self, axis)
            c = ci[key]
            if key in PHYSICS_AXES and values.size == 1:
                lines.append(f"  {label} = {values[0]:.3g} (fixed)")
                continue
            text = f"  {label} = {c['median']:.3g} ({pct}: {c['lo']:.3g}-{c['hi']:.3g})"
            if key in PHYSICS_AXES:
                text += f", prior {values[0]:.3g}-{values[-1]:.3g}"
                if not self.resolved(key, level):
                    text += " - narrower than 3 lattice steps: scan a finer lattice around it"
            lines.append(text)
        lines.append(f"  P(right-handed) = {self.marginal('hand').get('R', 0.0):.3f}")
        if any(getattr(self, a).size > 1 for a in ("slope", "alpha", "orbits")):
            lines.append("  The slope, alpha and age are those of the templates that fit best: on held-out "
                         "hydrodynamic planets their intervals missed the truth in several cases where H/r and M_p "
                         "held (docs/templates.md), so read them as the spiral's morphology, not as measurements.")
        if self.position_resolved() is False:
            lines.append("  The scan's position grid does not resolve the planet (every other radius and azimuth "
                         "give other marginals): scan with more radii and azimuths (n_r_p, n_phi_p, r_p).")
        return "\n".join(lines)

    def plot(self, axes: Sequence[str] = ("h_p", "slope", "alpha", "mass")):
        """The marginal densities of ``axes`` (per unit of each prior's coordinate), one panel each.

        Returns
        -------
        matplotlib.figure.Figure
        """
        import matplotlib.pyplot as plt

        axes = [a for a in axes if getattr(self, a).size > 1]
        fig, panels = plt.subplots(1, max(len(axes), 1), figsize=(3.2 * max(len(axes), 1), 2.8), squeeze=False)
        labels = {"h_p": "H/r", "slope": "slope p", "alpha": r"$\alpha$", "orbits": "age [orbits]",
                  "mass": r"template $M_p$ [$M_{\rm th}$]"}
        for ax, axis in zip(panels[0], axes):
            values = getattr(self, axis)
            c = _PRIOR_COORDINATE[axis][0](values)
            edges = _nearest_cells(c, float(c[0]), float(c[-1]))
            prob = np.array(list(self.marginal(axis).values()))
            density = prob / (edges[:, 1] - edges[:, 0])
            inv = _PRIOR_COORDINATE[axis][1]
            ax.stairs(density, inv(np.append(edges[:, 0], edges[-1, 1])), fill=True, alpha=0.6)
            if axis in ("alpha", "mass", "orbits"):
                ax.set_xscale("log")
            ax.set_xlabel(labels[axis])
            ax.set_yticks([])
        panels[0][0].set_ylabel("posterior density")
        fig.tight_layout()
        return fig

    def __repr__(self) -> str:
        b = self.best
        return (f"PhysicsPosterior({self.ln_bayes.size} templates; best H/r {b['h_p']:g}, p {b['slope']:g}, "
                f"alpha {b['alpha']:.2g}, {b['orbits']:g} orbits, {b['mass']:.3g} M_th, hand {b['hand']})")


def default_ages(model) -> tuple[float, ...]:
    """The ages of :data:`DEFAULT_AGES` inside ``model``'s training box (its oldest age if none is):
    a model trained on younger runs gets the lattice it can predict, as the default H/r lattice spans
    only the box."""
    lo, hi = model.bounds["orbits"]
    inside = tuple(a for a in DEFAULT_AGES if lo * (1 - 1e-9) <= a <= hi * (1 + 1e-9))
    return inside or (float(hi),)


def _lattice(name: str, values) -> np.ndarray:
    out = np.unique(np.atleast_1d(np.asarray(values, dtype=float)))
    if out.size == 0 or not np.all(np.isfinite(out)):
        raise InputError(f"{name}: give finite values, got {values!r}")
    return out


def physics_posterior(vis, axisymmetric, model, tau0: float, *, h_p=None, slope=None, alpha=None, orbits=None,
                      masses=None, hands: Sequence[str] = ("R", "L"), priors: Priors | None = None,
                      mass_prior: MassPrior | None = None, geometry=None, r_p=None, cache_dir=None,
                      refine: int = DEFAULT_REFINE, progress: bool = True, **scan_overrides) -> PhysicsPosterior:
    """The posterior of the disc's physics and the planet's mass on a lattice of a learned model.

    Parameters
    ----------
    vis : Visibilities
    axisymmetric : AxisymmetricModel
        The frank fit (as for :func:`~spiralbayes.inference.scan.scan`).
    model : LearnedTemplateModel
    tau0 : float
        Optical depth at r_p of the templates.
    h_p : array_like, optional
        Aspect ratios ``H/r`` at r_p; default every :data:`DEFAULT_H_STEP` across the model's box.
    slope, alpha : array_like, optional
        Surface-density slopes and viscosities α; default the learned bank's
        (:data:`~spiralbayes.templates.learned.bank.DEFAULT_SLOPES`, ``DEFAULT_ALPHAS``). One value fixes a
        parameter.
    orbits : array_like, optional
        Ages [orbits]; default :func:`default_ages` (:data:`DEFAULT_AGES` inside the model's box).
    masses : array_like, optional
        Template masses [M_th]; default :data:`DEFAULT_N_MASSES` log-spaced over ``mass_prior``'s range.
    hands : sequence of {'R', 'L'}
    priors : Priors, optional
        The r_p range and amplitude prior (default ``Priors.default(axisymmetric)``).
    mass_prior : MassPrior, optional
        Its mass range sets the default masses; its stellar mass and template-mismatch scatter convert
        the draws (default :class:`~.mass.MassPrior`).
    geometry : DiscGeometry, optional
        The scan's geometry (default the frank fit's).
    r_p : array_like, optional
        Scanned planet radii [arcsec] (default the scan's data-driven grid).
    cache_dir : path, optional
        Where the lattice's templates are cached (:func:`~spiralbayes.templates.learned.learned_bank`).
    refine : int
        While the position grid does not resolve the planet (:meth:`PhysicsPosterior.position_resolved`),
        up to this many times rescan the templates that matter on twice the radii and azimuths around the
        likelihood's peak (:mod:`~spiralbayes.inference.posterior.position`); 0 never.
    progress : bool
        Progress bars for the predictions and the scan.
    **scan_overrides
        Fields of :class:`~spiralbayes.inference.scan.ScanSettings` (e.g. ``n_phi_p=60``).

    Returns
    -------
    PhysicsPosterior

    Raises
    ------
    InputError
        A lattice value outside the model's training box (the message names it), or an empty lattice.
    """
    from ...templates.learned import DEFAULT_ALPHAS, DEFAULT_SLOPES, learned_bank
    from ..scan.run import scan
    from ..scan.settings import ScanSettings

    t0 = time.perf_counter()
    mass_prior = mass_prior or MassPrior()
    if h_p is None:
        lo, hi = model.bounds["h_p"]
        h_p = np.round(np.arange(np.ceil(lo / DEFAULT_H_STEP - 1e-9), np.floor(hi / DEFAULT_H_STEP + 1e-9) + 1)
                       * DEFAULT_H_STEP, 6)
    if masses is None:
        masses = np.geomspace(mass_prior.mass_range[0], mass_prior.mass_range[1], DEFAULT_N_MASSES)
    lattice = {"h_p": _lattice("h_p", h_p), "slope": _lattice("slope", DEFAULT_SLOPES if slope is None else slope),
               "alpha": _lattice("alpha", DEFAULT_ALPHAS if alpha is None else alpha),
               "orbits": _lattice("orbits", default_ages(model) if orbits is None else orbits),
               "mass": _lattice("masses", masses)}
    hands = [str(h) for h in ([hands] if isinstance(hands, str) else hands)]
    bank = learned_bank(model, lattice["mass"], lattice["h_p"], lattice["slope"], lattice["alpha"],
                        lattice["orbits"], float(tau0), hands, cache_dir=cache_dir, progress=progress)
    default = ScanSettings()
    grid = {"n_phi_p": GRID_FACTOR * default.n_phi_p}
    if r_p is None:
        grid["n_r_p"] = GRID_FACTOR * default.n_r_p
    result = scan(vis, axisymmetric, bank, geometry, r_p=r_p, progress=progress, **{**grid, **scan_overrides})
    priors = priors or Priors.default(axisymmetric)
    r_scan = np.asarray(result.r_p, dtype=float)
    if r_scan.size < 4 or np.any(np.diff(r_scan) <= 0):
        raise InputError(f"the physics posterior needs at least 4 increasing scanned radii, got {r_scan.tolist()}")
    index = {axis: {float(v): i for i, v in enumerate(lattice[axis])} for axis in PHYSICS_AXES}
    cells = []
    for t in bank:
        point = t.provenance["learned"]["point"]
        cells.append((*(index[a][float(point[a])] for a in PHYSICS_AXES[:4]), hands.index(t.hand),
                      index["mass"][float(point["mass"])]))
    levels = [PositionLevel(r_scan, np.asarray(result.phi_p, dtype=float), (float(r_scan[0]), float(r_scan[-1])),
                            {k: grid_log_likelihood(result.cross[k], result.power[k], priors.amplitude_max)
                             for k in range(len(bank))})]
    shape = (*(lattice[a].size for a in PHYSICS_AXES[:4]), len(hands), lattice["mass"].size)
    ln_b, ln_b_coarse = np.full(shape, -np.inf), np.full(shape, -np.inf)

    def assemble(todo) -> PhysicsPosterior:
        for k in todo:
            ln_b[cells[k]] = composite_ln_bayes(levels, k, priors.r_p)
            ln_b_coarse[cells[k]] = composite_ln_bayes(levels, k, priors.r_p, half=True)
        return PhysicsPosterior(lattice["h_p"], lattice["slope"], lattice["alpha"], lattice["orbits"],
                                lattice["mass"], hands, ln_b.copy(), float(tau0), ln_b_coarse.copy(),
                                mass_prior.to_dict())

    post = assemble(range(len(bank)))
    for _ in range(int(refine)):
        if post.position_resolved():
            break
        last = levels[-1]
        log_prior = np.broadcast_to(post._log_prior(), shape)
        best = max(ln_b[cells[k]] for k in last.log_like)
        keep = [k for k in last.log_like if ln_b[cells[k]] >= best - REFINE_LN_B_RANGE]
        window = peak_window(last, {k: float(log_prior[cells[k]]) for k in keep})
        step = float(np.min(np.diff(last.r_p)))
        r_new = np.linspace(*window, 2 * max(int(round((window[1] - window[0]) / step)), 1) + 1)
        sub = scan(vis, axisymmetric, [bank[k] for k in keep], geometry, r_p=r_new, progress=progress,
                   **{**scan_overrides, "n_phi_p": 2 * last.phi_p.size})
        levels.append(PositionLevel(r_new, np.asarray(sub.phi_p, dtype=float), window,
                                    {k: grid_log_likelihood(sub.cross[j], sub.power[j], priors.amplitude_max)
                                     for j, k in enumerate(keep)}))
        log.info("physics posterior: %d templates rescanned on %d radii over %.3f-%.3f arcsec and %d azimuths",
                 len(keep), r_new.size, *window, sub.phi_p.size)
        post = assemble(keep)
    post.provenance = provenance_record(
        wall_time_s=time.perf_counter() - t0, n_templates=len(bank), scan=result.provenance.get("data_hash"),
        model_runs=len(model.run_names), r_p_prior_arcsec=list(priors.r_p), amplitude_max=priors.amplitude_max,
        position_levels=[{"n_r_p": lev.r_p.size, "n_phi_p": lev.phi_p.size, "window_arcsec": list(lev.window),
                          "n_templates": len(lev.log_like)} for lev in levels])
    log.info("physics posterior: %d templates scanned in %.0f s", len(bank), time.perf_counter() - t0)
    if post.position_resolved() is False:
        log.warning("physics posterior: the scan's position grid (%d radii, %d azimuths, %d refinements) does not "
                    "resolve the planet; scan more radii and azimuths (n_r_p, n_phi_p, r_p) or raise refine",
                    r_scan.size, levels[0].phi_p.size, len(levels) - 1)
    return post
