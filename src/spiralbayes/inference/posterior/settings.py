"""How the posterior is sampled: :class:`SamplingSettings` and :class:`PriorSettings`, the ``[sample]`` and
``[priors]`` sections of the configuration."""

from __future__ import annotations

from dataclasses import dataclass

from ..._provenance import check_output_name
from ...exceptions import InputError
from ...settings import documented, is_finite_number, is_integer, option
from ...settings import DEFAULT_MSTAR_MSUN
from .likelihood import DEFAULT_AMPLITUDE_MAX
from .mass import MASS_SYSTEMATIC, MassPrior
from .priors import DEFAULT_WIDTHS, GEOMETRY_NAMES, N_DIM, Priors

__all__ = ["MASS_MODES", "PRUNED_EVIDENCE", "CONVERGENCE_POLICIES", "PriorSettings", "SamplingSettings"]

MASS_MODES = ("bank", "continuous")
"""How the planet mass enters the posterior (``[sample] mass``)."""
PRUNED_EVIDENCE = ("scan", "laplace")
"""How a template (family) without a chain gets its evidence (``[sample] pruned_evidence``)."""

CONVERGENCE_POLICIES = ("raise", "warn", "ignore")
"""What a run does with a chain shorter than 50 autocorrelation times."""


@documented
@dataclass(frozen=True)
class SamplingSettings:
    """Options of :func:`~spiralbayes.inference.posterior.sample_posterior` (TOML section ``[sample]``).

    Every field's description is its ``metadata["doc"]``; ``help()``, the API pages and ``--print-config`` show them.
    ``None`` means automatic (written ``0`` or ``[]`` in the TOML file).
    """

    run_name: str = option("posterior", "chains go to OUTPUT/chains/<run_name>.h5")
    n_walkers: int = option(32, "emcee walkers per template (>= 12)")
    n_steps: int | None = option(None, "total steps per walker (0: run until converged, up to max_steps)", toml=0)
    max_steps: int = option(20000, "cap on the steps per walker when running until converged")
    check_every: int = option(500, "steps before the first convergence check (at twice this) and between "
                               "the stopping rule's evidence checks; every parameter's 50-tau test runs "
                               "after each flush")
    convergence: str = option("warn", "'raise', 'warn' or 'ignore' when a chain is shorter than 50 autocorrelation "
                                      "times")
    min_ess: float = option(400.0, "smallest effective sample size per parameter for convergence")
    processes: int | None = option(None, "worker processes for a template's walkers (0: one per available core, at "
                                         "most 4, forked where the platform allows (Linux), else threads; 1: none)",
                                   toml=0)
    threads: int | None = option(None, "threads evaluating the walkers where no worker processes run (0: one per "
                                       "available core, at most 4; 1: none); a count > 0 also asks for threads "
                                       "instead of the automatic worker processes", toml=0)
    seed: int = option(0, "random seed of the sampler")
    prune_delta_lnL: float = option(7.0, "templates (families) whose scan-grid evidence is this far below the "
                                         "best's (in ln) get no chain, only the evidence named by pruned_evidence")
    max_chains: int = option(3, "most templates (families) sampled by emcee, the best by scan-grid evidence; the "
                                "others get pruned_evidence")
    pruned_evidence: str = option("scan", "evidence of the templates without a chain: 'scan' (from the scan's grid, "
                                          "lowered by the median over-count measured on the sampled ones of the "
                                          "same hypothesis, never raised; milliseconds) or "
                                          "'laplace' (tables, optimum and Laplace approximation; ~20 s each)")
    evidence_draws: int = option(2000, "draws of the importance-sampled evidence")
    mcmc_templates: tuple | None = option(None, "names of the templates that get a chain (empty: chosen by "
                                                "prune_delta_lnL)", toml=[])
    flush_every: int = option(100, "steps between atomic writes of the chain file (a kill loses at most these)")
    planet_prior: float = option(0.5, "prior probability that the disc hosts a planet (against the no-planet "
                                      "hypothesis)")
    mass: str = option("bank", "'bank': every template is its own hypothesis, the mass a label; 'continuous': the "
                               "planet mass is sampled within each family (variant, tau0, beta, hand, H/r)")
    alternatives: tuple | None = option(None, "competing explanations sampled beside the planet, for the posterior "
                                              "odds P(planet), P(arc), P(ring): 'arc', 'eccentric_ring' (empty: none)",
                                        toml=[])
    stop_when_planet_free: bool = option(True, "also stop a chain once its geometry has converged and its Bayes "
                                               "factor says the planet is not preferred (ln B + 2 sigma < 1)")
    # code only: objects a TOML file cannot hold
    pool: object = option(None, "'mpi' or any object with map(); then processes is ignored", config=False)
    moves: object = option(None, "emcee moves (default: differential evolution with phi_p wrapped)", config=False)
    template_prior: object = option(None, "prior probabilities of the templates given a planet (default uniform)",
                                    config=False)
    initial: object = option(None, "explicit initial walkers, shape (n_walkers, 6), for every template",
                             config=False)
    likelihood_kwargs: object = option(None, "table settings (epsilon, rp_tolerance, oversample, cell_factor) and "
                                             "the profile grid's tolerance/order", config=False)

    def __post_init__(self):
        try:
            check_output_name(self.run_name, "run_name")
        except ValueError:
            raise InputError(f"run_name = {self.run_name!r} must be a plain name (no '/', '\\', '..' or leading "
                             "'.'): the chains stay inside their folder") from None
        if self.convergence not in CONVERGENCE_POLICIES:
            raise InputError(f"convergence = {self.convergence!r} must be one of "
                             f"{', '.join(map(repr, CONVERGENCE_POLICIES))}")
        if not is_integer(self.n_walkers) or self.n_walkers < 2 * N_DIM:
            raise InputError(f"n_walkers = {self.n_walkers!r}: emcee needs at least 2 x {N_DIM} = {2 * N_DIM} "
                             "walkers")
        if self.n_steps is not None and (not is_integer(self.n_steps) or self.n_steps < 1):
            raise InputError(f"n_steps = {self.n_steps!r} must be a positive number of steps")
        for name in ("max_steps", "check_every", "evidence_draws"):
            if not is_integer(getattr(self, name)) or getattr(self, name) < 1:
                raise InputError(f"{name} = {getattr(self, name)!r} must be an integer >= 1")
        if self.threads is not None and (not is_integer(self.threads) or self.threads < 0):
            raise InputError(f"threads = {self.threads!r} must be an integer >= 0 (0: one per available core)")
        if self.processes is not None and (not is_integer(self.processes) or self.processes < 0):
            raise InputError(f"processes = {self.processes!r} must be an integer >= 0 (0: automatic, 1: none)")
        if not is_integer(self.seed) or self.seed < 0:
            raise InputError(f"seed = {self.seed!r} must be an integer >= 0")
        if not is_finite_number(self.min_ess) or self.min_ess < 0:
            raise InputError(f"min_ess = {self.min_ess!r} must be a finite number >= 0 (0: no ESS requirement)")
        if not is_finite_number(self.prune_delta_lnL) or self.prune_delta_lnL <= 0:
            raise InputError(f"prune_delta_lnL = {self.prune_delta_lnL!r} must be a positive, finite number")
        if self.mcmc_templates is not None and (isinstance(self.mcmc_templates, str)
                                                or not all(isinstance(n, str) for n in self.mcmc_templates)):
            raise InputError(f"mcmc_templates = {self.mcmc_templates!r} must be a list of template names")
        if not 0.0 < float(self.planet_prior) < 1.0:
            raise InputError(f"planet_prior = {self.planet_prior!r} must lie strictly between 0 and 1")
        if int(self.flush_every) < 1:
            raise InputError(f"flush_every = {self.flush_every!r} must be a positive number of steps")
        if not is_integer(self.max_chains) or self.max_chains < 1:
            raise InputError(f"max_chains = {self.max_chains!r} must be an integer >= 1 (the best template is always "
                             "sampled)")
        if self.pruned_evidence not in PRUNED_EVIDENCE:
            raise InputError(f"pruned_evidence = {self.pruned_evidence!r}: choose one of {PRUNED_EVIDENCE}")
        if self.mass not in MASS_MODES:
            raise InputError(f"mass = {self.mass!r}: choose one of {MASS_MODES}")
        from .odds import check_alternatives

        object.__setattr__(self, "alternatives", check_alternatives(self.alternatives) or None)


