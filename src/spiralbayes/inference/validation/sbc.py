"""Simulation-based calibration of the posterior (Talts et al. 2018, arXiv:1804.06788).

If truths are drawn from the prior and data from the model, the rank of each truth among its
posterior samples is uniform and every central interval covers the truth at its nominal rate.
:func:`run_dataset` does one such round trip with the package's own pieces — draw a planet
(``r_p``, ``phi_p``, ``A``) and geometry offsets from the priors the inference uses, simulate an
observation of a preset (:func:`spiralbayes.simulate.simulate_observation`), fit frank **at the
nominal geometry** (so the profile starts from a wrong geometry, as in Stevenson et al. 2024,
App. A), sample, and record ranks, interval coverage and ``P(planet | data)``; planet-free
datasets (``planet=False``) record ``P(planet | data)`` only. :func:`summarise` turns records into
coverage with binomial errors and rank histograms. ``benchmarks/bench_sbc.py`` runs it at
scale; ``tests/inference/test_sbc.py`` runs a small version.

With ``mass="continuous"`` the planet's mass is drawn too, log-uniform over ``mass_range``, the
spiral planted is the template family's at that mass (:class:`~spiralbayes.templates.family.TemplateFamily`,
the model the inference uses) and the posterior samples ``M_p`` with the rest
(:mod:`~spiralbayes.inference.posterior.mass`); ranks and coverage then include ``M_p``.

What is *not* drawn from the prior: the disc profile (a fixed power-law disc, not a draw from
frank's Gaussian process — it is integrated out, and the data pin it) and the template (one known
template). Geometry prior: inclination and PA within a few degrees and the phase centre within
~10 mas of the nominal values (the ranges of App. A), as Gaussians of widths ``widths``.
"""

from __future__ import annotations

import logging
import time
import warnings
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ...axisymmetric import fit_axisymmetric
from ...geometry import DiscGeometry
from ...settings import DEFAULT_DISTANCE_PC
from ...units import TWO_PI, wrap_angle
from ..posterior.likelihood import DEFAULT_AMPLITUDE_MAX
from ..posterior.priors import Priors
from ..posterior.results import MASS_SAMPLE_NAMES, SAMPLE_NAMES, wrap_phi
from ..posterior.sampler import sample_posterior

__all__ = ["CalibrationSetup", "draw_truth", "run_dataset", "summarise"]

log = logging.getLogger(__name__)


@dataclass
class CalibrationSetup:
    """What every dataset shares (all angles in degrees, offsets and radii in arcsec)."""

    preset: str = "fiducial"
    nominal: tuple = (30.0, 60.0, 0.0, 0.0)
    widths: dict = field(default_factory=lambda: {"inc": 1.5, "PA": 1.5, "dRA": 0.005, "dDec": 0.005})
    r_p: tuple = (0.1, 0.5)
    amplitude_max: float = DEFAULT_AMPLITUDE_MAX
    template: tuple = (1.0, 3.0, 10.0, "R")
    distance: float = DEFAULT_DISTANCE_PC
    frank: dict = field(default_factory=lambda: {"N": 200, "Rmax": 1.2})
    sampler: dict = field(default_factory=lambda: {"n_walkers": 24, "n_steps": 600, "evidence_draws": 800})
    mass: str = "bank"
    mass_range: tuple = (0.1, 3.0)
    n_mass_nodes: int | None = None

    def priors(self) -> Priors:
        g, w = self.nominal, self.widths
        return Priors(self.r_p, (g[0], w["inc"]), (g[1], w["PA"]), (g[2], w["dRA"]), (g[3], w["dDec"]),
                      self.amplitude_max)

    def make_template(self):
        from ...templates import make_template

        return make_template(*self.template)

    def family(self, template=None):
        """The template's family over ``mass_range`` (``mass="continuous"``) on ``n_mass_nodes`` nodes
        (default :data:`~spiralbayes.templates.family.N_MASS_NODES`). The data are planted from this
        family, so calibration holds for any node count; fewer nodes make fewer tables."""
        from ..posterior.mass import family_of

        return family_of(template or self.make_template(), tuple(self.mass_range), self.n_mass_nodes)

    def mass_prior(self):
        from ..posterior.mass import MassPrior

        # The data come from the family itself: no template mismatch to allow for.
        return MassPrior(tuple(self.mass_range), mstar_sigma=0.0, systematic=0.0)


def draw_truth(setup: CalibrationSetup, rng, planet: bool = True) -> dict:
    """Truth from the inference priors (``A = 0`` and no planet position when ``planet`` is False)."""
    priors = setup.priors()
    truth = {"inc": rng.normal(*priors.inc), "PA": rng.normal(*priors.PA), "dRA": rng.normal(*priors.dRA),
             "dDec": rng.normal(*priors.dDec)}
    if planet:
        truth.update(r_p=rng.uniform(*priors.r_p), phi_p=rng.uniform(0.0, TWO_PI),
                     A=rng.uniform(0.0, setup.amplitude_max))
        if setup.mass == "continuous":
            truth["M_p"] = float(np.exp(rng.uniform(*np.log(setup.mass_range))))
    else:
        truth.update(r_p=None, phi_p=None, A=0.0)
    return {k: (None if v is None else float(v)) for k, v in truth.items()}


