"""Convergence diagnostics of emcee chains: autocorrelation time first, arviz R-hat/ESS beside it.

emcee's integrated autocorrelation time ``tau`` is the primary test — chain length > 50 tau for
every parameter (after burn-in; burn-in = 5 max tau) — with ESS = n_walkers n_steps / tau. arviz's
R-hat and ESS are reported too, with the caveat that emcee's walkers are not independent chains
(R-hat near 1 is necessary, not sufficient).
"""

from __future__ import annotations

import logging
import warnings

import numpy as np

from ...exceptions import ConvergenceError, ConvergenceWarning
from .conditional import PARAMETER_NAMES

__all__ = ["TAU_FACTOR", "arviz_diagnostics", "chain_inference_data", "convergence_diagnostics"]

log = logging.getLogger(__name__)

TAU_FACTOR = 50.0


def convergence_diagnostics(chain: np.ndarray, *, tau_factor: float = TAU_FACTOR, min_ess: float = 0.0,
                            periodic=(1,), names=PARAMETER_NAMES) -> dict:
    """Autocorrelation-time diagnostics of an emcee chain of shape (n_steps, n_walkers, n_dim).

    Coordinates in ``periodic`` (``phi_p``) are angles: their ``tau`` is the larger of those of
    ``cos`` and ``sin`` (a chain that circles freely is well mixed, though its unwrapped angle
    wanders). Returns ``tau`` per parameter, ``n_steps``, ``burn_in`` (5 max tau), ``ess``
    (= n_walkers (n_steps - burn_in) / tau), ``converged`` (``n_steps > tau_factor tau`` for every
    parameter and ``ess >= min_ess``) and ``more_steps`` (a rough estimate of the extra steps
    needed; 0 when converged).
    """
    import emcee

    n_steps, n_walkers, n_dim = chain.shape
    tau = np.empty(n_dim)
    for j in range(n_dim):
        if j in periodic:
            x = chain[:, :, j]
            pair = np.stack([np.cos(x), np.sin(x)], axis=-1)
            tau[j] = float(np.max(emcee.autocorr.integrated_time(pair, tol=0, quiet=True)))
        else:
            tau[j] = float(emcee.autocorr.integrated_time(chain[:, :, j:j + 1], tol=0, quiet=True)[0])
    tau = np.where(np.isfinite(tau), tau, float(n_steps))
    tau_max = float(np.max(tau))
    burn = int(min(np.ceil(5 * tau_max), n_steps // 2))
    ess = n_walkers * (n_steps - burn) / tau
    long_enough = n_steps > tau_factor * tau
    enough_ess = ess >= min_ess
    needed = max(tau_factor * tau_max, 5 * tau_max + min_ess * tau_max / n_walkers)
    more = 0 if (long_enough.all() and enough_ess.all()) else int(np.ceil(1.2 * needed - n_steps))
    names = list(names)[:n_dim]
    return {"tau": dict(zip(names, tau.tolist())), "tau_max": tau_max, "n_steps": int(n_steps),
            "n_walkers": int(n_walkers), "burn_in": burn, "thin": max(1, int(tau_max / 2)),
            "ess": dict(zip(names, ess.tolist())), "converged": bool(long_enough.all() and enough_ess.all()),
            "tau_factor": tau_factor, "min_ess": min_ess, "more_steps": max(more, 0)}


def _convergence_message(name: str, diag: dict) -> str:
    worst = max(diag["tau"], key=diag["tau"].get)
    low_ess = min(diag["ess"], key=diag["ess"].get)
    return (f"template {name}: chain of {diag['n_steps']} steps is not converged: it needs > "
            f"{diag['tau_factor']:g} tau = {diag['tau_factor'] * diag['tau_max']:.0f} steps (largest tau = "
            f"{diag['tau_max']:.1f} for {worst!r}) and ESS >= {diag['min_ess']:g} (lowest {diag['ess'][low_ess]:.0f} "
            f"for {low_ess!r}); run about {diag['more_steps']} more steps (tau estimates grow on short chains, so "
            "maybe more)")


def _apply_policy(policy: str, message: str) -> None:
    if policy == "raise":
        raise ConvergenceError(message)
    if policy == "warn":
        warnings.warn(message, ConvergenceWarning, stacklevel=4)
    else:
        log.info(message)


def chain_inference_data(chain: np.ndarray, log_prob: np.ndarray | None = None, names=PARAMETER_NAMES):
    """arviz ``InferenceData`` of an emcee chain of shape (n_steps, n_walkers, n_dim).

    Walkers become arviz chains and steps draws (as ``arviz.from_emcee`` lays them out); the log
    posterior, when given (n_steps, n_walkers), is ``sample_stats.lp``. Caveat: emcee's walkers are
    not independent chains.
    """
    az = _import_arviz()
    chain = np.asarray(chain)
    posterior = {name: chain[:, :, j].T for j, name in enumerate(list(names)[:chain.shape[2]])}
    stats = None if log_prob is None else {"lp": np.asarray(log_prob).T}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # "more chains than draws" on short runs
        return az.from_dict(posterior=posterior, sample_stats=stats)


def _import_arviz():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        import arviz as az
    return az


def arviz_diagnostics(idata) -> dict:
    """R-hat and bulk/tail ESS per parameter from arviz (portable across arviz 0.2x and 1.x)."""
    az = _import_arviz()
    out: dict = {}
    try:
        table = az.summary(idata, kind="diagnostics")
        for name in idata.posterior.data_vars:
            row = table.loc[name]
            out[name] = {k: float(row[k]) for k in ("r_hat", "ess_bulk", "ess_tail") if k in row}
        return out
    except Exception:  # pragma: no cover - arviz API drift (1.x)
        rhat, ess = az.rhat(idata), az.ess(idata)
        for name in idata.posterior.data_vars:
            out[name] = {"r_hat": float(np.asarray(rhat[name])), "ess_bulk": float(np.asarray(ess[name]))}
        return out
