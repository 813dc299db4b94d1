"""Posterior results: one :class:`TemplateRun` per template, the :class:`NullRun`, and their combination.

Hypotheses: "no planet" (the disc alone, :class:`NullRun`) and "a planet with template T" for
each template (:class:`TemplateRun`). With evidences ``Z_0`` and ``Z_T``, prior probability
``P(planet)`` shared uniformly (or as given) among the templates,

    P(planet | data) = P(planet) sum_T pi_T Z_T / [P(planet) sum_T pi_T Z_T + (1 - P(planet)) Z_0],

the Bayes factor is ``B = sum_T pi_T Z_T / Z_0``, and ``P(T | data, planet) = pi_T Z_T / sum``.
:attr:`PosteriorResult.verdict` says "inconclusive" when ``|ln B| <`` ``INCONCLUSIVE_LN_B``
(= 1, the Jeffreys scale's "not worth more than a bare mention", B < e ~ 2.7 either way; Kass &
Raftery 1995, Trotta 2008): the data do not decide between planet and no planet, and no position
is reported. Otherwise "no planet preferred" when ``P(planet | data) < 0.5`` (no position
reported as a finding), else the most probable template's planet position and amplitude, and the
planet mass as a credible range over the templates (:meth:`PosteriorResult.mass_range`: the
marginal ``P(M_p | data, planet)`` summed over morphology variants, H/r, τ0, β and hand, because
no single template's label is the planet's mass).

Why this module is long: the three results (a template's or family's run, the no-planet run and
their combination) are written to and read from one file format together, and the combination's
summaries (verdict, mass range, mass posterior, marginals) read every run.

Samples (``SAMPLE_NAMES``): ``r_p`` [arcsec], ``phi_p`` [rad, wrapped around its circular
mean], ``A`` (drawn exactly from its conditional posterior for each sample), ``inc``, ``PA``
[deg], ``dRA``, ``dDec`` [arcsec].
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..._provenance import json_safe
from ...exceptions import InputError
from ...results import ResultMixin
from ...settings import DEFAULT_MSTAR_MSUN
from ...units import M_JUP, M_SUN, wrap_angle
from .conditional import PARAMETER_NAMES
from .diagnostics import chain_inference_data
from .likelihood import draw_amplitude
from .priors import GEOMETRY_NAMES, Priors
from ...templates.asymmetry import ASYMMETRY_KINDS as ASYMMETRY_LABELS
from ...templates.template import LEARNED_PHYSICS

INCONCLUSIVE_LN_B = 1.0
"""``|ln B(planet : none)|`` below this is "inconclusive" (Jeffreys scale: B < e either way)."""
MASS_LEVEL = 0.95
"""Credibility of the reported mass range."""

__all__ = ["MASS_SAMPLE_NAMES", "SAMPLE_NAMES", "NullRun", "PosteriorResult", "TemplateRun", "wrap_phi"]

RESULT_KIND = "spiralbayes.PosteriorResult"
SAMPLE_NAMES = ("r_p", "phi_p", "A", "inc", "PA", "dRA", "dDec")
"""Columns of ``TemplateRun.samples``."""
MASS_SAMPLE_NAMES = (*SAMPLE_NAMES, "M_p", "M_p_MJup")
"""Columns of a continuous-mass family run's samples (:mod:`~spiralbayes.inference.posterior.mass`):
``M_p`` [M_th], ``M_p_MJup`` [M_Jup]."""


def wrap_phi(samples: np.ndarray, column: int = 1) -> tuple[np.ndarray, float]:
    """Wrap phi_p into ``[mu - pi, mu + pi)`` around its circular mean ``mu`` (in [0, 2 pi))."""
    phi = samples[..., column]
    mu = float(wrap_angle(np.angle(np.mean(np.exp(1j * phi))), 0.0))
    out = samples.copy()
    out[..., column] = wrap_angle(phi, mu - np.pi)
    return out, mu


def _format_stats(stats: dict) -> str:
    """One line per parameter: median, 16-84 % and 2.5-97.5 % intervals."""
    rows = [f"{'':<6}{'median':>11}{'16%':>11}{'84%':>11}{'2.5%':>11}{'97.5%':>11}"]
    for name, s in stats.items():
        rows.append(f"{name:<6}" + "".join(f"{s[k]:>11.5g}" for k in ("median", "lo", "hi", "lo95", "hi95")))
    return "\n".join(rows)


def _stats(samples: np.ndarray, names) -> dict:
    q = np.percentile(samples, [2.5, 16, 50, 84, 97.5], axis=0)
    return {n: {"median": float(q[2, j]), "lo": float(q[1, j]), "hi": float(q[3, j]), "lo95": float(q[0, j]),
                "hi95": float(q[4, j]), "std": float(np.std(samples[:, j]))} for j, n in enumerate(names)}


@dataclass(repr=False)
class TemplateRun(ResultMixin):
    """The posterior of one template.

    Attributes
    ----------
    name : str
    metadata : dict
        Template metadata (mass, tau0, beta, hand, ...).
    mode : {'mcmc', 'laplace'}
        Whether a chain was run or only the Laplace approximation.
    samples : ndarray, shape (n, 7) or (n, 9)
        Post-burn-in, thinned samples of ``sample_names`` (``SAMPLE_NAMES``, and for a
        continuous-mass family run ``MASS_SAMPLE_NAMES``: ``M_p`` [M_th] and ``M_p_MJup`` added).
    theta_map : ndarray, shape (6,) or (7,)
        The optimum before sampling, ``(r_p, phi_p, inc, PA, dRA, dDec)`` (and ``ln M_p`` for a family).
    covariance : ndarray, shape (6, 6) or (7, 7)
        Laplace covariance at ``theta_map``.
    ln_evidence, ln_evidence_err : float
        Adopted ln Z and its error (importance sampling when a chain exists, else Laplace); same
        constant as the :class:`NullRun`'s.
    ln_evidence_laplace : float
    diagnostics : dict
        Convergence (``tau``, ESS, ...), evidence details (``evidence``, ``ln_bayes_savage_dickey``),
        arviz's R-hat/ESS, the likelihood's settings, timings.
    chain_path, group : str
        Where the chain lives (HDF5 file, group).
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

    KIND = "spiralbayes.TemplateRun"
    WHAT = "template posterior"

    @property
    def continuous_mass(self) -> bool:
        """True for a family run with the planet mass sampled (:mod:`~spiralbayes.inference.posterior.mass`)."""
        return self.samples.ndim == 2 and self.samples.shape[1] == len(MASS_SAMPLE_NAMES)

    @property
    def sample_names(self) -> tuple:
        """Names of the columns of ``samples``."""
        return MASS_SAMPLE_NAMES if self.continuous_mass else SAMPLE_NAMES

    def percentiles(self) -> dict:
        """Median, 16/84 and 2.5/97.5 percentiles and std of each of :attr:`sample_names`."""
        return _stats(self.samples, self.sample_names)

    def summary(self) -> str:
        """The template, how it was sampled, ln Z, and the percentiles of every parameter."""
        mass = ", M_p [M_th], M_p_MJup [M_Jup]" if self.continuous_mass else ""
        return (f"Template {self.name} ({self.mode}, {len(self.samples)} samples): ln Z = {self.ln_evidence:.2f} "
                f"+- {self.ln_evidence_err:.2f} (Laplace {self.ln_evidence_laplace:.2f}); r_p [arcsec], phi_p [rad], "
                f"inc, PA [deg], dRA, dDec [arcsec]{mass}:\n" + _format_stats(self.percentiles()))

    def __repr__(self) -> str:
        return (f"TemplateRun({self.name!r}, {self.mode}, {len(self.samples)} samples, "
                f"ln Z = {self.ln_evidence:.2f} +- {self.ln_evidence_err:.2f})")

    def chain(self, discard: int | None = None, thin: int | None = None) -> np.ndarray:
        """The stored chain (n_steps, n_walkers, 6) of ``(r_p, phi_p, inc, PA, dRA, dDec)`` as sampled."""
        import emcee

        if self.chain_path is None or self.mode != "mcmc":
            raise InputError(f"template {self.name} has no chain (mode = {self.mode!r})")
        backend = emcee.backends.HDFBackend(self.chain_path, name=self.group, read_only=True)
        d = self.diagnostics
        return backend.get_chain(discard=d.get("burn_in", 0) if discard is None else discard,
                                 thin=d.get("thin", 1) if thin is None else thin)

    def inference_data(self):
        """arviz ``InferenceData`` (walkers as chains; caveat: emcee walkers are not independent).

        A continuous-mass run's posterior also holds ``M_p`` [M_th] and ``M_p_MJup`` [M_Jup] (the
        template mass ``lnM_p`` with the mismatch systematic and one stellar mass drawn per draw,
        seeded by the run's name)."""
        import zlib

        import emcee

        backend = emcee.backends.HDFBackend(self.chain_path, name=self.group, read_only=True)
        d = self.diagnostics
        chain = backend.get_chain(discard=d.get("burn_in", 0), thin=d.get("thin", 1))
        lp = backend.get_log_prob(discard=d.get("burn_in", 0), thin=d.get("thin", 1))
        if chain.shape[2] == len(PARAMETER_NAMES):
            return chain_inference_data(wrap_phi(chain)[0], lp)
        from .mass import MASS_PARAMETER_NAMES, MassPrior

        rng = np.random.default_rng(zlib.crc32(self.name.encode()))
        mass, mjup = MassPrior.from_metadata(self.metadata).planet_masses(np.exp(chain[..., 6]),
                                                                          float(self.metadata["h_p"]), rng)
        full = np.concatenate([wrap_phi(chain)[0], mass[..., None], mjup[..., None]], axis=2)
        return chain_inference_data(full, lp, names=(*MASS_PARAMETER_NAMES, "M_p", "M_p_MJup"))

    def to_dict(self) -> dict:
        """Everything but the samples (which stay in the HDF5 file) as JSON-safe values, with the
        percentiles of every parameter."""
        return {**json_safe(self.record()), "percentiles": json_safe(self.percentiles())}

    def record(self) -> dict:
        """The fields but the samples, as stored beside them in a chain file (NaN kept)."""
        return {"name": self.name, "metadata": self.metadata, "mode": self.mode,
                "theta_map": self.theta_map.tolist(), "covariance": self.covariance.tolist(),
                "ln_evidence": self.ln_evidence, "ln_evidence_err": self.ln_evidence_err,
                "ln_evidence_laplace": self.ln_evidence_laplace, "diagnostics": self.diagnostics,
                "chain_path": self.chain_path, "group": self.group}

    @classmethod
    def from_record(cls, d: dict, samples: np.ndarray) -> TemplateRun:
        """The run from :meth:`record` and its samples."""
        return cls(d["name"], d["metadata"], d["mode"], np.asarray(samples), np.array(d["theta_map"]),
                   np.array(d["covariance"]), d["ln_evidence"], d["ln_evidence_err"], d["ln_evidence_laplace"],
                   d["diagnostics"], d["chain_path"], d["group"])


