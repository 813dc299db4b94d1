"""The posterior's planet mass as a credible range over morphology variants and H/r (issue 22), on a
result built by hand: template evidences fixed so that every probability is known in closed form."""

import json

import numpy as np
import pytest

from spiralbayes.exceptions import InputError
from spiralbayes.inference.posterior.priors import Priors
from spiralbayes.inference.posterior.results import NullRun, PosteriorResult, TemplateRun
from spiralbayes.units import thermal_mass

# (variant, mass [M_th], h_p, P(T | data, planet)): the evidences are ln of these (uniform prior)
TEMPLATES = [
    ("compromise", 1.0, 0.07, 0.40),
    ("hydro", 0.3, 0.05, 0.30),
    ("wakeflow", 1.0, 0.10, 0.15),
    ("compromise", 3.0, 0.07, 0.10),
    ("hydro", 0.1, 0.07, 0.05),
]


def run(variant, mass, h_p, p) -> TemplateRun:
    prefix = "wake" if variant == "compromise" else variant
    meta = {"name": f"{prefix}_m{mass:g}_tau3_b0_h{h_p:g}_R", "mass": mass, "tau0": 3.0, "beta": 0.0, "hand": "R",
            "h_p": h_p, "variant": variant}
    samples = np.column_stack([np.full(20, 0.357), np.full(20, 0.7), np.ones(20), np.full(20, 30.0),
                               np.full(20, 60.0), np.zeros(20), np.zeros(20)])
    return TemplateRun(meta["name"], meta, "laplace", samples, np.zeros(6), np.eye(6), float(np.log(p)), 0.0,
                       float(np.log(p)))


def result(templates=TEMPLATES, ln_z0=-10.0) -> PosteriorResult:
    null = NullRun(np.zeros((10, 4)), np.zeros(4), np.eye(4), ln_z0, 0.0, ln_z0)
    priors = Priors((0.05, 0.6), (30.0, 1.0), (60.0, 1.0), (0.0, 0.01), (0.0, 0.01))
    return PosteriorResult([run(*t) for t in templates], priors, np.full(len(templates), 1 / len(templates)),
                           null=null)


def mjup(mass, h_p, mstar=0.8):
    return mass * thermal_mass(50.0, mstar, h_ref=h_p, r_ref=50.0, flaring=0.0, unit="Mjup")


def test_mass_marginal_sums_over_variants_and_h_p():
    marg = result().marginals()
    assert marg["mass"] == pytest.approx({0.1: 0.05, 0.3: 0.30, 1.0: 0.55, 3.0: 0.10})
    assert marg["variant"] == pytest.approx({"compromise": 0.50, "hydro": 0.35, "wakeflow": 0.15})


def test_credible_range_of_the_mass_marginal_and_in_jupiter_masses_with_each_h_p():
    # by mass: 1 (0.55) + 0.3 (0.30) = 0.85 < 0.95, + 3 (0.10) = 0.95 -> 0.3-3 M_th
    m = result().mass_range()
    assert m["mth"] == [0.3, 3.0] and m["probability"]["mth"] == pytest.approx(0.95)
    # by (mass, h_p): 0.40 + 0.30 + 0.15 + 0.10 = 0.95: (1, .07), (0.3, .05), (1, .10), (3, .07)
    pairs = [(1.0, 0.07), (0.3, 0.05), (1.0, 0.10), (3.0, 0.07)]
    assert m["mjup"] == pytest.approx([min(mjup(*p) for p in pairs), max(mjup(*p) for p in pairs)], rel=1e-12)
    # at 68 %: 1 M_th alone holds 0.55, with 0.3 M_th 0.85
    assert result().mass_range(level=0.68)["mth"] == [0.3, 1.0]
    assert result().mass_range(level=0.5)["mth"] == [1.0, 1.0]
    with pytest.raises(InputError, match="credibility level"):
        result().mass_range(level=1.5)


def test_the_verdict_and_json_carry_the_range():
    r = result(ln_z0=-10.0)
    assert r.planet_preferred
    lo, hi = (f"{x:.2g}" for x in r.mass_range()["mjup"])
    assert f"planet mass 0.3-3 M_th ({lo}-{hi} M_Jup for M_* = 0.8 M_sun) (95 % credible" in r.verdict
    d = json.loads(json.dumps(r.to_dict(), allow_nan=False))
    assert d["mass_range"]["mth"] == [0.3, 3.0]
    assert "planet mass" not in result(ln_z0=10.0).verdict  # no planet preferred: no mass quoted
