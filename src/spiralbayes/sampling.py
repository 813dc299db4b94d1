"""Posterior sampling: emcee over planet position and disc geometry, templates as a discrete choice.

Continuous parameters (:data:`spiralbayes.posterior.PARAMETER_NAMES`): ``r_p`` [arcsec],
``phi_p`` [rad], ``inc`` [deg], ``PA`` [deg], ``dRA``, ``dDec`` [arcsec]. The likelihood is
:class:`spiralbayes.posterior.SpiralLikelihood` (axisymmetric profile held at the frank fit,
its visibilities re-evaluated under each sampled geometry).

Priors (:class:`Priors`): ``r_p`` uniform on ``[r_min, r_max]`` (default: the disc's extent,
``R_eff / 25`` to ``R_eff``, never beyond the profile's ``Rmax``), ``phi_p`` uniform on the circle
(the likelihood is 2 pi-periodic, so walkers wrap around freely; samples are reported wrapped into
``[mu - pi, mu + pi)`` around their circular mean), and Gaussian ``inc``, ``PA``, ``dRA``,
``dDec`` centred on the frank geometry with user-set widths (defaults 5 deg, 5 deg, 0.05 arcsec,
0.05 arcsec).

The template is a discrete parameter. **Choice: per-template runs combined by their evidence.**
For each template ``T`` the posterior of the six continuous parameters is sampled with emcee and
its evidence ``Z_T = int L pi`` estimated; then ``P(T | data) = Z_T pi_T / sum_T' Z_T' pi_T'``
(uniform ``pi_T`` by default). Why not an emcee move over a template index carried in the state:
the modes of different templates sit at different ``(r_p, phi_p)`` and geometries, so a jump
between templates at fixed continuous parameters is almost always rejected (a mirror template's
best planet lies elsewhere), and affine-invariant stretch/DE moves are undefined on a discrete
coordinate — mixing would be poor and hard to diagnose. Per-template runs are independent
(parallel over templates or walkers, resumable one by one), each has its own convergence test,
and the evidences come from two estimators that check each other:

* ``laplace``: Gaussian approximation at the optimum, ``ln Z = ln(L pi)(theta*) + (d/2) ln 2 pi +
  (1/2) ln det Sigma`` with ``Sigma`` from a finite-difference Hessian;
* ``importance`` (used when a chain exists): importance sampling of ``L pi`` with a multivariate
  Student-t (5 degrees of freedom) proposal fitted to the chain, ``Z = E_q[L pi / q]``; its error
  comes from the weights' variance. A Gaussian/unimodal posterior is assumed by both; a very large
  error flags a multimodal or badly fitted posterior.

Templates whose grid-scan peak (``ScanResult``) is far below the best template's
(``prune_delta_lnL``, default 25 in ln L) get the Laplace evidence only (no chain): their
probabilities are < e^-20 of the best's anyway. Thermodynamic integration or nested sampling would be
exact but 10-100x more expensive.

Chains: emcee's ``HDFBackend``, by default ``chains/<run_name>.h5``, one group per template
(named after it), with the run's inputs (priors, template metadata, geometry, data hash, table
settings) and package versions as JSON attributes of the group and the file. **Resuming**: emcee's
``run_mcmc`` always *adds* ``n`` steps to what the backend holds; :func:`sample_posterior` takes the
*total* ``n_steps`` and runs only the remainder (a finished run does nothing), and refuses to
resume a file written for other inputs.

Convergence: emcee's integrated autocorrelation time ``tau`` is the primary test — chain length
> 50 tau for every parameter (after burn-in; burn-in = 5 max tau) — with ESS = n_walkers n_steps / tau.
arviz's R-hat and ESS (:meth:`TemplateRun.inference_data`) are reported too, with the caveat that
emcee's walkers are not independent chains (R-hat near 1 is necessary, not sufficient). Policy for
unconverged runs: ``convergence="raise" | "warn" | "ignore"``; the message says roughly how many
more steps are needed.

Parallelism: ``processes=k`` runs walkers in a ``multiprocessing`` pool whose workers receive the
likelihood once (pool initializer; emcee #199) and pin BLAS threads; ``pool="mpi"`` uses
``schwimmbad.MPIPool`` (imported lazily): run the *same script on every rank*
(``mpiexec -n 8 python run.py``); every rank builds the likelihood tables, worker ranks serve
log-probability calls until the master closes the pool, then move on to the next template
together; only the master returns a result. Any object with a ``map`` method may also be passed
as ``pool``.
"""

from __future__ import annotations

import json
import logging
import os
import time
import warnings
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ._provenance import data_hash, json_default, provenance_record
from .geometry import DiscGeometry
from .posterior import PARAMETER_NAMES, SpiralLikelihood

__all__ = [
    "ConvergenceError",
    "ConvergenceWarning",
    "LogPosterior",
    "PosteriorResult",
    "Priors",
    "TemplateRun",
    "convergence_diagnostics",
    "refit_axisymmetric",
    "run_sample_config",
    "sample_posterior",
]

log = logging.getLogger(__name__)

TWO_PI = 2.0 * np.pi
N_DIM = len(PARAMETER_NAMES)
TAU_FACTOR = 50.0
DEFAULT_WIDTHS = {"inc": 5.0, "PA": 5.0, "dRA": 0.05, "dDec": 0.05}
HDF5_KIND = "spiralbayes.PosteriorRun"


class ConvergenceError(RuntimeError):
    """A chain failed the autocorrelation-time test and ``convergence="raise"``."""


class ConvergenceWarning(UserWarning):
    """A chain failed the autocorrelation-time test (``convergence="warn"``)."""