@dataclass(repr=False)
class NullRun(ResultMixin):
    """The no-planet hypothesis: the disc alone, its profile integrated out.

    Attributes
    ----------
    samples : ndarray, shape (n, 4)
        ``(inc, PA, dRA, dDec)`` drawn from the no-planet posterior (importance resampling).
    geometry_map, covariance : ndarray
        Mode and Laplace covariance of the geometry.
    ln_evidence, ln_evidence_err, ln_evidence_laplace : float
        ``ln Z_0`` (same constant as the templates').
    profile : dict
        The profile refitted at the mode (``r`` [arcsec], ``I``, ``I_err`` [Jy/sr]) — the profile
        of every template's spiral term.
    diagnostics : dict
    """

    samples: np.ndarray
    geometry_map: np.ndarray
    covariance: np.ndarray
    ln_evidence: float
    ln_evidence_err: float
    ln_evidence_laplace: float
    profile: dict = field(default_factory=dict)
    diagnostics: dict = field(default_factory=dict)

    KIND = "spiralbayes.NullRun"
    WHAT = "no-planet posterior"

    def percentiles(self) -> dict:
        """Median, 16/84 and 2.5/97.5 percentiles and std of ``inc``, ``PA`` [deg], ``dRA``, ``dDec`` [arcsec]."""
        return _stats(self.samples, GEOMETRY_NAMES)

    def summary(self) -> str:
        """ln Z_0 and the percentiles of the geometry."""
        return (f"No planet ({len(self.samples)} samples): ln Z0 = {self.ln_evidence:.2f} +- "
                f"{self.ln_evidence_err:.2f} "
                f"(Laplace {self.ln_evidence_laplace:.2f}); inc, PA [deg], dRA, dDec [arcsec]:\n"
                + _format_stats(self.percentiles()))

    def __repr__(self) -> str:
        return f"NullRun({len(self.samples)} samples, ln Z0 = {self.ln_evidence:.2f} +- {self.ln_evidence_err:.2f})"

    def to_dict(self) -> dict:
        """Everything but the samples as JSON-safe values, with the geometry's percentiles."""
        return {**json_safe(self.record()), "percentiles": json_safe(self.percentiles())}

    def record(self) -> dict:
        """The fields but the samples, as stored beside them in a chain file (NaN kept)."""
        return {"geometry_map": self.geometry_map.tolist(), "covariance": self.covariance.tolist(),
                "ln_evidence": self.ln_evidence, "ln_evidence_err": self.ln_evidence_err,
                "ln_evidence_laplace": self.ln_evidence_laplace, "profile": self.profile,
                "diagnostics": self.diagnostics}

    @classmethod
    def from_record(cls, d: dict, samples: np.ndarray) -> NullRun:
        """The run from :meth:`record` and its samples."""
        return cls(np.asarray(samples), np.array(d["geometry_map"]), np.array(d["covariance"]), d["ln_evidence"],
                   d["ln_evidence_err"], d["ln_evidence_laplace"], d.get("profile", {}), d.get("diagnostics", {}))


