"""Built-in wake generator: geometry, amplitude trends, cooling, radiative transfer."""

import numpy as np
import pytest

from spiralbayes.templates.burgers import solve_burgers


def test_burgers_conserves_and_decays_as_nwave():
    n, L = 2048, 200.0
    dx = L / n
    eta = -L / 2 + dx * np.arange(n)
    u0 = np.exp(-0.5 * eta**2)
    times = np.array([0.0, 50.0, 200.0, 800.0])
    u = solve_burgers(u0, dx, times)
    np.testing.assert_allclose(u.sum(axis=1) * dx, u0.sum() * dx, rtol=1e-10)  # conservative
    C = np.sqrt(2 * np.pi)  # positive area
    for k in (2, 3):
        assert u[k].max() == pytest.approx(np.sqrt(2 * C / times[k]), rel=0.08)