# ---------------------------------------------------------------------------------------------
# priors
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Priors:
    """Priors of the six continuous parameters.

    Parameters
    ----------
    r_p : (float, float)
        Uniform range of the planet radius [arcsec], ``0 < r_min < r_max``.
    inc, PA : (float, float)
        Gaussian (mean, sigma) [deg]; the inclination is also truncated to [0, 90).
    dRA, dDec : (float, float)
        Gaussian (mean, sigma) [arcsec].

    ``phi_p`` is uniform on the circle (no parameters).
    """

    r_p: tuple
    inc: tuple
    PA: tuple
    dRA: tuple
    dDec: tuple

    def __post_init__(self):
        lo, hi = (float(x) for x in self.r_p)
        if not (np.isfinite(lo) and np.isfinite(hi)) or lo <= 0 or hi <= lo:
            raise ValueError(f"Priors.r_p = {self.r_p!r}: need 0 < r_min < r_max [arcsec] (planet radii "
                             "must be positive and the range non-empty)")
        object.__setattr__(self, "r_p", (lo, hi))
        for name in ("inc", "PA", "dRA", "dDec"):
            value = getattr(self, name)
            if np.ndim(value) != 1 or len(value) != 2:
                raise ValueError(f"Priors.{name} = {value!r}: give (mean, sigma)")
            mean, sigma = float(value[0]), float(value[1])
            if not np.isfinite(mean) or not np.isfinite(sigma) or sigma <= 0:
                unit = "deg" if name in ("inc", "PA") else "arcsec"
                raise ValueError(f"Priors.{name}: the width must be a positive number of {unit}, got {sigma!r} "
                                 "(negative or zero widths are not allowed)")
            object.__setattr__(self, name, (mean, sigma))
        if not 0 <= self.inc[0] < 90:
            raise ValueError(f"Priors.inc mean = {self.inc[0]} deg is outside [0, 90)")

    @classmethod
    def default(cls, axisymmetric, *, geometry: DiscGeometry | None = None, r_p=None, widths: dict | None = None,
                ) -> "Priors":
        """Defaults: r_p over the disc's extent, geometry centred on the frank geometry.

        Parameters
        ----------
        axisymmetric : AxisymmetricModel
            Its ``R_eff()`` and ``Rmax`` set the r_p range; its ``geometry`` the centre.
        geometry : DiscGeometry, optional
            Centre of the geometry priors (default: the model's).
        r_p : (float, float), optional
            Override the r_p range [arcsec].
        widths : dict, optional
            Sigmas for ``inc``, ``PA`` [deg], ``dRA``, ``dDec`` [arcsec]; defaults
            :data:`DEFAULT_WIDTHS`.
        """
        geometry = geometry or axisymmetric.geometry
        widths = {**DEFAULT_WIDTHS, **(widths or {})}
        unknown = set(widths) - set(DEFAULT_WIDTHS)
        if unknown:
            raise ValueError(f"unknown prior widths {sorted(unknown)}: use {sorted(DEFAULT_WIDTHS)}")
        if r_p is None:
            r_eff = float(axisymmetric.R_eff())
            r_max = min(r_eff, float(getattr(axisymmetric, "Rmax", np.inf)) / 2.2)
            r_p = (r_eff / 25.0, r_max)
        return cls(tuple(r_p), (geometry.inc, widths["inc"]), (geometry.PA, widths["PA"]),
                   (geometry.dRA, widths["dRA"]), (geometry.dDec, widths["dDec"]))

    @classmethod
    def from_dict(cls, d: dict) -> "Priors":
        unknown = set(d) - {"r_p", "inc", "PA", "dRA", "dDec"}
        if unknown:
            raise ValueError(f"unknown prior keys {sorted(unknown)}: use r_p, inc, PA, dRA, dDec")
        return cls(**{k: tuple(v) for k, v in d.items()})

    def to_dict(self) -> dict:
        return {k: list(v) for k, v in asdict(self).items()}

    def check_data(self, vis, axisymmetric) -> None:
        """Raise ``ValueError`` if the r_p range lies outside what the data and model can describe."""
        lo, hi = self.r_p
        r_out = getattr(axisymmetric, "Rmax", None)
        if r_out is not None and hi > float(r_out):
            raise ValueError(f"Priors.r_p upper bound {hi} arcsec lies beyond the disc model's extent "
                             f"(Rmax = {float(r_out)} arcsec): the profile is zero there; lower it")
        if r_out is not None and lo >= float(r_out):
            raise ValueError(f"Priors.r_p = {self.r_p} lies entirely outside the disc (Rmax = {float(r_out)} arcsec)")
        from .geometry import ARCSEC

        resolution = 1.0 / float(np.max(vis.uv_distance)) / ARCSEC
        if hi < 0.25 * resolution:
            raise ValueError(f"Priors.r_p = {self.r_p} arcsec is far below the data's resolution "
                             f"(1 / u_max = {resolution:.3g} arcsec): the data cannot constrain it")

    @property
    def centre(self) -> np.ndarray:
        """The prior's centre: mid r_p, phi_p = 0, the geometry means."""
        return np.array([0.5 * sum(self.r_p), 0.0, self.inc[0], self.PA[0], self.dRA[0], self.dDec[0]])

    @property
    def widths(self) -> np.ndarray:
        """A scale per parameter (r_p range / sqrt 12, pi, sigmas)."""
        return np.array([(self.r_p[1] - self.r_p[0]) / np.sqrt(12.0), np.pi, self.inc[1], self.PA[1],
                         self.dRA[1], self.dDec[1]])

    def log_prior(self, theta) -> float:
        """Normalised log prior density (``-inf`` outside the support)."""
        r_p, _, inc, PA, dRA, dDec = theta
        lo, hi = self.r_p
        if not (lo <= r_p <= hi) or not (0.0 <= inc < 90.0):
            return -np.inf
        value = -np.log(hi - lo) - np.log(TWO_PI)
        for x, (mu, sigma) in ((inc, self.inc), (PA, self.PA), (dRA, self.dRA), (dDec, self.dDec)):
            value += -0.5 * ((x - mu) / sigma) ** 2 - np.log(sigma) - 0.5 * np.log(TWO_PI)
        return float(value)

    def draw(self, n: int, rng) -> np.ndarray:
        """``n`` samples from the prior, shape (n, 6)."""
        out = np.empty((n, N_DIM))
        out[:, 0] = rng.uniform(*self.r_p, n)
        out[:, 1] = rng.uniform(0, TWO_PI, n)
        for j, (mu, sigma) in enumerate((self.inc, self.PA, self.dRA, self.dDec), start=2):
            out[:, j] = rng.normal(mu, sigma, n)
        out[:, 2] = np.clip(out[:, 2], 0.0, 89.9)
        return out


class LogPosterior:
    """``ln pi(theta) + ln L(theta)`` for one template (picklable; the emcee log-probability)."""

    def __init__(self, likelihood: SpiralLikelihood, priors: Priors):
        self.likelihood = likelihood
        self.priors = priors

    def __call__(self, theta) -> float:
        lp = self.priors.log_prior(theta)
        if not np.isfinite(lp):
            return -np.inf
        return lp + self.likelihood(theta)


# -- worker-side globals (load the likelihood once per process, emcee #199) -----------------------
_WORKER_LOGPOST: LogPosterior | None = None


def _pin_threads() -> None:
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
        os.environ[var] = "1"
    try:  # pragma: no cover - optional
        from threadpoolctl import threadpool_limits

        threadpool_limits(1)
    except ImportError:
        pass


def _init_worker(logpost: LogPosterior) -> None:
    global _WORKER_LOGPOST
    _pin_threads()
    _WORKER_LOGPOST = logpost


def _worker_log_prob(theta) -> float:
    return _WORKER_LOGPOST(theta)


