"""The near-planet patch: the planet's surroundings in scale heights and back onto the map."""

from __future__ import annotations

import numpy as np

from spiralbayes.templates.learned.patch import PATCH_RADIUS, from_patch, to_patch, window

from .common import run_named


def test_near_planet_patch_goes_back_onto_the_map(runs):
    """The planet's surroundings in scale heights and back: a windowed map survives the round trip
    (bilinear both ways, 0.1 H_p steps) to 3 % of its RMS at H/r 0.04 and 6 % at 0.12 (the fit puts
    what it misses into the global map, so the two parts add up exactly), and the window reaches no
    further than the patch."""
    run = run_named(runs, "library:h0.07_mu1")
    rows = (run.x > 0.44) & (run.x < 2.28)
    x, phi = run.x[rows], run.phi
    for h_p, tolerance in ((0.04, 0.03), (0.12, 0.06)):
        local = window(x, phi, h_p) * run.dsigma[rows]
        back = from_patch(to_patch(local, x, phi, h_p), x, phi, h_p)
        err = np.sqrt(np.mean((back - local) ** 2) / np.mean(local**2))
        assert err < tolerance, (h_p, err)
        far = np.abs(x[:, None] - 1) > PATCH_RADIUS * h_p
        assert np.max(np.abs(local[np.broadcast_to(far, local.shape)])) < 5e-3 * np.max(np.abs(local))
