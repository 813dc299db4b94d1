"""The planet's mass as a sampled parameter: one template family with ``M_p`` continuous.

Within a family (morphology variant, τ0, β, hand and one ``H/r``) the template at any mass is a fixed
linear combination of at most four node templates (:class:`~spiralbayes.templates.family.TemplateFamily`:
Lagrange-4 interpolation in ``ln M_p``). The visibilities are linear in ``δ``, and so are the
Fourier-series tables of :mod:`.interpolation`, so for the interpolated template

    cos i P_hat(q; r_p, phi_p, M_p) = sum_j w_j(M_p) cos i P_hat_j(q; r_p, phi_p)

holds exactly: :class:`FamilyPerturbation` adds the (``r_p``-interpolated) grids of the four nodes
with their weights and evaluates the series at the data with one type-2 NUFFT — one template's call
plus three grid sums. A node's table is built the first time a walker needs it, starting its ``r_p``
refinement from the heaviest node's table, which is built first (``FastPerturbation(refine_from=...)``).

Parameters of a family run (:data:`MASS_PARAMETER_NAMES`): ``(r_p, phi_p, inc, PA, dRA, dDec,
lnM_p)``, with ``ln M_p`` uniform on ``[ln M_min, ln M_max]`` (``M_p`` log-uniform over the family's
range, by default the bank's 0.1–3 M_th). The amplitude ``A`` stays what it is for a fixed template:
integrated over its uniform prior (``[0, amplitude_max]``), or fixed at 1 when ``amplitude_max`` is
None. The samples (:data:`.results.MASS_SAMPLE_NAMES`) add ``M_p`` [M_th] and ``M_p_MJup`` [M_Jup] to the
template columns: ``M_p,Jup = M_p h_p³ M_* / M_Jup`` with ``h_p`` the family's ``H/r`` at ``r_p``
(``M_th = h_p³ M_*``) and ``M_*`` drawn for every sample from its prior
(:class:`MassPrior`: a Gaussian truncated at zero).

``M_p`` is the planet's mass, not the template's: no family is the true spiral, and a planted
hydrodynamic planet's template mass is off by more than its statistical width (docs/templates.md,
"The mass in the posterior"). The sampled coordinate ``lnM_p`` is the template's mass; each sample's
``M_p = exp(lnM_p + ε)`` with ``ε ~ N(0, σ_sys²)`` (``MassPrior.systematic``, calibrated
on planted reference spirals one source held out at a time). ``ε`` does not enter the likelihood, so
its posterior is its prior and it widens the mass only.

The template at an arbitrary mass is what the generator would make there only to the family's
interpolation accuracy (docs/templates.md, "Continuous family"); :meth:`FamilyPerturbation.exact_template`
gives the interpolated template so tests compare the fast path with a table built for it.
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass

import numpy as np

from ...exceptions import InputError
from ...geometry import DiscGeometry
from ...settings import DEFAULT_MSTAR_MSUN
from ...units import ARCSEC, M_JUP, M_SUN
from .conditional import PARAMETER_NAMES
from .forked import forked_map
from .likelihood import MarginalSpiralLikelihood
from .perturbation import FastPerturbation
from .priors import Priors

__all__ = ["MASS_PARAMETER_NAMES", "MASS_SYSTEMATIC", "FamilyPerturbation", "MassLikelihood", "MassLogPosterior",
           "MassPrior", "family_of", "group_families"]

log = logging.getLogger(__name__)

MASS_PARAMETER_NAMES = (*PARAMETER_NAMES, "lnM_p")
"""emcee's coordinates in a family run: the template's six and ``ln(M_p / M_th)``."""

MASS_SYSTEMATIC = 0.2
"""Standard deviation of ``ln M_p`` between a planet and the family template that fits it best
(template mismatch): the maximum-likelihood value over planted reference spirals from FARGO3D and
wakeflow, calibrated and checked one source held out at a time (docs/templates.md)."""


@dataclass(frozen=True)
class MassPrior:
    """Prior of the planet mass in a family run, and of the stellar mass that converts it to M_Jup.

    Parameters
    ----------
    mass_range : (float, float)
        ``M_p`` log-uniform on ``[M_min, M_max]`` [M_th]; default the bank's range.
    mstar : float
        Stellar mass [M_sun], the mean of its Gaussian prior.
    mstar_sigma : float or None
        Its standard deviation [M_sun] (truncated at zero); None: 10 % of ``mstar``, a typical
        dynamical-mass uncertainty; 0 fixes ``M_*``.
    systematic : float
        Standard deviation of ``ln M_p`` for the template mismatch (:data:`MASS_SYSTEMATIC`); 0 when
        the data were made from the family itself (simulation-based calibration).
    """

    mass_range: tuple = (0.1, 3.0)
    mstar: float = DEFAULT_MSTAR_MSUN
    mstar_sigma: float | None = None
    systematic: float = MASS_SYSTEMATIC

    def __post_init__(self):
        lo, hi = (float(m) for m in self.mass_range)
        if not (0 < lo < hi and np.isfinite(hi)):
            raise InputError(f"mass_range = {self.mass_range!r}: need 0 < M_min < M_max [M_th]")
        object.__setattr__(self, "mass_range", (lo, hi))
        if not (np.isfinite(self.mstar) and self.mstar > 0):
            raise InputError(f"mstar = {self.mstar!r} must be a positive stellar mass [M_sun]")
        if self.mstar_sigma is not None and not (np.isfinite(self.mstar_sigma) and self.mstar_sigma >= 0):
            raise InputError(f"mstar_sigma = {self.mstar_sigma!r} must be >= 0 [M_sun] (or None: 10 % of mstar)")
        if not (np.isfinite(self.systematic) and self.systematic >= 0):
            raise InputError(f"mass systematic = {self.systematic!r} must be a standard deviation of ln M_p >= 0")

    @property
    def sigma(self) -> float:
        return 0.1 * self.mstar if self.mstar_sigma is None else float(self.mstar_sigma)

    @property
    def ln_range(self) -> tuple[float, float]:
        return float(np.log(self.mass_range[0])), float(np.log(self.mass_range[1]))

    def log_prior(self, ln_mass: float) -> float:
        """Normalised log density of ``ln M_p`` (uniform; ``-inf`` outside)."""
        lo, hi = self.ln_range
        return -float(np.log(hi - lo)) if lo <= ln_mass <= hi else -np.inf

    def draw_mstar(self, n: int, rng) -> np.ndarray:
        """``n`` stellar masses [M_sun] from the prior (a Gaussian truncated at zero)."""
        if self.sigma == 0:
            return np.full(n, float(self.mstar))
        from scipy.stats import truncnorm

        a = -self.mstar / self.sigma
        return truncnorm.rvs(a, np.inf, loc=self.mstar, scale=self.sigma, size=n, random_state=rng)

    def to_mjup(self, mass_mth: np.ndarray, h_p: float, rng) -> np.ndarray:
        """Masses [M_Jup] of ``mass_mth`` [M_th] at aspect ratio ``h_p``, one ``M_*`` draw per mass."""
        mass_mth = np.asarray(mass_mth, float)
        return mass_mth * h_p ** 3 * self.draw_mstar(mass_mth.size, rng).reshape(mass_mth.shape) * M_SUN / M_JUP

    def planet_masses(self, template_mass: np.ndarray, h_p: float, rng) -> tuple[np.ndarray, np.ndarray]:
        """The planet's masses [M_th] and [M_Jup] for samples of the template's mass [M_th]: each
        scattered by the template mismatch (``systematic``), then converted at ``h_p``."""
        mass = np.asarray(template_mass, float)
        if self.systematic > 0:
            mass = mass * np.exp(self.systematic * rng.standard_normal(mass.shape))
        return mass, self.to_mjup(mass, h_p, rng)

    def to_dict(self) -> dict:
        return {"mass_range_mth": list(self.mass_range), "mass_prior": "log-uniform", "mstar_msun": self.mstar,
                "mstar_sigma_msun": self.sigma, "mass_systematic_ln": self.systematic}

    @classmethod
    def from_metadata(cls, metadata: dict) -> MassPrior:
        """The prior recorded in a family run's metadata (``to_dict``; runs written without a
        systematic had none)."""
        return cls(tuple(metadata["mass_range_mth"]), metadata["mstar_msun"], metadata["mstar_sigma_msun"],
                   metadata.get("mass_systematic_ln", 0.0))


def family_of(template, mass_range=(0.1, 3.0), n_masses: int | None = None):
    """The :class:`~spiralbayes.templates.family.TemplateFamily` of a generator, variant or learned template.

    A learned template's family is its disc's (:func:`~spiralbayes.templates.learned.family.learned_family`),
    from the model file its ``provenance["learned"]["model_file"]`` names.

    The family has the template's morphology, τ0, β, hand and ``H/r``, and the generator settings
    recorded in its provenance (grid, disc); ``template`` is checked to be what the family's node
    maker gives at its mass, so a template the generator did not make (a hydrodynamic map) is refused.
    """
    from ...templates.family import N_MASS_NODES, TemplateFamily

    prov = getattr(template, "provenance", {}) or {}
    if "learned" in prov:
        return _learned_family_of(template, prov["learned"], mass_range, n_masses or N_MASS_NODES)
    settings = dict(prov.get("settings") or {})
    if "builtin" not in str(prov.get("generator", "")) or not settings:
        raise InputError(f"template {template.name!r} was not made by the built-in generator: a continuous mass "
                         "needs a family the generator can make at any mass (pass mass='bank')")
    h_p = float(settings.pop("h_p", template.h_p))
    if "x_min" in settings and "x_max" in settings:
        settings["x_range"] = (settings.pop("x_min"), settings.pop("x_max"))
    allowed = _generator_options()
    settings = {k: v for k, v in settings.items() if k in allowed}
    variant = prov.get("variant", "compromise")
    family = TemplateFamily.build(template.tau0, template.beta, variant, template.hand, h_p=h_p,
                                  mass_range=mass_range, n_masses=n_masses or N_MASS_NODES, **settings)
    maker = family.nodes
    assert callable(maker)  # TemplateFamily.build makes nodes on demand
    made = maker(float(template.mass), h_p)
    if template.hand == "L":
        made = made.mirror()
    if made.delta.shape != np.shape(template.delta) or not np.allclose(made.delta, template.delta, rtol=1e-5,
                                                                       atol=1e-7):
        raise InputError(f"template {template.name!r}: the generator with its recorded settings does not remake it, "
                         "so its family is unknown (pass mass='bank')")
    return family


def _learned_family_of(template, learned: dict, mass_range, n_masses: int):
    """The learned model's family of ``template`` (one disc), from the model file its provenance records."""
    from ...templates.learned.family import learned_family, model_from_file

    if not learned.get("model_file"):
        raise InputError(f"template {template.name!r} was predicted by a learned model that it does not name: pass "
                         "learned_family(model, ...) for a continuous mass, or mass='bank'")
    model = model_from_file(learned["model_file"])
    point = learned["point"]
    family = learned_family(model, point["h_p"], point["slope"], point["alpha"], point["orbits"], template.tau0,
                            template.hand, mass_range=mass_range, n_masses=n_masses)
    made = model.predict(point["mass"], point["h_p"], point["slope"], point["alpha"], point["orbits"], template.tau0,
                         template.hand)
    if made.delta.shape != np.shape(template.delta) or not np.allclose(made.delta, template.delta, rtol=1e-5,
                                                                       atol=1e-6 * np.max(np.abs(made.delta))):
        raise InputError(f"template {template.name!r}: the model in {learned['model_file']} does not predict it "
                         "(another model saved under that name?); build the bank again from the model")
    return family


