"""Posterior odds between a planet and the competing explanations (inference.posterior.odds): the
probabilities by hand, their Monte Carlo errors against finite differences, the result's persistence."""

import numpy as np
import pytest

from spiralbayes.exceptions import InputError
from spiralbayes.inference.posterior.odds import check_alternatives, hypothesis_weights, model_probabilities
from spiralbayes.inference.posterior.priors import Priors
from spiralbayes.inference.posterior.results import NullRun, PosteriorResult, TemplateRun
from spiralbayes.inference.posterior.settings import SamplingSettings


def _run(name, ln_z, err, kind=None):
    rng = np.random.default_rng(len(name))
    samples = np.column_stack([rng.uniform(0.3, 0.4, 50), rng.uniform(0, 1, 50), rng.uniform(0, 2, 50),
                               rng.normal(30, 0.1, 50), rng.normal(60, 0.1, 50), np.zeros(50), np.zeros(50)])
    meta = {"name": name, "mass": 1.0, "hand": "R"} if kind is None else {"name": name, "kind": kind}
    return TemplateRun(name, meta, "mcmc", samples, samples[0, [0, 1, 3, 4, 5, 6]], np.eye(6), ln_z, err, ln_z)


def _null(ln_z=0.0, err=0.1):
    return NullRun(np.zeros((10, 4)), np.array([30.0, 60.0, 0.0, 0.0]), np.eye(4), ln_z, err, ln_z)


PLANETS = [("wake_m1_R", 5.0, 0.1), ("wake_m1_L", 2.0, 0.2)]
ARCS = [("arc_a", 4.0, 0.05), ("arc_b", 6.0, 0.3)]
RINGS = [("ring_a", 1.0, 0.1)]


def _groups(values=None):
    values = values or {n: z for n, z, _ in PLANETS + ARCS + RINGS}
    runs = {h: [_run(n, values[n], e, kind) for n, _, e in rows] for h, rows, kind in
            (("planet", PLANETS, None), ("arc/vortex", ARCS, "arc"), ("eccentric ring", RINGS, "eccentric_ring"))}
    return {h: (r, None) for h, r in runs.items()}


def test_probabilities_by_hand():
    w = hypothesis_weights(["arc", "eccentric_ring"], 0.5)
    assert w == pytest.approx({"no asymmetry": 0.25, "planet": 0.25, "arc/vortex": 0.25, "eccentric ring": 0.25})
    probs, _ = model_probabilities(_groups(), _null(), w)
    # each hypothesis: its weight times the mean evidence of its templates (uniform within it)
    by_hand = {"no asymmetry": 1.0, "planet": (np.exp(5) + np.exp(2)) / 2, "arc/vortex": (np.exp(4) + np.exp(6)) / 2,
               "eccentric ring": np.exp(1.0)}
    total = sum(by_hand.values())
    assert probs == pytest.approx({k: v / total for k, v in by_hand.items()}, rel=1e-12)
    assert hypothesis_weights([], 0.3) == pytest.approx({"no asymmetry": 0.7, "planet": 0.3})


def test_monte_carlo_errors_match_finite_differences():
    base = {n: z for n, z, _ in PLANETS + ARCS + RINGS}
    sigma = {n: e for n, _, e in PLANETS + ARCS + RINGS}
    w = hypothesis_weights(["arc", "eccentric_ring"], 0.5)
    null = _null(0.0, 0.1)
    probs, errors = model_probabilities(_groups(), null, w)
    grads = {h: [] for h in probs}
    h_step = 1e-6
    for name in [*base, "null"]:
        shifted = dict(base)
        if name == "null":
            up, _ = model_probabilities(_groups(), _null(h_step, 0.1), w)
        else:
            shifted[name] += h_step
            up, _ = model_probabilities(_groups(shifted), null, w)
        for h in probs:
            grads[h].append((up[h] - probs[h]) / h_step * (0.1 if name == "null" else sigma[name]))
    for h in probs:
        assert errors[h] == pytest.approx(np.sqrt(np.sum(np.square(grads[h]))), rel=1e-4), h


def test_the_result_reports_and_keeps_the_odds(tmp_path):
    groups = _groups()
    planets, _ = groups.pop("planet")
    alternative_runs = [r for runs, _ in groups.values() for r in runs]
    priors = Priors(r_p=(0.2, 0.5), inc=(29.0, 31.0), PA=(59.0, 61.0), dRA=(-0.01, 0.01), dDec=(-0.01, 0.01))
    result = PosteriorResult(planets, priors, np.array([0.5, 0.5]), null=_null(), alternative_runs=alternative_runs)
    probs = result.model_probabilities
    assert result.p_planet == pytest.approx(probs["planet"]) and sum(probs.values()) == pytest.approx(1.0)
    assert result.hypothesis_probabilities["arc/vortex"] == pytest.approx(probs["arc/vortex"])
    assert sum(result.hypothesis_probabilities.values()) == pytest.approx(1.0)
    text = result.verdict
    assert text.startswith("Posterior odds: P(planet) = ") and "most probable: arc/vortex (arc_b:" in text
    assert "Planet against none:" in text
    loaded = PosteriorResult.load(result.save(tmp_path / "odds.h5"))
    assert loaded.model_probabilities == pytest.approx(probs)
    assert loaded.model_probability_errors == pytest.approx(result.model_probability_errors)
    d = result.to_dict()
    assert d["model_probabilities"] == pytest.approx(probs) and len(d["alternative_runs"]) == 3
    # without alternatives nothing changes: planet against none
    plain = PosteriorResult(planets, result.priors, np.array([0.5, 0.5]), null=_null())
    assert plain.model_probabilities is None and plain.verdict.startswith("planet preferred")


def test_alternatives_are_checked():
    assert check_alternatives(None) == () and check_alternatives("arc") == ("arc",)
    assert SamplingSettings(alternatives=["arc", "eccentric_ring"]).alternatives == ("arc", "eccentric_ring")
    assert SamplingSettings(alternatives=[]).alternatives is None
    with pytest.raises(InputError, match="name each of 'arc', 'eccentric_ring' at most once"):
        SamplingSettings(alternatives=["arc", "vortex"])
    with pytest.raises(InputError, match="at most once"):
        check_alternatives(["arc", "arc"])


def test_grid_evidence_is_lowered_by_its_hypothesis_over_count_never_raised():
    from types import SimpleNamespace

    from spiralbayes.inference.posterior.sampler import lower_grid_runs

    null = _null(-3.0)
    grids = {name: SimpleNamespace(ln_bayes=value) for name, value in (("a", 20.0), ("b", 21.0), ("c", 19.0))}
    runs = {"a": _run("a", 10.0, 0.05), "b": _run("b", 11.0, 0.05), "c": _run("c", -3.0 + 19.0, 0.5)}
    runs["c"].mode = "scan"
    # the sampled a and b sit 7 below their grid values (-3 + 20 = 17 against 10, 18 against 11)
    assert lower_grid_runs(runs, {"c"}, grids, null) == pytest.approx(-7.0)
    assert runs["c"].ln_evidence == pytest.approx(9.0) and runs["c"].diagnostics["evidence"]["grid_offset"] == -7.0
    # a grid that under-counts (the sampled ones above it) leaves the unsampled as they are
    up = {"a": _run("a", 20.0, 0.05), "c": _run("c", 16.0, 0.5)}
    up["c"].mode = "scan"
    assert lower_grid_runs(up, {"c"}, grids, null) == pytest.approx(3.0) and up["c"].ln_evidence == 16.0
    assert lower_grid_runs({"c": runs["c"]}, {"c"}, grids, null) is None  # nothing sampled: nothing measured
