"""Move mixtures compared on a surrogate of real posteriors: how many steps each chain needs to stop.

A real chain costs minutes per run and its stopping step scatters by a flush or two, so comparing
move mixtures on it needs many runs. This benchmark fits a cheap stand-in instead: one normal to a
template's converged chain and a two-component normal mixture (EM) to its continuous-mass family's
(whose ``lnM_p`` has two close modes), then runs emcee on them with each mixture, ``--seeds`` times,
under the package's convergence test (every parameter longer than 50 tau, ESS >= 400) checked every
100 steps from ``--first-check`` on. It prints the mean stopping step with its standard error, the
largest tau and the acceptance. The first rows (DE alone, checks from 1000) are the ones to hold
against the real chains' stopping steps and acceptance.

    python benchmarks/bench_sample.py --skip-likelihood --skip-build --mass   # writes the chains
    python benchmarks/bench_moves.py bench_sample_output/chains
"""

from __future__ import annotations

import argparse
from pathlib import Path

import emcee
import h5py
import numpy as np
from scipy.special import logsumexp
from scipy.stats import multivariate_normal

from spiralbayes.inference.posterior import EnsembleGaussianMove, WrappedDEMove, convergence_diagnostics, default_moves


class NormalMixture:
    """A normal mixture fitted by expectation-maximisation (vectorised ``log_prob`` for emcee)."""

    def __init__(self, x: np.ndarray, k: int, iterations: int = 200, seed: int = 0):
        rng = np.random.default_rng(seed)
        n, d = x.shape
        self.mu = x[rng.choice(n, k, replace=False)]
        self.cov = np.array([np.cov(x, rowvar=False)] * k)
        self.w = np.full(k, 1.0 / k)
        for _ in range(iterations):
            resp = np.exp(self._components(x) - self.log_prob(x)[:, None])
            nk = resp.sum(axis=0)
            self.w, self.mu = nk / n, (resp.T @ x) / nk[:, None]
            self.cov = np.array([((x - m).T * r) @ (x - m) / s for m, r, s in zip(self.mu, resp.T, nk)])

    def _components(self, q):
        return np.column_stack([np.log(w) + multivariate_normal.logpdf(q, m, c)
                                for w, m, c in zip(self.w, self.mu, self.cov)])

    def log_prob(self, q):
        return logsumexp(self._components(np.atleast_2d(q)), axis=1)


def chain_samples(path: Path, burn: int = 300) -> np.ndarray:
    """The chain of the one template or family group in a ``sample_posterior`` chain file, burn-in dropped."""
    with h5py.File(path, "r") as f:
        group = next(k for k in f if not k.startswith("__"))
        chain = f[group]["chain"][:]
    return chain[burn:].reshape(-1, chain.shape[2])


def stopping_step(target: NormalMixture, samples, moves, seed: int, first_check: int, walkers: int = 32,
                  max_steps: int = 4000) -> tuple[int, float, float]:
    rng = np.random.default_rng(seed)
    p0 = rng.multivariate_normal(samples.mean(axis=0), np.cov(samples, rowvar=False) * 0.1, walkers)
    sampler = emcee.EnsembleSampler(walkers, samples.shape[1], target.log_prob, moves=moves, vectorize=True)
    sampler.random_state = np.random.RandomState(seed).get_state()
    state, names = p0, [f"x{i}" for i in range(samples.shape[1])]
    for n in range(100, max_steps + 1, 100):
        state = sampler.run_mcmc(state, 100, progress=False)
        if n >= first_check:
            d = convergence_diagnostics(sampler.get_chain(), min_ess=400.0, names=names)
            if d["converged"]:
                return n, d["tau_max"], float(np.mean(sampler.acceptance_fraction))
    return max_steps, float("nan"), float(np.mean(sampler.acceptance_fraction))


def mixtures(planet, ndim):
    """Candidate move mixtures for a chain whose planet block is ``planet`` (geometry: 2-5)."""
    geometry, p = (2, 3, 4, 5), (1,)
    de = default_moves(p, blocks=(planet, geometry), gaussian=False)
    jumps = [(WrappedDEMove(p), 0.1), (WrappedDEMove(p, gamma0=1.0), 0.3)] + de[2:]
    rows = {"DE alone": de, "DE, 30 % mode jumps": jumps,
            "DE + emcee StretchMove": [(m, 0.7 * w) for m, w in de] + [(emcee.moves.StretchMove(), 0.3)],
            "DE + emcee DESnookerMove": [(m, 0.8 * w) for m, w in de] + [(emcee.moves.DESnookerMove(), 0.2)],
            "DE + emcee KDEMove": [(m, 0.8 * w) for m, w in de] + [(emcee.moves.KDEMove(), 0.2)],
            "DE + joint normal proposals": [(m, 0.8 * w) for m, w in de] + [(EnsembleGaussianMove(p), 0.2)],
            "default (normal proposals per block and joint)": default_moves(p, blocks=(planet, geometry))}
    if ndim == 7:
        rows["DE, lnM_p a block of its own"] = default_moves(p, blocks=((0, 1), (6,), geometry), gaussian=False)
    return rows


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("chains", type=Path, help="folder with bench_sample.py --mass's chain files")
    parser.add_argument("--seeds", type=int, default=12)
    parser.add_argument("--first-check", type=int, default=300, help="first convergence check [steps]")
    args = parser.parse_args(argv)
    cases = [("one template", args.chains / "bench_mass_bank.h5", 1, (0, 1)),
             ("continuous-mass family", args.chains / "bench_mass_continuous.h5", 2, (0, 1, 6))]
    for label, path, k, planet in cases:
        samples = chain_samples(path)
        target = NormalMixture(samples[::4], k)
        print(f"\n{label}: {samples.shape[1]} parameters, a {k}-component normal fitted to {path.name}; "
              f"{args.seeds} seeds, 32 walkers")
        for first, rows in ((1000, {"DE alone": None}), (args.first_check, None)):
            names = rows or mixtures(planet, samples.shape[1])
            for name in names:
                out = np.array([stopping_step(target, samples, mixtures(planet, samples.shape[1])[name], s, first)
                                for s in range(args.seeds)])
                print(f"  {name:48s} checks from {first:4d}: stops at {out[:, 0].mean():6.0f} +- "
                      f"{out[:, 0].std() / np.sqrt(len(out)):3.0f} steps, largest tau {np.nanmean(out[:, 1]):5.1f}, "
                      f"acceptance {out[:, 2].mean():.3f}", flush=True)


if __name__ == "__main__":
    main()
