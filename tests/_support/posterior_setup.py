"""The posterior tests' synthetic observation (seeded), shared by the likelihood, sampler and CLI tests.

3000 random baselines up to 2 Mlambda, a smooth exponential disc, a strong right-handed 3 M_th
template planted with the exact type-3 NUFFT (:func:`spiralbayes.model.perturbation_visibilities`),
Gaussian noise. The sampler starts from a geometry off by 20 mas in RA and 2 deg in inclination
(the "frank geometry" of the tests).
"""

import numpy as np

from spiralbayes.axisymmetric import AxisymmetricModel
from spiralbayes.geometry import DiscGeometry
from spiralbayes.inference.posterior.priors import Priors
from spiralbayes.model import perturbation_visibilities
from spiralbayes.templates import make_template
from spiralbayes.visibilities import Visibilities

TRUE_GEOMETRY = DiscGeometry(40.0, 70.0, 0.005, -0.01)
START_GEOMETRY = DiscGeometry(42.0, 70.0, 0.025, -0.01)  # 2 deg and 20 mas off
R_P, PHI_P = 0.35, 2.0
TRUTH = np.array([R_P, PHI_P, 40.0, 70.0, 0.005, -0.01])
R_RANGE = (0.15, 0.6)


def profile(r):
    r = np.asarray(r, dtype=float)
    return 5e10 * np.exp(-r / 0.3 - (r / 0.8) ** 6)


def build_setup() -> dict:
    template = make_template(3.0, 0.3, 0.0, "R", n_x=160, n_phi=360)
    truth_model = AxisymmetricModel.from_profile(profile, TRUE_GEOMETRY)
    rng = np.random.default_rng(1)
    n = 3000
    q = 2e6 * np.sqrt(rng.uniform(4e-4, 1, n))
    th = rng.uniform(0, 2 * np.pi, n)
    u, v = q * np.cos(th), q * np.sin(th)
    dV = perturbation_visibilities(u, v, TRUE_GEOMETRY, truth_model.brightness, template, R_P, PHI_P)
    sigma = np.sqrt(np.sum(np.abs(dV) ** 2) / 600.0)  # the planet alone: chi2 ~ 600
    V = truth_model.visibilities(u, v, TRUE_GEOMETRY) + dV + sigma * (rng.normal(size=n) + 1j * rng.normal(size=n))
    vis = Visibilities(u, v, V, np.full(n, sigma ** -2))
    model = AxisymmetricModel.from_profile(profile, START_GEOMETRY)
    priors = Priors.default(model, r_p=R_RANGE)
    return {"vis": vis, "model": model, "template": template, "priors": priors}


# -- a weak planet (Delta BIC ~ 30) seen through a frank fit made 3 deg off in inclination ----------
WEAK_TRUTH = {"r_p": 0.35, "phi_p": 0.05, "A": 0.4, "inc": 40.0, "PA": 70.0, "dRA": 0.005, "dDec": -0.01}
WEAK_START = DiscGeometry(43.0, 70.0, 0.005, -0.01)  # frank is fitted 3 deg off in inclination
WEAK_N_VIS = 1500
WEAK_DELTA_BIC = 30.0


def weak_template():
    return make_template(3.0, 0.3, 0.0, "R", n_x=160, n_phi=360)


def build_weak_observation(planet: bool = True, seed: int = 11) -> Visibilities:
    """1500 random baselines; noise set so that the planet (A = 0.4) has Delta BIC = 30.

    ``planet=False``: the same disc and noise level without the planet (a different noise seed).
    """
    from spiralbayes.inference.scan.statistics import bic_threshold

    template = weak_template()
    truth = AxisymmetricModel.from_profile(profile, TRUE_GEOMETRY, N=80)
    rng = np.random.default_rng(seed)
    n = WEAK_N_VIS
    q = 2e6 * np.sqrt(rng.uniform(4e-4, 1, n))
    th = rng.uniform(0, 2 * np.pi, n)
    u, v = q * np.cos(th), q * np.sin(th)
    dV = WEAK_TRUTH["A"] * perturbation_visibilities(u, v, TRUE_GEOMETRY, truth.brightness, template,
                                                     WEAK_TRUTH["r_p"], WEAK_TRUTH["phi_p"])
    sigma = np.sqrt(np.sum(np.abs(dV) ** 2) / (WEAK_DELTA_BIC + bic_threshold(n)))
    V = truth.visibilities(u, v, TRUE_GEOMETRY) + sigma * (rng.normal(size=n) + 1j * rng.normal(size=n))
    if planet:
        V = V + dV
    return Visibilities(u, v, V, np.full(n, sigma ** -2))