# ---------------------------------------------------------------------------------------------
# diagnostics
# ---------------------------------------------------------------------------------------------
def convergence_diagnostics(chain: np.ndarray, *, tau_factor: float = TAU_FACTOR, min_ess: float = 0.0) -> dict:
    """Autocorrelation-time diagnostics of an emcee chain of shape (n_steps, n_walkers, n_dim).

    ``phi_p`` must be unwrapped (as sampled). Returns ``tau`` per parameter, ``n_steps``,
    ``burn_in`` (5 max tau), ``ess`` (= n_walkers (n_steps - burn_in) / tau), ``converged``
    (``n_steps > tau_factor tau`` for every parameter and ``ess >= min_ess``) and
    ``more_steps`` (a rough estimate of the extra steps needed; 0 when converged).
    """
    import emcee

    n_steps, n_walkers, _ = chain.shape
    tau = np.asarray(emcee.autocorr.integrated_time(chain, tol=0, quiet=True), dtype=float)
    tau_max = float(np.max(tau))
    burn = int(min(np.ceil(5 * tau_max), n_steps // 2))
    ess = n_walkers * (n_steps - burn) / tau
    long_enough = n_steps > tau_factor * tau
    enough_ess = ess >= min_ess
    needed = max(tau_factor * tau_max, 5 * tau_max + min_ess * tau_max / n_walkers)
    more = 0 if (long_enough.all() and enough_ess.all()) else int(np.ceil(1.2 * needed - n_steps))
    return {"tau": dict(zip(PARAMETER_NAMES, tau.tolist())), "tau_max": tau_max, "n_steps": int(n_steps),
            "n_walkers": int(n_walkers), "burn_in": burn, "thin": max(1, int(tau_max / 2)),
            "ess": dict(zip(PARAMETER_NAMES, ess.tolist())), "converged": bool(long_enough.all() and enough_ess.all()),
            "tau_factor": tau_factor, "min_ess": min_ess, "more_steps": max(more, 0)}


def _convergence_message(name: str, diag: dict) -> str:
    worst = max(diag["tau"], key=diag["tau"].get)
    low_ess = min(diag["ess"], key=diag["ess"].get)
    return (f"template {name}: chain of {diag['n_steps']} steps is not converged: it needs > "
            f"{diag['tau_factor']:g} tau = {diag['tau_factor'] * diag['tau_max']:.0f} steps (largest tau = "
            f"{diag['tau_max']:.1f} for {worst!r}) and ESS >= {diag['min_ess']:g} (lowest {diag['ess'][low_ess]:.0f} for "
            f"{low_ess!r}); run about {diag['more_steps']} more steps (tau estimates grow on short chains, so "
            "maybe more)")


def _apply_policy(policy: str, message: str) -> None:
    if policy == "raise":
        raise ConvergenceError(message)
    if policy == "warn":
        warnings.warn(message, ConvergenceWarning, stacklevel=4)
    else:
        log.info(message)


class _ChainView:
    """The minimal emcee-sampler interface ``arviz.from_emcee`` reads (post-burn-in, thinned)."""

    def __init__(self, chain, log_prob):
        self._chain, self._log_prob = chain, log_prob

        class _Fn:
            args: list = []
            kwargs: dict = {}

        self.log_prob_fn = _Fn()

    def get_chain(self, **kwargs):
        return self._chain

    def get_log_prob(self, **kwargs):
        return self._log_prob

    def get_blobs(self, **kwargs):
        return None


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
        for name in PARAMETER_NAMES:
            row = table.loc[name]
            out[name] = {k: float(row[k]) for k in ("r_hat", "ess_bulk", "ess_tail") if k in row}
        return out
    except Exception:  # pragma: no cover - arviz API drift (1.x)
        rhat, ess = az.rhat(idata), az.ess(idata)
        for name in PARAMETER_NAMES:
            out[name] = {"r_hat": float(np.asarray(rhat[name])), "ess_bulk": float(np.asarray(ess[name]))}
        return out


# ---------------------------------------------------------------------------------------------
# results
# ---------------------------------------------------------------------------------------------
def _wrap_phi(samples: np.ndarray) -> tuple[np.ndarray, float]:
    """Wrap phi_p into ``[mu - pi, mu + pi)`` around its circular mean ``mu`` (in [0, 2 pi))."""
    phi = samples[..., 1]
    mu = float(np.angle(np.mean(np.exp(1j * phi))) % TWO_PI)
    out = samples.copy()
    out[..., 1] = mu + (phi - mu + np.pi) % TWO_PI - np.pi
    return out, mu


@dataclass
class TemplateRun:
    """The posterior of one template.

    Attributes
    ----------
    name : str
    metadata : dict
        Template metadata (mass, tau0, beta, hand, ...).
    mode : {'mcmc', 'laplace'}
        Whether a chain was run or only the Laplace approximation.
    samples : ndarray, shape (n, 6)
        Post-burn-in, thinned, flattened samples; ``phi_p`` wrapped around its circular mean.
    theta_map : ndarray
        The optimum found before sampling (maximum a posteriori).
    covariance : ndarray, shape (6, 6)
        Laplace covariance at ``theta_map``.
    ln_evidence, ln_evidence_err : float
        Adopted ln Z and its error (importance sampling when a chain exists, else Laplace).
    ln_evidence_laplace : float
    diagnostics : dict
        :func:`convergence_diagnostics` output plus arviz's R-hat/ESS (mcmc mode).
    chain_path, group : str
        Where the chain lives (HDF5 file, emcee group).
    """

    name: str
    metadata: dict
    mode: str
    samples: np.ndarray
    theta_map: np.ndarray
    covariance: np.ndarray
    ln_evidence: float
    ln_evidence_err: float
    ln_evidence_laplace: float
    diagnostics: dict = field(default_factory=dict)
    chain_path: str | None = None
    group: str | None = None

    def summary(self) -> dict:
        """Median and 16/84 percentiles of each parameter."""
        q = np.percentile(self.samples, [16, 50, 84], axis=0)
        return {n: {"median": float(q[1, j]), "lo": float(q[0, j]), "hi": float(q[2, j]),
                    "std": float(np.std(self.samples[:, j]))} for j, n in enumerate(PARAMETER_NAMES)}

    def chain(self, discard: int | None = None, thin: int | None = None) -> np.ndarray:
        """The stored chain (n_steps, n_walkers, 6), ``phi_p`` unwrapped (as sampled)."""
        import emcee

        if self.chain_path is None:
            raise ValueError(f"template {self.name} has no chain (mode = {self.mode!r})")
        backend = emcee.backends.HDFBackend(self.chain_path, name=self.group, read_only=True)
        d = self.diagnostics
        return backend.get_chain(discard=d.get("burn_in", 0) if discard is None else discard,
                                 thin=d.get("thin", 1) if thin is None else thin)

    def inference_data(self):
        """arviz ``InferenceData`` (walkers as chains; caveat: emcee walkers are not independent)."""
        import emcee

        az = _import_arviz()
        backend = emcee.backends.HDFBackend(self.chain_path, name=self.group, read_only=True)
        d = self.diagnostics
        chain = backend.get_chain(discard=d.get("burn_in", 0), thin=d.get("thin", 1))
        chain, _ = _wrap_phi(chain)
        lp = backend.get_log_prob(discard=d.get("burn_in", 0), thin=d.get("thin", 1))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "more chains than draws" on short runs
            return az.from_emcee(_ChainView(chain, lp), var_names=list(PARAMETER_NAMES))

    def to_json(self) -> dict:
        return {"name": self.name, "metadata": self.metadata, "mode": self.mode,
                "theta_map": self.theta_map.tolist(), "covariance": self.covariance.tolist(),
                "ln_evidence": self.ln_evidence, "ln_evidence_err": self.ln_evidence_err,
                "ln_evidence_laplace": self.ln_evidence_laplace, "diagnostics": self.diagnostics,
                "chain_path": self.chain_path, "group": self.group}


@dataclass
class PosteriorResult:
    """Per-template posteriors and the posterior over templates.

    Attributes
    ----------
    runs : list of TemplateRun
    priors : Priors
    template_prior : ndarray
        Prior probabilities of the templates (uniform by default).
    run_name : str
    chain_path : str or None
    provenance : dict
    """

    runs: list
    priors: Priors
    template_prior: np.ndarray
    run_name: str = "posterior"
    chain_path: str | None = None
    provenance: dict = field(default_factory=dict)

    @property
    def names(self) -> list[str]:
        return [r.name for r in self.runs]

    @property
    def template_probabilities(self) -> dict:
        """``P(T | data)`` for every template (evidence × prior, normalised)."""
        lnz = np.array([r.ln_evidence for r in self.runs]) + np.log(self.template_prior)
        p = np.exp(lnz - np.max(lnz))
        return dict(zip(self.names, (p / p.sum()).tolist()))

    def marginals(self) -> dict:
        """Posterior probabilities of each value of hand, mass, beta and tau0 (summed over templates)."""
        probs = self.template_probabilities
        out: dict = {}
        for key in ("hand", "mass", "beta", "tau0"):
            table: dict = {}
            for r in self.runs:
                value = r.metadata.get(key)
                if value is None:
                    continue
                table[value] = table.get(value, 0.0) + probs[r.name]
            out[key] = dict(sorted(table.items(), key=lambda kv: str(kv[0])))
        return out

    @property
    def p_right_handed(self) -> float:
        """``P(right-handed | data)``."""
        return float(self.marginals()["hand"].get("R", 0.0))

    def run(self, template: str | int | None = None) -> TemplateRun:
        """A template's run by name or index (default: the most probable)."""
        if template is None:
            probs = self.template_probabilities
            template = max(probs, key=probs.get)
        if isinstance(template, (int, np.integer)):
            return self.runs[int(template)]
        for r in self.runs:
            if r.name == template:
                return r
        raise KeyError(f"no template named {template!r}; have {self.names}")

    @property
    def best(self) -> TemplateRun:
        return self.run()

    def summary(self, template=None) -> dict:
        return self.run(template).summary()

    def to_inference_data(self, template=None):
        return self.run(template).inference_data()

    def corner(self, template=None, **kwargs):
        """Corner plot of a template's posterior (see :func:`spiralbayes.plotting.posterior.plot_corner`)."""
        from .plotting.posterior import plot_corner

        return plot_corner(self, template=template, **kwargs)

    # -- persistence -------------------------------------------------------------------------
    def to_json(self) -> dict:
        return {"run_name": self.run_name, "priors": self.priors.to_dict(), "template_prior": self.template_prior.tolist(),
                "chain_path": self.chain_path, "provenance": self.provenance,
                "template_probabilities": self.template_probabilities, "marginals": _json_keys(self.marginals()),
                "runs": [r.to_json() for r in self.runs]}

    def save(self, path) -> Path:
        """Write the result (with the samples) to HDF5, atomically."""
        import h5py

        from ._provenance import atomic_path

        path = Path(path)
        with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
            f.attrs["kind"] = "spiralbayes.PosteriorResult"
            f.attrs["result"] = json.dumps(self.to_json(), default=json_default)
            for r in self.runs:
                f.create_dataset(f"samples/{r.name}", data=r.samples)
        return path

    @classmethod
    def load(cls, path) -> "PosteriorResult":
        import h5py

        with h5py.File(path, "r") as f:
            if f.attrs.get("kind") != "spiralbayes.PosteriorResult":
                raise ValueError(f"{path} is not a spiralbayes posterior result")
            d = json.loads(f.attrs["result"])
            runs = []
            for r in d["runs"]:
                runs.append(TemplateRun(r["name"], r["metadata"], r["mode"], f[f"samples/{r['name']}"][()],
                                        np.array(r["theta_map"]), np.array(r["covariance"]), r["ln_evidence"],
                                        r["ln_evidence_err"], r["ln_evidence_laplace"], r["diagnostics"],
                                        r["chain_path"], r["group"]))
        return cls(runs, Priors.from_dict(d["priors"]), np.array(d["template_prior"]), d["run_name"],
                   d["chain_path"], d["provenance"])


def _json_keys(d):
    if isinstance(d, dict):
        return {str(k): _json_keys(v) for k, v in d.items()}
    return d


# ---------------------------------------------------------------------------------------------
# optimisation, Laplace, evidence
# ---------------------------------------------------------------------------------------------
def _optimise(logpost, start: np.ndarray, scales: np.ndarray, max_evals: int = 3000) -> np.ndarray:
    """Nelder-Mead on the log posterior (with restarts), from ``start``."""
    from scipy.optimize import minimize

    x = np.array(start, dtype=float)
    for _ in range(3):
        simplex = x + np.vstack([np.zeros(N_DIM), np.diag(scales)])
        res = minimize(lambda t: -logpost(t) if np.isfinite(logpost(t)) else 1e300, x, method="Nelder-Mead",
                       options={"initial_simplex": simplex, "maxfev": max_evals, "xatol": 1e-9, "fatol": 1e-4})
        moved = np.abs(res.x - x) / scales
        x = res.x
        scales = np.maximum(scales * 0.2, np.abs(moved) * scales * 0.5 + 1e-9)
        if np.all(moved < 1e-2):
            break
    return x


def _inside(theta: np.ndarray, priors: Priors) -> tuple[np.ndarray, np.ndarray]:
    """Move ``theta`` off the hard prior edges (r_p range, inc in [0, 90)); room to each edge."""
    theta = theta.copy()
    lo, hi = priors.r_p
    span = hi - lo
    theta[0] = np.clip(theta[0], lo + 1e-3 * span, hi - 1e-3 * span)
    theta[2] = np.clip(theta[2], 1e-3, 90 - 1e-3)
    room = np.full(N_DIM, np.inf)
    room[0] = min(theta[0] - lo, hi - theta[0])
    room[2] = min(theta[2], 90 - theta[2])
    return theta, 0.9 * room


def _hessian_cov(logpost, theta: np.ndarray, scales: np.ndarray, priors: Priors) -> np.ndarray:
    """Laplace covariance ``(-H)^-1`` from central differences with steps tuned to d ln p ~ 0.5.

    Steps never cross the hard prior edges (an optimum on an edge is moved just inside; the
    Gaussian approximation is then rough, which only matters for templates far from the best).
    """
    theta, room = _inside(theta, priors)
    f0 = logpost(theta)
    h = np.minimum(scales * 1e-2, room)
    for i in range(N_DIM):
        for _ in range(10):
            e = np.zeros(N_DIM)
            e[i] = h[i]
            curv = logpost(theta + e) + logpost(theta - e) - 2 * f0
            if not np.isfinite(curv):
                h[i] *= 0.3
                continue
            if 0.1 < -curv < 2.0:
                break
            h[i] = min(h[i] * np.sqrt(0.5 / max(abs(curv), 1e-12)), scales[i] * 3, room[i])
    H = np.zeros((N_DIM, N_DIM))
    for i in range(N_DIM):
        for j in range(i, N_DIM):
            ei = np.zeros(N_DIM)
            ej = np.zeros(N_DIM)
            ei[i], ej[j] = h[i], h[j]
            if i == j:
                H[i, i] = (logpost(theta + ei) + logpost(theta - ei) - 2 * f0) / h[i] ** 2
            else:
                H[i, j] = H[j, i] = (logpost(theta + ei + ej) - logpost(theta + ei - ej) - logpost(theta - ei + ej)
                                     + logpost(theta - ei - ej)) / (4 * h[i] * h[j])
    H = np.where(np.isfinite(H), H, 0.0)
    try:
        cov = np.linalg.inv(-H)
        np.linalg.cholesky(cov)
        return cov
    except np.linalg.LinAlgError:
        diag = -np.diag(H)
        log.warning("Hessian not negative definite at the optimum; using its diagonal")
        return np.diag(1.0 / np.where(diag > 0, diag, 1.0 / scales ** 2))


def _laplace_evidence(lp_max: float, cov: np.ndarray) -> float:
    sign, logdet = np.linalg.slogdet(cov)
    return float(lp_max + 0.5 * N_DIM * np.log(TWO_PI) + 0.5 * logdet) if sign > 0 else float("nan")


def _importance_evidence(logpost, samples: np.ndarray, n_draws: int, rng, mapper=map) -> tuple[float, float, float]:
    """``ln Z`` by importance sampling with a Student-t proposal fitted to ``samples``.

    Returns ``(ln Z, its standard error, effective sample size of the weights)``.
    """
    from scipy import stats
    from scipy.special import logsumexp

    nu = 5.0
    mean = samples.mean(axis=0)
    cov = np.cov(samples, rowvar=False) * 1.2 ** 2
    proposal = stats.multivariate_t(loc=mean, shape=cov * (nu - 2) / nu, df=nu, seed=rng)
    draws = proposal.rvs(n_draws)
    lp = np.array(list(mapper(logpost, list(draws))))
    lw = lp - proposal.logpdf(draws)
    lw = np.where(np.isfinite(lw), lw, -np.inf)
    lnz = float(logsumexp(lw) - np.log(n_draws))
    w = np.exp(lw - np.max(lw))
    ess = float(w.sum() ** 2 / np.sum(w ** 2))
    err = float(np.sqrt(np.var(w) / n_draws) / np.mean(w))
    return lnz, err, ess


# ---------------------------------------------------------------------------------------------
# the run
# ---------------------------------------------------------------------------------------------
def _fit_geometry(likelihood: SpiralLikelihood, priors: Priors) -> np.ndarray:
    """MAP geometry (inc, PA, dRA, dDec) of the axisymmetric model alone.

    Done before searching for the planet: with the geometry off (the frank geometry may be off by
    tens of mas), the best planet positions at that geometry are often the ones that absorb the
    geometry error (Stevenson et al. 2024, appendix A), a local mode of the joint posterior.
    """
    from scipy.optimize import minimize

    centre = priors.centre

    def neg(g):
        theta = np.concatenate([centre[:2], g])
        lp = priors.log_prior(theta)
        if not np.isfinite(lp):
            return 1e300
        return -(lp + likelihood.log_likelihood_axisymmetric(DiscGeometry(*g)))

    x = centre[2:].copy()
    step = priors.widths[2:] * 0.2
    for _ in range(3):
        res = minimize(neg, x, method="Nelder-Mead",
                       options={"initial_simplex": x + np.vstack([np.zeros(4), np.diag(step)]), "maxfev": 2000,
                                "xatol": 1e-9, "fatol": 1e-4})
        if np.all(np.abs(res.x - x) < 0.01 * step):
            x = res.x
            break
        x, step = res.x, step * 0.2
    return x


def _start_points(likelihood: SpiralLikelihood, priors: Priors, scan, template_name: str, geometry: np.ndarray,
                  n: int = 8):
    """Candidate starts: the scan's best (r_p, phi_p) instances plus a coarse grid, at ``geometry``."""
    cands = []
    if scan is not None:
        try:
            k = scan.template_index(template_name)
        except (KeyError, IndexError):
            k = None
        if k is not None:
            dchi2 = scan.delta_chi2()[k]
            order = np.argsort(np.nan_to_num(dchi2, nan=-np.inf), axis=None)[::-1]
            for flat in order[:n]:
                i, j = np.unravel_index(flat, dchi2.shape)
                cands.append((float(np.clip(scan.r_p[i], *priors.r_p)), float(scan.phi_p[j])))
    lo, hi = priors.r_p
    for r in np.linspace(lo, hi, 14)[1:-1]:
        for phi in np.linspace(0, TWO_PI, 36, endpoint=False):
            cands.append((float(r), float(phi)))
    return [np.concatenate([[r, phi], geometry]) for r, phi in cands]


def _find_map(logpost, likelihood, priors, scan, name, scales, n_starts: int = 3):
    """Geometry first, then a grid/scan search over (r_p, phi_p), then joint optimisation from the
    ``n_starts`` best distinct candidates; returns the best optimum."""
    geometry = _fit_geometry(likelihood, priors)
    starts = _start_points(likelihood, priors, scan, name, geometry)
    values = np.array([logpost(s) for s in starts])
    order = np.argsort(np.where(np.isfinite(values), values, -np.inf))[::-1]
    chosen: list = []
    for i in order:
        s = starts[i]
        far = all(abs(s[0] - c[0]) > 0.05 * (priors.r_p[1] - priors.r_p[0])
                  or abs(np.angle(np.exp(1j * (s[1] - c[1])))) > 0.3 for c in chosen)
        if far:
            chosen.append(s)
        if len(chosen) >= n_starts:
            break
    optima = [_optimise(logpost, s, scales) for s in chosen]
    lps = [logpost(o) for o in optima]
    best = int(np.argmax(lps))
    log.info("%s: optima from %d starts, ln p = %s", name, len(optima), np.round(lps, 2).tolist())
    return optima[best]


def _initial_walkers(logpost, theta_map, cov, priors, n_walkers, rng, initial=None):
    """Walkers around the optimum (Laplace covariance / 4), redrawn where ln p = -inf."""
    if initial is not None:
        p0 = np.array(initial, dtype=float)
        if p0.shape != (n_walkers, N_DIM):
            raise ValueError(f"initial walkers have shape {p0.shape}, expected ({n_walkers}, {N_DIM})")
    else:
        p0 = rng.multivariate_normal(theta_map, cov * 0.25, size=n_walkers)
    lp = np.array([logpost(p) for p in p0])
    for _ in range(50 if initial is None else 0):
        bad = ~np.isfinite(lp)
        if not bad.any():
            break
        p0[bad] = rng.multivariate_normal(theta_map, cov * 0.05, size=int(bad.sum()))
        lp[bad] = [logpost(p) for p in p0[bad]]
    bad = np.flatnonzero(~np.isfinite(lp))
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"walker {i} starts at theta = {np.round(p0[i], 6).tolist()} "
                         f"({', '.join(PARAMETER_NAMES)}) where the log posterior is -inf "
                         f"({bad.size} such walkers): move the start inside the prior "
                         f"(r_p in {priors.r_p}, 0 <= inc < 90)")
    return p0


def _inputs_record(vis, priors, template, likelihood, n_walkers, moves_name) -> dict:
    from .scan import template_metadata

    return {"priors": priors.to_dict(), "template": template_metadata(template),
            "data_hash": data_hash(vis.u, vis.v, vis.V, vis.weights), "n_data": int(vis.n),
            "reference_geometry": likelihood.reference_geometry.to_dict(), "n_walkers": int(n_walkers),
            "parameters": list(PARAMETER_NAMES), "moves": moves_name}


def _check_resume(path, group, inputs):
    import h5py

    if not Path(path).exists():
        return 0
    with h5py.File(path, "r") as f:
        if group not in f:
            return 0
        g = f[group]
        stored = json.loads(g.attrs.get("spiralbayes_inputs", "{}"))
        iteration = int(g.attrs.get("iteration", 0))
    if iteration and stored != json.loads(json.dumps(inputs, default=json_default)):
        diff = sorted(k for k in set(stored) | set(inputs) if stored.get(k) != json.loads(json.dumps(inputs.get(k), default=json_default)))
        raise ValueError(f"chain file {path} (group {group!r}) was written for different inputs (differ in {diff}): "
                         "delete it or choose another run_name to start afresh")
    return iteration


def _write_attrs(path, group, **items):
    import h5py

    with h5py.File(path, "a") as f:
        g = f.require_group(group)
        for k, v in items.items():
            g.attrs[k] = json.dumps(v, default=json_default)


def _make_pool(pool, processes, logpost):
    """(pool object or None, owned, emcee log-prob function, is_worker)."""
    if pool == "mpi":
        from schwimmbad import MPIPool  # lazy: only needed on clusters

        global _WORKER_LOGPOST
        _WORKER_LOGPOST = logpost
        mpi = MPIPool()
        if not mpi.is_master():
            mpi.wait()
            return None, False, None, True
        return mpi, True, _worker_log_prob, False
    if pool is not None:
        return pool, False, logpost, False
    if processes and processes > 1:
        import multiprocessing

        mp = multiprocessing.Pool(processes, initializer=_init_worker, initargs=(logpost,))
        return mp, True, _worker_log_prob, False
    return None, False, logpost, False


def _default_moves():
    import emcee

    return [(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)]


def _sample_one(vis, axisymmetric, template, priors, *, scan, chain_path, n_walkers, n_steps, max_steps,
                check_every, convergence, min_ess, pool, processes, rng, moves, progress, evidence_draws,
                likelihood_kwargs, mode, initial):
    import emcee

    from .scan import template_metadata

    t0 = time.perf_counter()
    name = getattr(template, "name", "template")
    likelihood = SpiralLikelihood(vis, axisymmetric, template, priors.r_p,
                                  reference_geometry=DiscGeometry(priors.inc[0], priors.PA[0], priors.dRA[0], priors.dDec[0]),
                                  **likelihood_kwargs)
    logpost = LogPosterior(likelihood, priors)
    scales = priors.widths * np.array([0.1, 0.05, 0.1, 0.1, 0.1, 0.1])
    theta_map = _find_map(logpost, likelihood, priors, scan, name, scales)
    cov = _hessian_cov(logpost, theta_map, scales, priors)
    lp_map = logpost(theta_map)
    lnz_laplace = _laplace_evidence(lp_map, cov)
    meta = template_metadata(template)
    log.info("%s: optimum ln p = %.2f at %s; Laplace ln Z = %.2f", name, lp_map, np.round(theta_map, 5), lnz_laplace)
    if mode == "laplace":
        samples = rng.multivariate_normal(theta_map, cov, size=4000)
        samples, _ = _wrap_phi(samples)
        return TemplateRun(name, meta, "laplace", samples, theta_map, cov, lnz_laplace, float("nan"), lnz_laplace,
                           {"time_s": time.perf_counter() - t0, "likelihood": likelihood.describe()})

    group = name
    inputs = _inputs_record(vis, priors, template, likelihood, n_walkers, "DE+snooker" if moves is None else repr(moves))
    done = _check_resume(chain_path, group, inputs)
    backend = emcee.backends.HDFBackend(str(chain_path), name=group)
    if done == 0:
        backend.reset(n_walkers, N_DIM)
    elif backend.shape != (n_walkers, N_DIM):
        raise ValueError(f"chain file {chain_path} has {backend.shape} walkers x dims, asked for ({n_walkers}, {N_DIM})")
    _write_attrs(chain_path, group, spiralbayes_inputs=inputs, provenance=provenance_record(
        likelihood=likelihood.describe()))
    pool_obj, owned, fn, is_worker = _make_pool(pool, processes, logpost)
    if is_worker:
        return None
    try:
        sampler = emcee.EnsembleSampler(n_walkers, N_DIM, fn, pool=pool_obj, backend=backend,
                                        moves=moves if moves is not None else _default_moves())
        sampler._random = np.random.mtrand.RandomState(int(rng.integers(2 ** 31)))
        state = backend.get_last_sample() if done else _initial_walkers(logpost, theta_map, cov, priors, n_walkers,
                                                                         rng, initial)
        if done:
            log.info("%s: resuming %s at step %d", name, chain_path, done)
        target = n_steps if n_steps is not None else max_steps
        while backend.iteration < target:
            chunk = min(check_every, target - backend.iteration) if n_steps is None else target - backend.iteration
            state = sampler.run_mcmc(state, chunk, progress=progress)
            if n_steps is None and backend.iteration >= 2 * check_every:
                diag = convergence_diagnostics(backend.get_chain(), min_ess=min_ess)
                log.info("%s: %d steps, max tau %.1f", name, backend.iteration, diag["tau_max"])
                if diag["converged"]:
                    break
        chain = backend.get_chain()
        diag = convergence_diagnostics(chain, min_ess=min_ess)
        mapper = pool_obj.map if pool_obj is not None else map
        flat = backend.get_chain(discard=diag["burn_in"], thin=diag["thin"], flat=True)
        lnz, lnz_err, ess_w = _importance_evidence(fn, flat, evidence_draws, rng, mapper)
    finally:
        if owned:
            pool_obj.close()
    run = TemplateRun(name, meta, "mcmc", _wrap_phi(flat)[0], theta_map, cov, lnz, lnz_err, lnz_laplace,
                      {**diag, "importance_ess": ess_w, "time_s": time.perf_counter() - t0,
                       "acceptance": float(np.mean(sampler.acceptance_fraction)), "likelihood": likelihood.describe()},
                      str(chain_path), group)
    try:
        run.diagnostics["arviz"] = arviz_diagnostics(run.inference_data())
    except Exception as exc:  # pragma: no cover - diagnostics must not lose a run
        log.warning("arviz diagnostics failed: %s", exc)
    _write_attrs(chain_path, group, result=run.to_json())
    if not diag["converged"]:
        _apply_policy(convergence, _convergence_message(name, diag))
    return run


def sample_posterior(vis, axisymmetric, templates, *, scan=None, priors: Priors | None = None,
                     run_name: str = "posterior", chains_dir="chains", n_walkers: int = 32,
                     n_steps: int | None = None, max_steps: int = 20000, check_every: int = 500,
                     convergence: str = "warn", min_ess: float = 400.0, processes: int | None = None, pool=None,
                     seed: int = 0, moves=None, template_prior=None, mcmc_templates=None,
                     prune_delta_lnL: float = 25.0, evidence_draws: int = 2000, progress: bool = True,
                     initial=None, likelihood_kwargs: dict | None = None) -> PosteriorResult:
    """Sample the posterior of every template and combine them by their evidence.

    Parameters
    ----------
    vis : Visibilities
    axisymmetric : AxisymmetricModel
        The frank fit (held fixed); its geometry centres the default priors.
    templates : SpiralTemplate, TemplateBank or sequence
    scan : ScanResult, optional
        Initialises each template's optimiser from its best grid instances, and prunes templates
        (``prune_delta_lnL``).
    priors : Priors, optional
        Default :meth:`Priors.default` (``axisymmetric``).
    run_name, chains_dir : str, path
        Chains go to ``<chains_dir>/<run_name>.h5`` (one group per template). An existing file with
        the same inputs is resumed.
    n_walkers : int
        emcee walkers (>= 2 x 6; default 32).
    n_steps : int, optional
        Total steps per walker (an interrupted run continues up to this total). ``None``: run in
        chunks of ``check_every`` until converged (> 50 tau and ESS >= ``min_ess``) or
        ``max_steps``.
    convergence : {'warn', 'raise', 'ignore'}
        What to do when a chain fails the 50-tau / ESS test.
    processes : int, optional
        Run walkers in a multiprocessing pool of this size. ``pool``: ``"mpi"`` or any object with
        ``map`` (then ``processes`` is ignored).
    seed : int
        Seed of the initialisation, the moves and the evidence draws.
    moves : emcee moves, optional
        Default: 80 % DEMove + 20 % DESnookerMove.
    template_prior : array_like, optional
        Prior probabilities of the templates (default uniform).
    mcmc_templates : list of str, optional
        Templates that get a chain; the others get the Laplace evidence only. Default: those
        within ``prune_delta_lnL`` of the best scan peak (every template without a scan).
    evidence_draws : int
        Proposal draws of the importance-sampled evidence.
    initial : array_like, optional
        Explicit initial walkers (n_walkers, 6) for every template (checked: none may start at
        -inf).
    likelihood_kwargs : dict, optional
        Passed to :class:`~spiralbayes.posterior.SpiralLikelihood` (``epsilon``, ``rp_tolerance``,
        ``oversample``, ...).
    progress : bool
        Show emcee's progress bar for each chunk of steps (default True).

    Returns
    -------
    PosteriorResult
    """
    if convergence not in ("warn", "raise", "ignore"):
        raise ValueError(f"convergence = {convergence!r}: use 'warn', 'raise' or 'ignore'")
    if hasattr(templates, "evaluate"):
        templates = [templates]
    templates = list(templates)
    if not templates:
        raise ValueError("no templates: pass a SpiralTemplate, a TemplateBank or a list of them")
    names = [t.name for t in templates]
    if len(set(names)) != len(names):
        raise ValueError(f"template names must be unique, got {names}")
    if n_walkers < 2 * N_DIM:
        raise ValueError(f"n_walkers = {n_walkers}: emcee needs at least 2 x {N_DIM} = {2 * N_DIM} walkers")
    if n_steps is not None and n_steps < 1:
        raise ValueError(f"n_steps = {n_steps} must be a positive number of steps")
    vis = vis.standardised()
    priors = priors or Priors.default(axisymmetric)
    priors.check_data(vis, axisymmetric)
    prior_t = np.full(len(templates), 1.0 / len(templates)) if template_prior is None else np.asarray(template_prior, float)
    if prior_t.shape != (len(templates),) or np.any(prior_t <= 0):
        raise ValueError("template_prior must hold one positive probability per template")
    prior_t = prior_t / prior_t.sum()
    chain_path = Path(chains_dir) / f"{run_name}.h5"
    chain_path.parent.mkdir(parents=True, exist_ok=True)
    selected = _select_mcmc(names, scan, mcmc_templates, prune_delta_lnL)
    rng = np.random.default_rng(seed)
    runs = []
    for template in templates:
        mode = "mcmc" if template.name in selected else "laplace"
        run = _sample_one(vis, axisymmetric, template, priors, scan=scan, chain_path=chain_path, n_walkers=n_walkers,
                          n_steps=n_steps, max_steps=max_steps, check_every=check_every, convergence=convergence,
                          min_ess=min_ess, pool=pool, processes=processes, rng=rng, moves=moves, progress=progress,
                          evidence_draws=evidence_draws, likelihood_kwargs=likelihood_kwargs or {}, mode=mode,
                          initial=initial)
        if run is None:  # an MPI worker rank
            continue
        runs.append(run)
    if pool == "mpi" and not runs:
        return None
    result = PosteriorResult(runs, priors, prior_t, run_name, str(chain_path),
                             provenance_record(data_hash=data_hash(vis.u, vis.v, vis.V, vis.weights),
                                               geometry=axisymmetric.geometry.to_dict()))
    _write_attrs(chain_path, "/", kind=HDF5_KIND, summary=result.to_json())
    return result


def _select_mcmc(names, scan, mcmc_templates, prune_delta_lnL) -> set:
    if mcmc_templates is not None:
        unknown = set(mcmc_templates) - set(names)
        if unknown:
            raise ValueError(f"mcmc_templates names unknown templates {sorted(unknown)}")
        return set(mcmc_templates)
    if scan is None:
        return set(names)
    peaks = {}
    dchi2 = scan.delta_chi2()
    for name in names:
        try:
            peaks[name] = float(np.nanmax(dchi2[scan.template_index(name)]))
        except (KeyError, IndexError):
            peaks[name] = np.inf
    best = max(peaks.values())
    return {n for n, p in peaks.items() if (best - p) / 2 <= prune_delta_lnL}


# ---------------------------------------------------------------------------------------------
# configuration entry point (the CLI's `spiralbayes sample CONFIG`)
# ---------------------------------------------------------------------------------------------
def refit_axisymmetric(vis, axisymmetric, result, template=None, *, progress: bool = False):
    """Refit the frank profile at the posterior-median geometry: the likelihood's optional refit.

    The likelihood holds the axisymmetric profile at the frank fit while the geometry varies. A
    profile fitted at a wrong geometry absorbs part of the error (the inclination is nearly
    degenerate with the profile's normalisation and radial scale, flux ∝ cos i), so the geometry
    posterior is conditional on that profile and can be biased by it. Iterate: refit here with the
    same hyperparameters, then call :func:`sample_posterior` again with the returned model.

    Parameters
    ----------
    vis : Visibilities
    axisymmetric : AxisymmetricModel
        The model used for ``result``; its frank hyperparameters are reused.
    result : PosteriorResult or TemplateRun
    template : str or int, optional
        Which template's posterior gives the geometry (default: the most probable).
    """
    from .axisymmetric import DEFAULT_HYPERPARAMETERS, fit_axisymmetric

    run = result.run(template) if hasattr(result, "run") else result
    median = {name: stats["median"] for name, stats in run.summary().items()}
    geometry = DiscGeometry(median["inc"], median["PA"], median["dRA"], median["dDec"])
    hyper = {k: axisymmetric.hyperparameters.get(k, v) for k, v in DEFAULT_HYPERPARAMETERS.items()}
    log.info("refitting the frank profile at the posterior geometry %s", geometry)
    return fit_axisymmetric(vis, geometry, progress=progress, **hyper)


SAMPLE_CONFIG_KEYS = {
    "data": "path of the visibilities (any format load_visibilities reads)",
    "axisymmetric": "path of a saved AxisymmetricModel (HDF5)",
    "templates": "path of a TemplateBank file, or 'default' for the built-in bank",
    "select": "optional TemplateBank.select(...) keywords: mass, tau0, beta, hand",
    "scan": "optional path of a saved ScanResult (initialisation and pruning)",
    "priors": "optional dict: r_p [min, max] arcsec; inc, PA [mean, sigma] deg; dRA, dDec [mean, sigma] arcsec",
    "widths": "optional dict of prior sigmas around the frank geometry (inc, PA, dRA, dDec)",
    "sampler": "optional dict: n_walkers, n_steps, max_steps, check_every, convergence, min_ess, processes, seed, "
               "prune_delta_lnL, evidence_draws",
    "run_name": "name of the chain file chains/<run_name>.h5 (default 'posterior')",
    "truths": "optional dict of true parameter values for the corner plot",
}
_SAMPLER_KEYS = {"n_walkers", "n_steps", "max_steps", "check_every", "convergence", "min_ess", "processes", "seed",
                 "prune_delta_lnL", "evidence_draws", "mcmc_templates"}


def run_sample_config(config: dict, out_dir) -> PosteriorResult:
    """Run :func:`sample_posterior` from a configuration dict and write the outputs to ``out_dir``.

    Keys: see :data:`SAMPLE_CONFIG_KEYS` (unknown keys are rejected). Writes
    ``out_dir/chains/<run_name>.h5`` (chains), ``out_dir/<run_name>_posterior.h5`` (result),
    ``out_dir/<run_name>_summary.json``, ``out_dir/<run_name>_corner.png`` and
    ``out_dir/<run_name>_templates.png``, and the configuration used
    (``out_dir/<run_name>_config.json``).
    """
    from .axisymmetric import AxisymmetricModel
    from .scan import ScanResult
    from .visibilities import load_visibilities

    unknown = set(config) - set(SAMPLE_CONFIG_KEYS)
    if unknown:
        raise ValueError(f"unknown configuration keys {sorted(unknown)}; valid keys: {sorted(SAMPLE_CONFIG_KEYS)}")
    for key in ("data", "axisymmetric", "templates"):
        if key not in config:
            raise ValueError(f"configuration needs {key!r}: {SAMPLE_CONFIG_KEYS[key]}")
    sampler_cfg = dict(config.get("sampler", {}))
    bad = set(sampler_cfg) - _SAMPLER_KEYS
    if bad:
        raise ValueError(f"unknown sampler keys {sorted(bad)}; valid: {sorted(_SAMPLER_KEYS)}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    run_name = config.get("run_name", "posterior")
    vis = load_visibilities(config["data"])
    axisym = AxisymmetricModel.load(config["axisymmetric"])
    templates = _load_templates(config["templates"], config.get("select"))
    scan = ScanResult.load(config["scan"]) if config.get("scan") else None
    if "priors" in config:
        priors = Priors.from_dict(config["priors"])
    else:
        priors = Priors.default(axisym, widths=config.get("widths"))
    with open(out_dir / f"{run_name}_config.json", "w") as f:
        json.dump(config, f, indent=2, default=str)
    result = sample_posterior(vis, axisym, templates, scan=scan, priors=priors, run_name=run_name,
                              chains_dir=out_dir / "chains", **sampler_cfg)
    result.save(out_dir / f"{run_name}_posterior.h5")
    with open(out_dir / f"{run_name}_summary.json", "w") as f:
        json.dump({**result.to_json(), "summary": result.summary()}, f, indent=2, default=json_default)
    from .plotting.posterior import plot_corner, plot_template_probabilities

    plot_corner(result, truths=config.get("truths")).savefig(out_dir / f"{run_name}_corner.png", dpi=120)
    plot_template_probabilities(result).savefig(out_dir / f"{run_name}_templates.png", dpi=120)
    return result


def _load_templates(spec, select):
    from .templates.bank import TemplateBank, default_bank

    bank = default_bank() if spec == "default" else TemplateBank.load(spec)
    if select:
        bank = bank.select(**select)
    if len(bank) == 0:
        raise ValueError(f"no templates left after select={select!r}")
    return list(bank)
