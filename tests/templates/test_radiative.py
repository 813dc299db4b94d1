"""Built-in wake generator: geometry, amplitude trends, cooling, radiative transfer."""

import pytest

from spiralbayes.templates.radiative import dlnB_dlnT, midplane_temperature, planck_nu


def test_temperature_and_planck():
    assert midplane_temperature(1.0) == pytest.approx(19.7, abs=0.1)
    assert midplane_temperature(4.0) == pytest.approx(19.73 / 2, rel=1e-3)
    assert dlnB_dlnT(20.0, 0.87e-3) == pytest.approx(1.47, abs=0.01)
    # Rayleigh–Jeans limit at long wavelength
    lam = 1.0
    T = 30.0
    rj = 2 * 1.380649e-23 * T / lam**2 * 1.0
    assert planck_nu(T, lam) == pytest.approx(rj, rel=1e-3)