def _simulate(setup: CalibrationSetup, truth: dict, template, coverage, seed: int):
    from ...simulate import DiscModel, simulate_observation

    geometry = DiscGeometry(truth["inc"], truth["PA"], truth["dRA"], truth["dDec"])
    disc = DiscModel(distance=setup.distance, tau_ref=setup.template[1])
    perturbation: Callable[[Any, Any], Any] | None = None
    if truth["A"] > 0:
        A, r_p, phi_p = truth["A"], truth["r_p"], truth["phi_p"]

        def planet(r, phi):
            return A * template.evaluate(r, phi, r_p, phi_p)
        perturbation = planet
    return simulate_observation(setup.preset, disc, geometry, perturbation, seed=seed, coverage=coverage)


def ranks(samples: np.ndarray, truth: dict) -> dict:
    """Fraction of posterior samples below the truth, per parameter (``phi_p`` on the circle)."""
    wrapped, mu = wrap_phi(samples)
    out = {}
    names = MASS_SAMPLE_NAMES if samples.shape[1] == len(MASS_SAMPLE_NAMES) else SAMPLE_NAMES
    for j, name in enumerate(names):
        t = truth.get(name)
        if t is None:
            continue
        if name == "phi_p":
            t = wrap_angle(t, mu - np.pi)
        out[name] = float(np.mean(wrapped[:, j] < t))
    return out


def run_dataset(setup: CalibrationSetup, index: int, workdir, *, planet: bool = True, coverage=None,
                template=None, seed: int = 0, processes: int | None = None, family=None) -> dict:
    """One round trip (see the module docs); returns a JSON-able record. ``family``: the template's
    family when ``setup.mass`` is ``"continuous"`` (made from ``template`` when not given)."""
    t0 = time.perf_counter()
    rng = np.random.default_rng([seed, index, int(planet)])
    truth = draw_truth(setup, rng, planet)
    template = template or setup.make_template()
    continuous = setup.mass == "continuous"
    if continuous:
        family = family or setup.family(template)
    planted = family.at(truth["M_p"]) if continuous and planet else template
    vis = _simulate(setup, truth, planted, coverage, seed=int(rng.integers(2 ** 31)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = fit_axisymmetric(vis, DiscGeometry(*setup.nominal), progress=False, **setup.frank)
    t_fit = time.perf_counter() - t0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = sample_posterior(vis, model, [family if continuous else template], priors=setup.priors(),
                                  run_name=f"d{index:03d}_{int(planet)}",
                                  chains_dir=Path(workdir), convergence="ignore", progress=False,
                                  seed=int(rng.integers(2 ** 31)), processes=processes, mass=setup.mass,
                                  mass_prior=setup.mass_prior() if continuous else None, **setup.sampler)
    if result is None:  # an MPI worker rank (pool="mpi" in setup.sampler) has no result to record
        raise RuntimeError("sample_posterior returned no result, as on an MPI worker rank")
    run = result.runs[0]
    r = ranks(run.samples, truth)
    record = {"index": index, "planet": planet, "truth": truth, "ranks": r,
              "inside68": {k: bool(abs(v - 0.5) < 0.34) for k, v in r.items()},
              "inside95": {k: bool(abs(v - 0.5) < 0.475) for k, v in r.items()},
              "p_planet": result.p_planet, "ln_bayes_factor": result.ln_bayes_factor,
              "tau_max": run.diagnostics.get("tau_max"), "converged": run.diagnostics.get("converged"),
              "n_vis": int(vis.n), "time_fit_s": t_fit, "time_s": time.perf_counter() - t0}
    log.info("dataset %d (%s): P(planet) = %.3g, ranks %s, %.0f s", index, "planet" if planet else "no planet",
             result.p_planet, {k: round(v, 2) for k, v in r.items()}, record["time_s"])
    return record


def summarise(records: list, bins: int = 5) -> dict:
    """Coverage of the 68 % and 95 % intervals (with binomial errors) and rank histograms per parameter;
    ``P(planet | data)`` of the planet-free datasets."""
    planets = [r for r in records if r["planet"]]
    table = {}
    for name in (*SAMPLE_NAMES, "M_p"):
        rk = np.array([r["ranks"][name] for r in planets if name in r["ranks"]])
        n = rk.size
        if n == 0:
            continue
        row: dict[str, Any] = {"n": int(n)}
        for level, key in ((0.68, "inside68"), (0.95, "inside95")):
            k = sum(r[key][name] for r in planets if name in r[key])
            p = k / n
            row[f"coverage{int(level * 100)}"] = p
            row[f"coverage{int(level * 100)}_err"] = float(np.sqrt(max(level * (1 - level), 1e-12) / n))
        row["rank_histogram"] = np.histogram(rk, bins=bins, range=(0, 1))[0].tolist()
        table[name] = row
    nulls = [r for r in records if not r["planet"]]
    return {"parameters": table, "null_p_planet": [r["p_planet"] for r in nulls],
            "planet_p_planet": [(r["truth"]["A"], r["p_planet"]) for r in planets]}


def setup_dict(setup: CalibrationSetup) -> dict:
    return asdict(setup)
