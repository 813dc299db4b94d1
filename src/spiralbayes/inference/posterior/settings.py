"""How the posterior is sampled: :class:`SamplingSettings`, the ``[sample]`` section of the configuration."""

from __future__ import annotations

from dataclasses import dataclass

from ...exceptions import InputError
from ...settings import option
from .priors import N_DIM

__all__ = ["SamplingSettings"]


@dataclass(frozen=True)
class SamplingSettings:
    """Options of :func:`~spiralbayes.inference.posterior.sample_posterior` (TOML section ``[sample]``).

    Every field's description is its ``metadata["doc"]``; ``--print-config`` shows them.
    ``None`` means automatic (written ``0`` or ``[]`` in the TOML file).
    """

    run_name: str = option("posterior", "chains go to OUTPUT/chains/<run_name>.h5")
    n_walkers: int = option(32, "emcee walkers per template (>= 12)")
    n_steps: int | None = option(None, "total steps per walker (0: run until converged, up to max_steps)", toml=0)
    max_steps: int = option(20000, "cap on the steps per walker when running until converged")
    check_every: int = option(500, "steps between convergence checks")
    convergence: str = option("warn", "'raise', 'warn' or 'ignore' when a chain is shorter than 50 autocorrelation "
                                      "times")
    min_ess: float = option(400.0, "smallest effective sample size per parameter for convergence")
    processes: int | None = option(None, "worker processes for the walkers", toml=1)
    seed: int = option(0, "random seed of the sampler")
    prune_delta_lnL: float = option(25.0, "templates whose scan peak is this far below the best (in ln L) get a "
                                          "Laplace evidence only")
    evidence_draws: int = option(2000, "draws of the importance-sampled evidence")
    mcmc_templates: tuple | None = option(None, "names of the templates that get a chain (empty: chosen by "
                                                "prune_delta_lnL)", toml=[])
    flush_every: int = option(100, "steps between atomic writes of the chain file (a kill loses at most these)")
    planet_prior: float = option(0.5, "prior probability that the disc hosts a planet (against the no-planet "
                                      "hypothesis)")
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
        if self.convergence not in ("warn", "raise", "ignore"):
            raise InputError(f"convergence = {self.convergence!r}: use 'warn', 'raise' or 'ignore'")
        if self.n_walkers < 2 * N_DIM:
            raise InputError(f"n_walkers = {self.n_walkers}: emcee needs at least 2 x {N_DIM} = {2 * N_DIM} walkers")
        if self.n_steps is not None and self.n_steps < 1:
            raise InputError(f"n_steps = {self.n_steps} must be a positive number of steps")
        if not 0.0 < float(self.planet_prior) < 1.0:
            raise InputError(f"planet_prior = {self.planet_prior!r} must lie strictly between 0 and 1")
        if int(self.flush_every) < 1:
            raise InputError(f"flush_every = {self.flush_every!r} must be a positive number of steps")
