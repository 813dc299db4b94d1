"""Posterior results: one :class:`TemplateRun` per template and the :class:`PosteriorResult`."""

from __future__ import annotations

import json
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._hdf5 import open_file, write_file
from .._provenance import json_default
from ..exceptions import InputError
from ..units import TWO_PI
from .diagnostics import _ChainView, _import_arviz
from .likelihood import PARAMETER_NAMES
from .priors import Priors

__all__ = ["PosteriorResult", "TemplateRun"]

RESULT_KIND = "spiralbayes.PosteriorResult"


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
            raise InputError(f"template {self.name} has no chain (mode = {self.mode!r})")
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
        """Posterior probabilities of each value of hand, mass, beta, tau0 and h_p (summed over templates)."""
        probs = self.template_probabilities
        out: dict = {}
        for key in ("hand", "mass", "beta", "tau0", "h_p"):
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

    # -- persistence -------------------------------------------------------------------------
    def to_json(self) -> dict:
        return {"run_name": self.run_name, "priors": self.priors.to_dict(), "template_prior": self.template_prior.tolist(),
                "chain_path": self.chain_path, "provenance": self.provenance,
                "template_probabilities": self.template_probabilities, "marginals": _json_keys(self.marginals()),
                "runs": [r.to_json() for r in self.runs]}

    def save(self, path) -> Path:
        """Write the result (with the samples) to HDF5, atomically."""
        with write_file(path, RESULT_KIND) as f:
            f.attrs["result"] = json.dumps(self.to_json(), default=json_default)
            for r in self.runs:
                f.create_dataset(f"samples/{r.name}", data=r.samples)
        return Path(path)

    @classmethod
    def load(cls, path) -> "PosteriorResult":
        with open_file(path, RESULT_KIND, "posterior result") as f:
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