def _generator_options() -> set:
    import inspect

    from ...templates.generator import make_template
    from ...templates.wake import WakeSettings

    return set(inspect.signature(make_template).parameters) | set(WakeSettings.__dataclass_fields__)


class FamilyPerturbation:
    """``cos i P_hat(q; r_p, phi_p, M_p)`` at fixed baselines for a template family (module docs).

    Parameters
    ----------
    u, v, weights, profile, r_range, reference_geometry
        As :class:`~.perturbation.FastPerturbation`.
    family : TemplateFamily
        One ``H/r`` (a family spanning several is refused: ``H/r`` is not sampled).
    mirror_of : FamilyPerturbation, optional
        The same perturbation for the mirror family (other hand, same nodes, data and ``r_p``
        range): the hand-R node tables are shared, and each hand reads them with one coordinate
        flipped (:class:`~.perturbation.FastPerturbation`'s ``mirror_of``).
    **table_kwargs
        :class:`~.perturbation.FastPerturbation` settings of every node's table.
    """

    def __init__(self, u, v, weights, profile, family, r_range, reference_geometry: DiscGeometry, *,
                 progress: bool = False, mirror_of: FamilyPerturbation | None = None, **table_kwargs):
        if family.h_ps.size != 1:
            raise InputError(f"the family spans H/r {family.h_range}: a continuous-mass run samples M_p at one H/r "
                             "(build the family with a single h_p)")
        self.family = family
        self.u, self.v, self.weights, self.profile = u, v, weights, profile
        self.r_range = (float(r_range[0]), float(r_range[1]))
        self.reference_geometry = reference_geometry
        self.table_kwargs = dict(table_kwargs)
        self.progress = progress
        self.tables: dict[int, FastPerturbation] = {}
        self._lock = threading.Lock()  # walker threads (ThreadMap) reaching a new node build it once
        self._build_s: dict[int, float] = {}
        self._right: dict[int, FastPerturbation] = {}  # hand-R node tables; a mirror family shares them
        self._radial: dict = {}  # the nodes' shared radial integrals (one radial grid, one profile)
        if mirror_of is not None:
            other = mirror_of.family
            if (other.hand == family.hand or not np.array_equal(other.masses, family.masses)
                    or other.variant != family.variant or (other.tau0, other.beta) != (family.tau0, family.beta)
                    or not np.array_equal(other.h_ps, family.h_ps) or mirror_of.r_range != self.r_range
                    or mirror_of.u.size != u.size):
                raise InputError(f"{family!r} is not the mirror of {other!r} on the same data and r_p range")
            self._right, self._radial = mirror_of._right, mirror_of._radial
        self.template = family.at(float(np.sqrt(family.mass_range[0] * family.mass_range[1])))

    @property
    def mass_range(self) -> tuple[float, float]:
        return self.family.mass_range

    def _right_table(self, j: int) -> tuple[FastPerturbation, float]:
        """Node ``j``'s hand-R table (shared with a mirror family) and the seconds spent building it here."""
        if j in self._right:
            return self._right[j], 0.0
        heaviest = self.family.masses.size - 1
        if not self._right and j != heaviest:
            # every node starts its r_p refinement from the heaviest node's (the largest spiral, the
            # largest interpolation error), whichever node a walker reaches first
            self._build_s[heaviest] = self._right_table(heaviest)[1]
        first = next(iter(self._right.values()), None)
        fp = FastPerturbation(self.u, self.v, self.weights, self.profile, self.family.node(j), self.r_range,
                              self.reference_geometry, progress=self.progress, radial_cache=self._radial,
                              refine_from=first, **self.table_kwargs)
        if first is not None and (fp.table.N != first.table.N or fp._delta != first._delta):
            raise InputError("the family's node tables differ in their Fourier grids: the nodes must share "
                             "one (x, phi) grid")
        self._right[j] = fp
        return fp, fp.build_time_s

    def node_table(self, j: int) -> FastPerturbation:
        """Node ``j``'s table in the family's hand (made on first use)."""
        table = self.tables.get(j)
        if table is not None:
            return table
        with self._lock:
            if j not in self.tables:
                fp, built_s = self._right_table(j)
                if self.family.hand == "L":
                    fp = FastPerturbation(self.u, self.v, self.weights, self.profile, self.family.node(j).mirror(),
                                          self.r_range, self.reference_geometry, mirror_of=fp, **self.table_kwargs)
                by_worker = j in self._build_s  # build_nodes: its build time was recorded there
                built_s = self._build_s[j] if by_worker else built_s
                how = "built by a worker" if by_worker else "built" if built_s else "shared with the mirror family"
                log.log(logging.DEBUG if by_worker else logging.INFO,
                        "%s: table of mass node %.4g M_th %s (%.1f s; %d of %d nodes)", self.template.name,
                        self.family.masses[j], how, built_s, len(self.tables) + 1, self.family.masses.size)
                self._build_s[j] = built_s
                self.tables[j] = fp
            return self.tables[j]

    def __getstate__(self):
        state = self.__dict__.copy()
        state.pop("_lock", None)  # a lock does not pickle; each process gets its own
        state["_radial"] = {}  # large, and rebuilt where needed
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._lock = threading.Lock()

    def check_r_p(self, r_p: float) -> None:
        if not (self.r_range[0] <= r_p <= self.r_range[1]):
            raise InputError(f"r_p = {r_p} arcsec is outside the likelihood's range {self.r_range}")

    def disc_frame(self, r_p, phi_p, inc, PA, mass) -> np.ndarray:
        """``cos i P_hat`` at the data [Jy] for the template at ``mass`` [M_th] (no phase-centre factor)."""
        terms = self.family.weights(float(mass))
        scale = np.cos(np.radians(inc)) * (r_p * ARCSEC) ** 2
        first = self.node_table(terms[0][0])
        grid = first.table.grid(r_p, scale=scale * terms[0][2])  # a new array: safe to add into
        for j, _, w in terms[1:]:
            self.node_table(j).table.grid(r_p, scale=scale * w, out=grid)
        return first.u2nu(grid, first.coords(r_p, phi_p, inc, PA))

    def exact_template(self, mass: float):
        """The family's (interpolated) template at ``mass`` — the reference for :meth:`disc_frame`."""
        return self.family.at(float(mass))

    @property
    def quadrature_error(self) -> float:
        return max((fp.quadrature_error for fp in self.tables.values()), default=0.0)

    @property
    def build_time_s(self) -> float:
        return float(sum(self._build_s.values()))

    @property
    def nbytes(self) -> int:
        return int(sum(fp.nbytes for fp in self.tables.values()))

    def describe(self) -> dict:
        return {"family": repr(self.family), "r_range_arcsec": list(self.r_range),
                "mass_nodes_built": [float(self.family.masses[j]) for j in sorted(self.tables)],
                "table_bytes": self.nbytes, "build_time_s": self.build_time_s,
                "quadrature_error": self.quadrature_error}

    def build_nodes(self, mass_range: tuple[float, float] | None = None, processes: int = 1) -> int:
        """Build every node table that masses in ``mass_range`` [M_th] use (default the family's range);
        returns how many there are. Worker processes receive a copy of this object, and a table one of
        them builds stays there, so a pooled run builds them first.

        ``processes`` > 1 builds the missing hand-R tables in as many forked workers
        (:func:`.forked.forked_map`; the same tables as in this process)."""
        lo, hi = mass_range or self.family.mass_range
        needed = sorted({j for m in np.geomspace(lo, hi, 8 * self.family.masses.size)
                         for j, _, _ in self.family.weights(float(m))})
        missing = [j for j in needed if j not in self._right and j not in self.tables]
        if missing and not self._right:
            # the heaviest node, whose step the others start from, here: the workers inherit its
            # table and radial integrals
            self.node_table(self.family.masses.size - 1)
            missing = [j for j in missing if j not in self._right]
        if processes > 1 and len(missing) > 1:
            t0 = time.perf_counter()
            # the workers write each node's grids into memory shared with this process (the heaviest
            # node's shape: every node started from its step), so only small objects travel back
            # (pickling an 86 MB table through the pool cost ~0.35 s on the demo observation)
            shape = self._right[self.family.masses.size - 1].table.grids.shape
            self._shared = _shared_array((len(missing), *shape), np.complex64)
            try:
                with forked_map(self._built_right_table, processes) as build:
                    built = build(list(enumerate(missing)))
                    if self.progress:
                        from tqdm.auto import tqdm

                        built = tqdm(built, total=len(missing), desc=f"{self.template.name}: mass-node tables",
                                     unit="table", leave=False)
                    for slot, (j, fp) in enumerate(zip(missing, built)):
                        if fp.table.grids.size == 0:  # written to the shared memory
                            fp.table.grids = self._shared[slot]
                        fp.u, fp.v, fp.weights, fp.profile = self.u, self.v, self.weights, self.profile
                        self._right[j] = fp
                        self._build_s[j] = fp.build_time_s
            finally:
                del self._shared  # the tables' views keep the shared memory alive
            log.info("%s: %d mass-node tables built by %d worker processes in %.1f s", self.template.name,
                     len(missing), processes, time.perf_counter() - t0)
        for j in needed:
            self.node_table(j)
        return len(needed)

    def _built_right_table(self, item: tuple[int, int]) -> FastPerturbation:
        """In a worker: node ``j``'s table for ``item = (slot, j)``, its grids moved to ``_shared[slot]``
        when they have the shared shape (``table.grids`` is then left empty) and sent whole otherwise."""
        self.progress = False  # the parent shows one bar for all the tables
        slot, j = item
        fp = self._right_table(j)[0]
        grids = fp.table.grids
        if grids.shape == self._shared.shape[1:] and grids.dtype == self._shared.dtype:
            self._shared[slot] = grids
            fp.table.grids = grids[:0]
        return fp


