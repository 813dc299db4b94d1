"""A planet between the bank's masses: the weak observation's disc with a generator spiral at 0.5 or 2 M_th.

The spiral is the generator's own template at that mass (not the family's interpolation), planted with
the exact type-3 transform; the noise is set so that the planet alone has ``chi2 = snr2``.
"""

import numpy as np

from spiralbayes.axisymmetric import AxisymmetricModel
from spiralbayes.model import perturbation_visibilities
from spiralbayes.templates import make_template
from spiralbayes.visibilities import Visibilities
from tests._support.posterior_setup import TRUE_GEOMETRY, profile

GRID = dict(n_x=160, n_phi=360)
TAU0, BETA = 0.3, 0.0
R_P, PHI_P = 0.35, 2.0


def bank_members(hand: str = "R") -> list:
    """The family's bank templates (0.1, 0.3, 1, 3 M_th) on the tests' grid."""
    return [make_template(m, TAU0, BETA, hand, **GRID) for m in (0.1, 0.3, 1.0, 3.0)]


def planted_observation(mass: float, *, snr2: float = 400.0, n: int = 1500, seed: int = 5) -> Visibilities:
    return plant(make_template(mass, TAU0, BETA, "R", **GRID), snr2=snr2, n=n, seed=seed)


def plant(template, *, snr2: float = 400.0, n: int = 1500, seed: int = 5) -> Visibilities:
    """``template`` at (R_P, PHI_P) in the weak observation's disc, the noise set so that it alone has
    ``chi2 = snr2``."""
    truth = AxisymmetricModel.from_profile(profile, TRUE_GEOMETRY, N=80)
    rng = np.random.default_rng(seed)
    q = 2e6 * np.sqrt(rng.uniform(4e-4, 1, n))
    th = rng.uniform(0, 2 * np.pi, n)
    u, v = q * np.cos(th), q * np.sin(th)
    dV = perturbation_visibilities(u, v, TRUE_GEOMETRY, truth.brightness, template, R_P, PHI_P)
    sigma = np.sqrt(np.sum(np.abs(dV) ** 2) / snr2)
    V = truth.visibilities(u, v, TRUE_GEOMETRY) + dV + sigma * (rng.normal(size=n) + 1j * rng.normal(size=n))
    return Visibilities(u, v, V, np.full(n, sigma ** -2))