@dataclass(repr=False)
class PosteriorResult(ResultMixin):
    """Per-template posteriors, the no-planet hypothesis, and the posterior over hypotheses.

    Attributes
    ----------
    runs : list of TemplateRun
    priors : Priors
    template_prior : ndarray
        Prior probabilities of the templates given a planet (uniform by default).
    run_name : str
    chain_path : str or None
    provenance : dict
    null : NullRun or None
        The no-planet hypothesis (None for results made without it).
    planet_prior : float
        Prior probability that there is a planet (default 0.5).
    alternative_runs : list of TemplateRun
        The competing explanations' runs (``alternatives`` of :func:`~.sampler.sample_posterior`; each
        run's ``metadata["kind"]`` names its explanation, :mod:`.odds`); empty without them.
    """

    runs: list
    priors: Priors
    template_prior: np.ndarray
    run_name: str = "posterior"
    chain_path: str | None = None
    provenance: dict = field(default_factory=dict)
    null: NullRun | None = None
    planet_prior: float = 0.5
    alternative_runs: list = field(default_factory=list)

    KIND = RESULT_KIND
    WHAT = "posterior result"

    @property
    def names(self) -> list[str]:
        return [r.name for r in self.runs]

    def _log_weights(self) -> np.ndarray:
        return np.array([r.ln_evidence for r in self.runs], dtype=float) + np.log(self.template_prior)

    @property
    def template_probabilities(self) -> dict:
        """``P(T | data, planet)`` for every template (evidence x prior, normalised over templates)."""
        lnz = self._log_weights()
        p = np.exp(lnz - np.max(lnz))
        return dict(zip(self.names, (p / p.sum()).tolist()))

    @property
    def ln_bayes_factor(self) -> float:
        """``ln[sum_T pi_T Z_T / Z_0]``: evidence for a planet over none (nan without the null)."""
        from scipy.special import logsumexp

        if self.null is None:
            return float("nan")
        return float(logsumexp(self._log_weights()) - self.null.ln_evidence)

    def _odds(self) -> tuple[dict, dict] | None:
        from .odds import PLANET, hypothesis_weights, model_probabilities

        if not self.alternative_runs or self.null is None:
            return None
        kinds = list(dict.fromkeys(r.metadata["kind"] for r in self.alternative_runs))
        groups: dict[str, tuple] = {PLANET: (self.runs, self.template_prior)}
        for kind in kinds:
            groups[ASYMMETRY_LABELS[kind]] = ([r for r in self.alternative_runs if r.metadata["kind"] == kind], None)
        return model_probabilities(groups, self.null, hypothesis_weights(kinds, self.planet_prior))

    @property
    def model_probabilities(self) -> dict | None:
        """``P(h | data)`` of "no asymmetry", "planet" and each competing explanation ("arc/vortex",
        "eccentric ring"), when they were sampled (:mod:`.odds`); None otherwise."""
        odds = self._odds()
        return None if odds is None else odds[0]

    @property
    def model_probability_errors(self) -> dict | None:
        """Monte Carlo errors of :attr:`model_probabilities` (first-order propagation of the ``ln Z`` errors)."""
        odds = self._odds()
        return None if odds is None else odds[1]

    @property
    def p_planet(self) -> float:
        """``P(planet | data)`` (nan without the null); with competing explanations sampled, among all of
        them (:attr:`model_probabilities`)."""
        odds = self.model_probabilities
        if odds is not None:
            return float(odds["planet"])
        lnb = self.ln_bayes_factor
        if not np.isfinite(lnb):
            return float("nan") if np.isnan(lnb) else float(lnb > 0)
        prior_odds = np.log(self.planet_prior) - np.log1p(-self.planet_prior)
        return float(1.0 / (1.0 + np.exp(-(lnb + prior_odds))))

    @property
    def hypothesis_probabilities(self) -> dict:
        """``P(hypothesis | data)`` for "no planet" (or, with competing explanations, "no asymmetry" and
        each explanation) and every template (sums to 1)."""
        p = self.p_planet
        odds = self.model_probabilities
        out = {"no planet": 1.0 - p} if odds is None else {k: v for k, v in odds.items() if k != "planet"}
        out.update({name: p * q for name, q in self.template_probabilities.items()})
        return out

    def odds_sentence(self) -> str:
        """The posterior odds between the planet and its competing explanations, in words ("" without them)."""
        odds, errors = self.model_probabilities, self.model_probability_errors
        if odds is None or errors is None:
            return ""
        parts = [f"P({h}) = {odds[h]:.3g} +- {errors[h]:.2g}" for h in ("planet", *[k for k in odds if k not in
                                                                                    ("planet", "no asymmetry")],
                                                                         "no asymmetry")]
        best = max(odds, key=lambda h: odds[h])
        text = "Posterior odds: " + ", ".join(parts) + f" (Monte Carlo errors); most probable: {best}"
        if best not in ("planet", "no asymmetry"):
            run = max((r for r in self.alternative_runs if ASYMMETRY_LABELS[r.metadata["kind"]] == best),
                      key=lambda r: r.ln_evidence)
            st = run.percentiles()
            text += (f" ({run.name}: r = {st['r_p']['median']:.4f} arcsec, phi = "
                     f"{wrap_angle(np.degrees(st['phi_p']['median']), 0.0, 360.0):.1f} deg, amplitude "
                     f"{st['A']['median']:.2f})")
        return text + "."

    @property
    def inconclusive(self) -> bool:
        """True when ``|ln B| <`` ``INCONCLUSIVE_LN_B``: the data do not decide (Jeffreys scale)."""
        return bool(np.isfinite(self.ln_bayes_factor) and abs(self.ln_bayes_factor) < INCONCLUSIVE_LN_B)

    @property
    def planet_preferred(self) -> bool:
        """P(planet | data) >= 0.5 and the Bayes factor outside the inconclusive band."""
        return bool(self.p_planet >= 0.5 and not self.inconclusive)

    def amplitude(self, template=None) -> dict:
        """The amplitude's posterior (median, 16/84, 2.5/97.5) for a template (default: most probable)."""
        return self.run(template).percentiles()["A"]

    @property
    def verdict(self) -> str:
        """One sentence: "no planet preferred" or the preferred planet and its position (after the posterior
        odds when competing explanations were sampled)."""
        odds = self.odds_sentence()
        return self._planet_verdict() if not odds else odds + " Planet against none: " + self._planet_verdict(
            bare=True)

    def _planet_verdict(self, bare: bool = False) -> str:
        from scipy.special import expit

        lnb = self.ln_bayes_factor
        # against the disc alone (the odds sentence gives it among the explanations)
        p = (float(expit(lnb + np.log(self.planet_prior) - np.log1p(-self.planet_prior))) if bare
             else self.p_planet)
        if np.isnan(p):
            return f"most probable template {self.best.name} (no no-planet hypothesis computed)"
        if self.inconclusive:
            return (f"inconclusive: P(planet | data) = {p:.3g}, ln B(planet : none) = {lnb:.2f} (|ln B| < "
                    f"{INCONCLUSIVE_LN_B:g}: the data do not decide between a planet and none on the Jeffreys scale; "
                    f"no planet position is reported; prior P(planet) = {self.planet_prior:g})")
        if p < 0.5:
            return (f"no planet preferred: P(planet | data) = {p:.3g}, ln B(planet : none) = {lnb:.2f} "
                    f"(prior P(planet) = {self.planet_prior:g})")
        s = self.best.percentiles()
        return (f"planet preferred: P(planet | data) = {p:.4g}, ln B = {lnb:.2f}; most probable template "
                f"{self.best.name} (P = {self.template_probabilities[self.best.name]:.3g} given a planet): "
                f"r_p = {s['r_p']['median']:.4f} (+{s['r_p']['hi'] - s['r_p']['median']:.4f} "
                f"-{s['r_p']['median'] - s['r_p']['lo']:.4f}) arcsec, phi_p = "
                f"{wrap_angle(np.degrees(s['phi_p']['median']), 0.0, 360.0):.1f} "
                f"+- {np.degrees(s['phi_p']['std']):.1f} deg, A = {s['A']['median']:.2f} "
                f"(+{s['A']['hi'] - s['A']['median']:.2f} -{s['A']['median'] - s['A']['lo']:.2f})"
                + self._mass_clause())

    def _mass_clause(self) -> str:
        post = self.mass_posterior()
        if post is not None:
            t, j = post["mth"], post["mjup"]
            return (f"; planet mass {t['median']:.2g} M_th (68 %: {t['lo']:.2g}-{t['hi']:.2g}, 95 %: "
                    f"{t['lo95']:.2g}-{t['hi95']:.2g}) = {j['median']:.2g} M_Jup (95 %: {j['lo95']:.2g}-"
                    f"{j['hi95']:.2g}; M_* = {post['mstar']:g} +- {post['mstar_sigma']:.2g} M_sun), M_p sampled"
                    + (f" with a template-mismatch scatter of {post['systematic']:.2g} in ln M_p"
                       if post["systematic"] > 0 else ""))
        m = self.mass_range()
        if m is None:
            return ""
        span = [f"{x:g}" for x in m["mth"]]
        text = f"; planet mass {span[0] if span[0] == span[1] else '-'.join(span)} M_th"
        if m["mjup"] is not None:
            j = [f"{x:.2g}" for x in m["mjup"]]
            text += f" ({j[0] if j[0] == j[1] else '-'.join(j)} M_Jup for M_* = {m['mstar']:g} M_sun)"
        return text + f" ({100 * m['level']:g} % credible, over morphology variants and H/r)"

    def mass_range(self, level: float = MASS_LEVEL, mstar: float = DEFAULT_MSTAR_MSUN) -> dict | None:
        """Credible range of the planet mass given a planet, over all templates.

        In M_th: the smallest set of masses whose marginal probability (:meth:`marginals`) reaches
        ``level``, most probable first; its smallest and largest mass. In M_Jup: the same over the
        (mass, H/r) pairs, each converted with its own H/r (``M_th = h_p³ M_*``). None when no
        template has a mass.

        Returns
        -------
        dict or None
            ``mth``, ``mjup`` ([min, max]; ``mjup`` None when no template has an H/r), ``level``,
            ``mstar`` [M_sun], ``probability`` (the sets' probabilities in M_th and M_Jup).
        """
        if not 0 < level <= 1:
            raise InputError(f"mass credibility level must be in (0, 1], got {level!r}")
        probs = self.template_probabilities
        by_mass: dict = {}
        by_pair: dict = {}
        for r in self.runs:
            mass, h_p = r.metadata.get("mass"), r.metadata.get("h_p")
            if mass is None:
                continue
            by_mass[float(mass)] = by_mass.get(float(mass), 0.0) + probs[r.name]
            if h_p is not None and np.isfinite(h_p):
                key = (float(mass), float(h_p))
                by_pair[key] = by_pair.get(key, 0.0) + probs[r.name]
        if not by_mass:
            return None
        masses, p_mass = _credible_set(by_mass, level)
        out: dict[str, Any] = {"mth": [min(masses), max(masses)], "mjup": None, "level": float(level),
                               "mstar": float(mstar), "probability": {"mth": p_mass, "mjup": None}}
        if by_pair:
            pairs, p_pair = _credible_set(by_pair, level)
            mj = [m * h**3 * mstar * M_SUN / M_JUP for m, h in pairs]
            out["mjup"], out["probability"]["mjup"] = [min(mj), max(mj)], p_pair
        return out

    def mass_posterior(self, seed: int = 0) -> dict | None:
        """The planet mass's posterior given a planet, from the continuous-mass family runs
        (:mod:`~spiralbayes.inference.posterior.mass`).

        The families' samples are mixed in proportion to their probabilities
        (:attr:`template_probabilities`, renormalised over the family runs).

        Returns
        -------
        dict or None
            ``mth`` [M_th] and ``mjup`` [M_Jup], each with ``median``, ``lo``/``hi`` (16/84 %) and
            ``lo95``/``hi95`` (2.5/97.5 %); ``mstar``, ``mstar_sigma`` [M_sun] of the conversion's
            prior and ``systematic`` (the template mismatch's σ of ln M_p; of the most probable family);
            ``n_samples``. None without a family run.
        """
        runs = [r for r in self.runs if r.continuous_mass]
        if not runs:
            return None
        probs = self.template_probabilities
        p = np.array([probs[r.name] for r in runs])
        p = p / p.sum() if p.sum() > 0 else np.full(len(runs), 1.0 / len(runs))
        rng = np.random.default_rng(seed)
        n = sum(len(r.samples) for r in runs)
        counts = rng.multinomial(n, p)
        pooled = np.concatenate([r.samples[rng.integers(0, len(r.samples), k)] for r, k in zip(runs, counts) if k])
        stats = _stats(pooled[:, 7:9], ("mth", "mjup"))
        best = runs[int(np.argmax(p))].metadata
        return {**stats, "mstar": float(best["mstar_msun"]), "mstar_sigma": float(best["mstar_sigma_msun"]),
                "systematic": float(best.get("mass_systematic_ln", 0.0)), "n_samples": int(n)}

    def marginals(self) -> dict:
        """``P(value | data, planet)`` of each value of hand, mass, beta, tau0, h_p and morphology variant,
        and of a learned bank's disc physics (slope, alpha, orbits) (summed over templates; templates without
        a key are left out of its marginal, and a key no template has is absent)."""
        probs = self.template_probabilities
        out: dict = {}
        for key in ("hand", "mass", "beta", "tau0", "h_p", "variant", *LEARNED_PHYSICS):
            if key in LEARNED_PHYSICS and not any(key in r.metadata for r in self.runs):
                continue
            table: dict = {}
            for r in self.runs:
                value = r.metadata.get(key)
                if value is None or (isinstance(value, float) and np.isnan(value)):
                    continue  # unknown (a FARGO3D run's beta): NaN keys would not sum, as NaN != NaN
                table[value] = table.get(value, 0.0) + probs[r.name]
            out[key] = dict(sorted(table.items(), key=lambda kv: str(kv[0])))
        return out

    @property
    def p_right_handed(self) -> float:
        """``P(right-handed | data, planet)``."""
        return float(self.marginals()["hand"].get("R", 0.0))

    def run(self, template: str | int | None = None) -> TemplateRun:
        """A template's run by name or index (default: the most probable)."""
        if template is None:
            probs = self.template_probabilities
            template = max(probs, key=lambda name: probs[name])
        if isinstance(template, (int, np.integer)):
            return self.runs[int(template)]
        for r in self.runs:
            if r.name == template:
                return r
        raise KeyError(f"no template named {template!r}; have {self.names}")

    @property
    def best(self) -> TemplateRun:
        """The most probable template's run."""
        return self.run()

    def percentiles(self, template=None) -> dict:
        """Percentiles of every parameter of a template's posterior (default: the most probable);
        see :meth:`TemplateRun.percentiles`."""
        return self.run(template).percentiles()

    def summary(self, template=None) -> str:
        """The verdict, then the percentiles of ``template`` (default: the most probable)."""
        return self.verdict + "\n" + self.run(template).summary()

    def to_inference_data(self, template=None):
        return self.run(template).inference_data()

    def to_dict(self) -> dict:
        """The run's settings, hypothesis probabilities, verdict and each template's record and
        percentiles (samples stay in the HDF5 file), JSON-safe."""
        return json_safe({"run_name": self.run_name, "priors": self.priors.to_dict(),
                          "template_prior": self.template_prior, "chain_path": self.chain_path,
                          "provenance": self.provenance, "planet_prior": self.planet_prior, "verdict": self.verdict,
                          "p_planet": self.p_planet, "ln_bayes_factor": self.ln_bayes_factor,
                          "template_probabilities": self.template_probabilities, "marginals": self.marginals(),
                          "model_probabilities": self.model_probabilities,
                          "model_probability_errors": self.model_probability_errors,
                          "alternative_runs": [r.to_dict() for r in self.alternative_runs],
                          "mass_range": self.mass_range(), "mass_posterior": self.mass_posterior(),
                          "null": None if self.null is None else self.null.to_dict(),
                          "runs": [r.to_dict() for r in self.runs]})

    def __repr__(self) -> str:
        return (f"PosteriorResult({self.run_name!r}, {len(self.runs)} templates, P(planet | data) = "
                f"{self.p_planet:.3g}, "
                f"ln B = {self.ln_bayes_factor:.2f}, best {self.best.name if self.runs else None})")