def _shared_array(shape: tuple[int, ...], dtype) -> np.ndarray:
    """A zeroed array in anonymous memory shared with processes forked after it is made."""
    import mmap

    nbytes = int(np.prod(shape)) * np.dtype(dtype).itemsize
    return np.frombuffer(mmap.mmap(-1, max(nbytes, 1)), dtype=dtype, count=int(np.prod(shape))).reshape(shape)


class MassLikelihood(MarginalSpiralLikelihood):
    """:class:`~.likelihood.MarginalSpiralLikelihood` of a family: ``theta`` ends with ``ln M_p`` (7 values)."""

    def spiral_visibilities(self, theta) -> np.ndarray:
        r_p, phi_p, inc, PA, _, _, ln_mass = (float(t) for t in theta)
        return self.perturbation.disc_frame(r_p, phi_p, inc, PA, np.exp(ln_mass))


class MassLogPosterior:
    """``ln pi(theta) + ln L(theta)`` of a family run, with the amplitude terms ``(c1, c2)`` as blob."""

    def __init__(self, likelihood: MassLikelihood, priors: Priors, mass_prior: MassPrior):
        self.likelihood = likelihood
        self.priors = priors
        self.mass_prior = mass_prior

    def __call__(self, theta):
        lp = self.priors.log_prior(theta[:6]) + self.mass_prior.log_prior(float(theta[6]))
        if not np.isfinite(lp):
            return -np.inf, np.array([np.nan, np.nan])
        terms = self.likelihood.amplitude_terms(theta)
        return lp + self.likelihood.marginal(terms), np.array(terms[1:])


def group_families(templates, mass_prior: MassPrior) -> list:
    """``[(family, members), ...]``: the bank templates grouped by (variant, τ0, β, hand, H/r), each
    group's :class:`~spiralbayes.templates.family.TemplateFamily` over ``mass_prior.mass_range``.
    A ``TemplateFamily`` among ``templates`` is taken as it is (no members); its mass range must hold
    the prior's."""
    from ...templates.family import TemplateFamily

    groups: dict = {}
    out: list[tuple] = []
    for t in templates:
        if isinstance(t, TemplateFamily):
            lo, hi = mass_prior.mass_range
            if not t.mass_range[0] * (1 - 1e-9) <= lo < hi <= t.mass_range[1] * (1 + 1e-9):
                raise InputError(f"{t!r} spans {t.mass_range} M_th but the mass prior is {mass_prior.mass_range}: "
                                 "build the family over the prior's range")
            out.append((t, []))
            continue
        prov = getattr(t, "provenance", {}) or {}
        key = (prov.get("variant", "compromise"), float(t.tau0), float(t.beta), t.hand, float(t.h_p))
        groups.setdefault(key, []).append(t)
    return out + [(family_of(members[0], mass_prior.mass_range), members) for members in groups.values()]
