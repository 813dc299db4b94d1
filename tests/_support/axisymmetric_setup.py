"""A known axisymmetric disc and its synthetic observation, shared by the frank-model and plot tests."""

import numpy as np

from spiralbayes.axisymmetric import AxisymmetricModel
from spiralbayes.geometry import DiscGeometry
from spiralbayes.visibilities import Visibilities

TRUE_GEOMETRY = DiscGeometry(inc=35.0, PA=60.0, dRA=0.010, dDec=-0.005)
PEAK = 1e10  # Jy/sr
SIGMA = 2e-3  # Jy, noise of Re and Im of each visibility


def ring_and_core(r):
    """Known profile [Jy/sr]: Gaussian core (0.12") plus a Gaussian ring at 0.5" (width 0.08")."""
    r = np.asarray(r, dtype=float)
    return PEAK * (np.exp(-0.5 * (r / 0.12) ** 2) + 0.5 * np.exp(-0.5 * ((r - 0.5) / 0.08) ** 2))


def random_baselines(rng, n, q_min=1e4, q_max=2.5e6):
    """Log-uniform baseline lengths, uniform angles [lambda]."""
    q = 10 ** rng.uniform(np.log10(q_min), np.log10(q_max), n)
    theta = rng.uniform(0, 2 * np.pi, n)
    return q * np.cos(theta), q * np.sin(theta)


def truth_model() -> AxisymmetricModel:
    """The true disc as a fine Fourier–Bessel series (N = 400, Rmax = 2")."""
    return AxisymmetricModel.from_profile(ring_and_core, TRUE_GEOMETRY, N=400, Rmax=2.0)


def synthetic_observation(model: AxisymmetricModel) -> Visibilities:
    rng = np.random.default_rng(2)
    u, v = random_baselines(rng, 10_000)
    V = model.visibilities(u, v) + SIGMA * (rng.normal(size=u.size) + 1j * rng.normal(size=u.size))
    return Visibilities(u, v, V, np.full(u.size, SIGMA ** -2), provenance={"source": "test synthetic"})
