"""The two simulation backends observe the same sky alike (marker ``casa``; needs CASA).

What each assumes (see :mod:`spiralbayes.simulate.casa`): the package predicts the disc exactly
(Hankel transform) and the planet by NUFFT of a fine rendering, and adds Gaussian noise set by the
preset's image sensitivity (35 uJy/beam for the fiducial set-up); CASA degrids the FFT of a 4-mas
FITS model, multiplies by the 12-m primary beam and adds noise from its ATM model (PWV 0.9 mm) and
its efficiencies. Measured here: rows matched one to one with CASA's UVW = -(u, v) of the package to
2e-5; noise-free visibilities equal to 0.3 % RMS (0.06 % at the shortest baselines, the primary beam;
0.26 % beyond 2 Mlambda, the model's 4-mas pixels), the spiral at 0.997 of its amplitude; with the
earlier 30-s integrations CASA's Stokes-I noise was 7.09 mJy per visibility against the package's
6.65 mJy, i.e. 6.5 % more (37.2 vs 35.0 uJy/beam); with the presets' 60-s integrations (same N, the
paper's times on source) it is 0.753 times the package's, as t_int^-1/2 predicts.
"""

from __future__ import annotations

import numpy as np
import pytest

from spiralbayes.simulate import DiscModel, disc_visibilities, get_preset, simulate_observation
from spiralbayes.templates import make_template
from tests._support.casa_support import require_casa
from tests._support.helpers import DISTANCE, GEOMETRY, R_P_TRUE

pytestmark = pytest.mark.casa

DISC = DiscModel(distance=DISTANCE, tau_ref=3.0)


@pytest.fixture(scope="module")
def planet():
    require_casa()
    return make_template(1.0, 3.0, 10.0, "R")


@pytest.fixture(scope="module")
def both(planet):
    kw = dict(r_p=R_P_TRUE, phi_p=0.0, seed=1)
    package = simulate_observation("fiducial", DISC, GEOMETRY, planet, **kw)
    casa_clean = simulate_observation("fiducial", DISC, GEOMETRY, planet, add_noise=False, backend="casa", **kw)
    casa_noisy = simulate_observation("fiducial", DISC, GEOMETRY, planet, backend="casa", **kw)
    return package, casa_clean, casa_noisy


def test_same_baselines_row_by_row(both):
    package, casa, _ = both
    assert casa.n == package.n
    length = np.hypot(package.u, package.v)
    # CASA stores uvw(ANTENNA1) - uvw(ANTENNA2), the package uvw(j) - uvw(i) for i < j: opposite signs
    mismatch = np.hypot(casa.u + package.u, casa.v + package.v) / length
    assert np.max(mismatch) < 1e-4, np.max(mismatch)
    assert abs(casa.provenance["hour_angle_offset_s"]["remaining_per_configuration"][1]) < 2.0


def test_noise_free_visibilities_agree(both, planet):
    _, casa, _ = both
    model = disc_visibilities(casa.u, casa.v, DISC.profile(casa.wavelength), GEOMETRY, DISC.r_max, r_min=DISC.r_min,
                              perturbation=planet, r_p=R_P_TRUE, phi_p=0.0)
    diff = casa.V - model
    rel = np.sqrt(np.mean(np.abs(diff) ** 2) / np.mean(np.abs(model) ** 2))
    assert rel < 0.01, rel  # measured 0.27 %
    short = np.hypot(casa.u, casa.v) < 5e5
    ratio = np.median((casa.V[short] / model[short]).real)
    assert 0.995 < ratio <= 1.0, ratio  # CASA's primary beam attenuates the disc by < 0.5 %
    # the spiral is in CASA's data at its full amplitude: CASA's visibilities minus the planet-free
    # disc's, projected on the package's spiral signal, give the spiral's amplitude (measured 0.997).
    # (The disc's own 0.3 % mismatch is comparable in power to the recalibrated templates' weaker
    # spiral, so a power ratio no longer tells; the projection does, the mismatch being uncorrelated.)
    no_planet = disc_visibilities(casa.u, casa.v, DISC.profile(casa.wavelength), GEOMETRY, DISC.r_max,
                                  r_min=DISC.r_min)
    spiral = model - no_planet
    amplitude = np.real(np.vdot(spiral, casa.V - no_planet)) / np.real(np.vdot(spiral, spiral))
    assert 0.99 < amplitude < 1.005, amplitude


def test_noise_and_weights(both):
    package, clean, noisy = both
    noise = noisy.V - clean.V
    # CASA's weights are statistical: each of Re, Im has variance 1 / w
    assert np.mean(noisy.weights * np.abs(noise) ** 2) / 2.0 == pytest.approx(1.0, abs=0.02)
    sigma_casa = np.sqrt(np.mean(1.0 / noisy.weights))
    sigma_package = np.sqrt(np.mean(1.0 / package.weights))
    # CASA's noise follows the radiometer equation for the preset's integrations (60 s since the
    # presets state the paper's times on source); the package's follows the paper's image noise for
    # the same N. At the earlier 30-s integrations CASA's was 6.5 % above the package's; per
    # visibility it scales as t_int^-1/2, so now 1.065 / sqrt(2) = 0.753 (measured 0.753): ALMA's
    # nominal T_sys gives ~25 % less noise than the paper's sensitivities (simulate.PRESETS docs).
    preset = get_preset("fiducial")
    ratio = sigma_casa / sigma_package * np.sqrt(preset.integration_time / 30.0)
    assert 1.0 < ratio < 1.15, ratio  # CASA's Tsys at PWV 0.9 mm and its efficiencies, at 30-s integrations
    np.testing.assert_array_equal(clean.weights, noisy.weights)  # same seed, same noise, same weights