@documented
@dataclass(frozen=True)
class PriorSettings:
    """The user's choices of the priors (TOML section ``[priors]``); :meth:`priors` makes the
    :class:`~spiralbayes.inference.posterior.Priors` of a fitted disc from them.

    The geometry priors are Gaussians centred on the disc's geometry with these widths; ``None``
    radii mean the disc's extent (written ``0`` in the TOML file).
    """

    r_p_min: float | None = option(None, "smallest planet radius [arcsec] (0: R_eff / 25 of the frank profile)",
                                   toml=0.0)
    r_p_max: float | None = option(None, "largest planet radius [arcsec] (0: R_eff, at most Rmax / 2.2)", toml=0.0)
    inc_sigma: float = option(DEFAULT_WIDTHS["inc"], "width of the Gaussian prior on the inclination [deg], "
                                                     "centred on [geometry]")
    PA_sigma: float = option(DEFAULT_WIDTHS["PA"], "width of the Gaussian prior on the position angle [deg]")
    dRA_sigma: float = option(DEFAULT_WIDTHS["dRA"], "width of the Gaussian prior on the RA offset [arcsec]")
    dDec_sigma: float = option(DEFAULT_WIDTHS["dDec"], "width of the Gaussian prior on the Dec offset [arcsec]")
    amplitude_max: float = option(DEFAULT_AMPLITUDE_MAX, "spiral amplitude A uniform on [0, amplitude_max] (A = 1: "
                                                         "the template as simulated; 0: fix A = 1)")
    mass_min: float = option(0.1, "smallest planet mass [M_th] of the log-uniform prior (mass = 'continuous')")
    mass_max: float = option(3.0, "largest planet mass [M_th] of the log-uniform prior (mass = 'continuous')")
    mstar: float = option(DEFAULT_MSTAR_MSUN, "stellar mass [M_sun]: mean of its Gaussian prior, for M_p in M_Jup")
    mstar_sigma: float = option(0.1, "fractional width of the stellar-mass prior (0: M_* fixed)")
    mass_systematic: float = option(MASS_SYSTEMATIC, "standard deviation of ln M_p between the planet and the "
                                                     "template that fits it (template mismatch; 0: none)")

    def __post_init__(self):
        if not is_finite_number(self.mass_min) or self.mass_min <= 0:
            raise InputError(f"mass_min = {self.mass_min!r} must be a positive planet mass [M_th]")
        if not is_finite_number(self.mass_max) or self.mass_max <= self.mass_min:
            raise InputError(f"mass_max = {self.mass_max!r} must be a planet mass [M_th] above mass_min = "
                             f"{self.mass_min!r}")
        if not is_finite_number(self.mstar) or self.mstar <= 0:
            raise InputError(f"mstar = {self.mstar!r} must be a positive stellar mass [M_sun]")
        self.mstar_sigma_msun  # noqa: B018 - validates mstar_sigma
        if not is_finite_number(self.mass_systematic) or self.mass_systematic < 0:
            raise InputError(f"mass_systematic = {self.mass_systematic!r} must be a standard deviation of ln M_p "
                             ">= 0 (0: the template's mass is the planet's)")
        for name in ("r_p_min", "r_p_max"):
            value = getattr(self, name)
            if value is not None and (not is_finite_number(value) or value <= 0):
                raise InputError(f"{name} = {value!r} must be a positive radius [arcsec] (or 0: the disc's extent)")
        if self.r_p_min is not None and self.r_p_max is not None and self.r_p_min >= self.r_p_max:
            raise InputError(f"r_p_min = {self.r_p_min!r} must be smaller than r_p_max = {self.r_p_max!r} [arcsec] "
                             "(or 0 for the default)")
        for name in GEOMETRY_NAMES:
            value = getattr(self, f"{name}_sigma")
            if not is_finite_number(value) or value <= 0:
                unit = "deg" if name in ("inc", "PA") else "arcsec"
                raise InputError(f"{name}_sigma = {value!r} must be a positive width [{unit}]")
        if not is_finite_number(self.amplitude_max) or self.amplitude_max < 0:
            raise InputError(f"amplitude_max = {self.amplitude_max!r} must be a finite number >= 0 (0: fix A = 1)")

    @property
    def widths(self) -> dict:
        """``{"inc": deg, "PA": deg, "dRA": arcsec, "dDec": arcsec}``: the geometry priors' sigmas."""
        return {name: float(getattr(self, f"{name}_sigma")) for name in GEOMETRY_NAMES}

    @property
    def mstar_sigma_msun(self) -> float:
        """The stellar-mass prior's standard deviation [M_sun]."""
        if not is_finite_number(self.mstar_sigma) or self.mstar_sigma < 0:
            raise InputError(f"mstar_sigma = {self.mstar_sigma!r} must be a fraction >= 0 of mstar (0: M_* fixed)")
        return float(self.mstar_sigma) * float(self.mstar)

    def mass_prior(self) -> MassPrior:
        """The :class:`~.mass.MassPrior` of a continuous-mass run."""
        return MassPrior((self.mass_min, self.mass_max), self.mstar, self.mstar_sigma_msun, self.mass_systematic)

    def priors(self, axisymmetric, *, geometry=None) -> Priors:
        """The :class:`Priors` of ``axisymmetric`` (its extent for unset radii, its geometry as the centre
        unless ``geometry`` is given)."""
        r_p = None
        if self.r_p_min is not None or self.r_p_max is not None:
            default = Priors.default(axisymmetric, geometry=geometry, widths=self.widths).r_p
            r_p = (self.r_p_min or default[0], self.r_p_max or default[1])
        return Priors.default(axisymmetric, geometry=geometry, r_p=r_p, widths=self.widths,
                              amplitude_max=self.amplitude_max or None)
