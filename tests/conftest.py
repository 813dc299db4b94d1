"""Shared fixtures: synthetic fiducial observations with and without a planet (built once)."""

import warnings

import numpy as np
import pytest

from spiralbayes import DiscGeometry
from spiralbayes.simulate import DiscModel, simulate_observation

GEOMETRY = DiscGeometry(30.0, 60.0)
DISTANCE = 140.0
R_P_TRUE = 50.0 / DISTANCE  # 50 au at 140 pc
SCAN_RP = np.linspace(0.02, 0.5, 25)  # the paper's 25 radii


@pytest.fixture(scope="session")
def planet_templates():
    from spiralbayes.templates import make_template

    right = make_template(1.0, 3.0, 10.0, "R")
    return right, right.mirror()


@pytest.fixture(scope="session")
def planet_observation(planet_templates):
    """Fiducial set-up, 1 M_th / tau0 = 3 / beta = 10 right-handed planet at (50 au, 0 deg), frank fit."""
    from spiralbayes.axisymmetric import fit_axisymmetric

    disc = DiscModel(distance=DISTANCE, tau_ref=3.0)
    vis = simulate_observation("fiducial", disc, GEOMETRY, planet_templates[0], r_p=R_P_TRUE, phi_p=0.0, seed=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        axisym = fit_axisymmetric(vis, GEOMETRY, progress=False)
    return vis, axisym


@pytest.fixture(scope="session")
def planet_scan(planet_observation, planet_templates):
    from spiralbayes.scan import scan

    vis, axisym = planet_observation
    return scan(vis, axisym, list(planet_templates), GEOMETRY, r_p=SCAN_RP, distance=DISTANCE, progress=False)
