"""Shared fixtures, built once per session: synthetic fiducial observations with and without a planet,
the posterior tests' observation and likelihood, and a frank fit of a known disc."""

import warnings

import pytest

from spiralbayes.simulate import DiscModel, simulate_observation
from tests._support import axisymmetric_setup, posterior_setup
from tests._support.helpers import DISTANCE, GEOMETRY, R_P_TRUE, SCAN_RP


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
    from spiralbayes.inference.scan.run import scan

    vis, axisym = planet_observation
    return scan(vis, axisym, list(planet_templates), GEOMETRY, r_p=SCAN_RP, distance=DISTANCE, progress=False)


@pytest.fixture(scope="session")
def planet_alternatives(planet_observation):
    """The competing asymmetry models fitted to the planet observation (one start each)."""
    from spiralbayes.inference.detection.alternatives import fit_alternatives

    vis, axisym = planet_observation
    return fit_alternatives(vis, axisym, n_starts=1)


@pytest.fixture(scope="session")
def setup():
    """The posterior tests' observation (:mod:`tests._support.posterior_setup`)."""
    return posterior_setup.build_setup()


@pytest.fixture(scope="session")
def likelihood(setup):
    from spiralbayes.inference.posterior.conditional import SpiralLikelihood

    return SpiralLikelihood(setup["vis"], setup["model"], setup["template"], posterior_setup.R_RANGE)


@pytest.fixture(scope="session")
def truth_model():
    return axisymmetric_setup.truth_model()


@pytest.fixture(scope="session")
def synthetic(truth_model):
    return axisymmetric_setup.synthetic_observation(truth_model)


@pytest.fixture(scope="session")
def fixed_fit(synthetic):
    """The paper's hyperparameters, geometry held at the truth."""
    from spiralbayes.axisymmetric import fit_axisymmetric

    return fit_axisymmetric(synthetic, axisymmetric_setup.TRUE_GEOMETRY, nonnegative=True, progress=False)


@pytest.fixture(scope="session")
def limits_case():
    """A planet-free C-4 observation at 120 uJy/beam scanned with the tau0 = 0.3, beta = 10 family
    (:mod:`tests._support.limits_setup`): limits lie between the bank's masses."""
    from tests._support import limits_setup

    return limits_setup.scanned(120e-6)


@pytest.fixture(scope="session")
def bright_case():
    """The same disc at 35 uJy/beam: 1 and 3 M_th planets are detectable, 0.3 M_th are not."""
    from tests._support import limits_setup

    return limits_setup.scanned(35e-6, seed=5)
