"""A small, fast synthetic observation for the limits, completeness, injection and calibration tests.

ALMA C-4 alone (baselines up to 0.9 Mlambda, ~1e4 visibilities in 11 min at 0.87 mm) keeps the
quadratures small; the disc is the paper's power-law disc at 140 pc with the true axisymmetric model
(no frank fit), so residuals are exactly planet + noise. Templates: the family tau0 = 0.3, beta = 10
with masses 0.3, 1 and 3 M_th, both hands, on a coarse grid.
"""

import functools
import warnings

import numpy as np

from spiralbayes import AxisymmetricModel, DiscGeometry
from spiralbayes.simulate import DiscModel, observe, uv_coverage
from spiralbayes.templates import make_template

GEOMETRY = DiscGeometry(30.0, 60.0)
WAVELENGTH = 0.87e-3
DISTANCE = 140.0
R_P = np.array([0.15, 0.25, 0.35, 0.45])
N_PHI = 30
MASSES = (0.3, 1.0, 3.0)
GRID = dict(n_x=120, n_phi=360)


@functools.cache
def coverage():
    return uv_coverage(["C-4"], -25.0, (-0.1, 0.1), 60.0, WAVELENGTH)


@functools.cache
def disc_model() -> AxisymmetricModel:
    disc = DiscModel(distance=DISTANCE, tau_ref=0.3)
    return AxisymmetricModel.from_profile(disc.profile(WAVELENGTH), GEOMETRY)


@functools.cache
def family(tau0: float = 0.3, beta: float = 10.0, masses=MASSES) -> tuple:
    """R and L templates of each mass, in the order R(m1), L(m1), R(m2), ..."""
    out = []
    for mass in masses:
        right = make_template(mass, tau0, beta, "R", **GRID)
        out += [right, right.mirror()]
    return tuple(out)


def observation(sensitivity: float, seed: int = 0):
    """Model visibilities plus noise of the given image sensitivity [Jy/beam], no planet."""
    model = disc_model()
    cov = coverage()
    return observe(model.visibilities(cov.u, cov.v, GEOMETRY), cov, sensitivity=sensitivity, seed=seed)


def scanned(sensitivity: float, seed: int = 0, templates=None, n_phi: int = N_PHI, r_p=R_P):
    """(vis, model, templates, ScanResult) of a planet-free observation."""
    from spiralbayes.inference.scan.run import scan

    templates = list(templates or family())
    vis = observation(sensitivity, seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = scan(vis, disc_model(), templates, GEOMETRY, r_p=r_p, n_phi_p=n_phi, distance=DISTANCE,
                      progress=False)
    return vis, disc_model(), templates, result