def _read_format_1(f) -> PosteriorResult:
    """A posterior written before the dataclass layout (``format_version`` 1)."""
    d = json.loads(f.attrs["result"])
    runs = [TemplateRun.from_record(r, f[f"samples/{r['name']}"][()]) for r in d["runs"]]
    null = NullRun.from_record(d["null"], f["null_samples"][()]) if d.get("null") else None
    return PosteriorResult(runs, Priors.from_dict(d["priors"]), np.array(d["template_prior"]), d["run_name"],
                           d["chain_path"], d["provenance"], null, float(d.get("planet_prior", 0.5)))


PosteriorResult.LEGACY_READERS = {1: _read_format_1}
def _credible_set(probabilities: dict, level: float) -> tuple[list, float]:
    """The most probable keys whose probabilities first reach ``level``, and their total."""
    chosen, total = [], 0.0
    for key, p in sorted(probabilities.items(), key=lambda kv: -kv[1]):
        chosen.append(key)
        total += p
        if total >= level * (1 - 1e-12):
            break
    return chosen, float(total)


def _with_amplitude(samples6: np.ndarray, c1, c2, priors: Priors, rng) -> np.ndarray:
    """``(r_p, phi_p, A, inc, PA, dRA, dDec)``: ``A`` drawn from its conditional posterior per sample."""
    A = np.ones(len(samples6)) if priors.amplitude_max is None else draw_amplitude(c1, c2, priors.amplitude_max, rng)
    out = np.column_stack([samples6[:, :2], A, samples6[:, 2:]])
    return wrap_phi(out)[0]
