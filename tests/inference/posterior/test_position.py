"""The position integral of a template's likelihood, and its refinement around a narrow peak.

References: a Gaussian ``ln L`` in (r_p, φ_p), whose integral over the prior is known in closed form, and
a peak whose ``ln L`` is not quadratic (``P (exp(-q/2) - 1)``, the shape of a correlation's peak), integrated
by adaptive quadrature (``scipy.integrate.dblquad``).
"""

from __future__ import annotations

import numpy as np
import pytest

from spiralbayes.exceptions import InputError
from spiralbayes.inference.posterior.position import (
    MIN_WINDOW_STEPS,
    PositionLevel,
    composite_ln_bayes,
    peak_window,
    position_ln_bayes,
)

PRIOR = (0.2, 0.5)
R0, PHI0 = 0.3317, 1.234


SIGMA_PHI = np.radians(0.5)


def gaussian_ln_like(r, phi, peak=60.0, sigma_r=0.004, sigma_phi=SIGMA_PHI):
    dphi = np.angle(np.exp(1j * (phi[None, :] - PHI0)))
    return peak - 0.5 * ((r[:, None] - R0) / sigma_r) ** 2 - 0.5 * (dphi / sigma_phi) ** 2


def exact_ln_bayes(peak=60.0, sigma_r=0.004, sigma_phi=SIGMA_PHI):
    """∫∫ L dr dφ / ((hi - lo) 2π) for the Gaussian (its tails well inside the prior)."""
    return peak + np.log(np.sqrt(2 * np.pi) * sigma_r / (PRIOR[1] - PRIOR[0])) + np.log(sigma_phi / np.sqrt(2 * np.pi))


def level(n_r, n_phi, window=PRIOR, ln_like=gaussian_ln_like):
    r = np.linspace(*window, n_r)
    phi = 2 * np.pi * np.arange(n_phi) / n_phi
    return PositionLevel(r, phi, (float(r[0]), float(r[-1])), {0: ln_like(r, phi)})


SHARP = dict(p=80.0, s_r=0.01, s_phi=np.radians(2.0))   # L's peak: 0.0011" and 0.22 deg wide


def sharp_ln_like(r, phi):
    dphi = np.angle(np.exp(1j * (np.asarray(phi)[None, :] - PHI0)))
    q = ((np.asarray(r)[:, None] - R0) / SHARP["s_r"]) ** 2 + (dphi / SHARP["s_phi"]) ** 2
    return SHARP["p"] * (np.exp(-0.5 * q) - 1.0) + 40.0


def sharp_ln_bayes() -> float:
    from scipy.integrate import dblquad

    w_r, w_phi = 12 * SHARP["s_r"] / np.sqrt(SHARP["p"]), 12 * SHARP["s_phi"] / np.sqrt(SHARP["p"])
    value, _ = dblquad(lambda phi, r: np.exp(sharp_ln_like([r], [phi])[0, 0] - 40.0), R0 - w_r, R0 + w_r,
                       PHI0 - w_phi, PHI0 + w_phi, epsabs=0.0, epsrel=1e-8)
    # far from the peak L/L_0 = e^(40-80): negligible beside the peak's e^40 x its area
    return 40.0 + np.log(value / ((PRIOR[1] - PRIOR[0]) * 2 * np.pi))


def test_a_resolved_gaussian_integrates_to_its_closed_form():
    fine = level(301, 1440)
    assert composite_ln_bayes([fine], 0, PRIOR) == pytest.approx(exact_ln_bayes(), abs=1e-3)


def test_segments_of_the_radii_add_up_to_the_whole():
    lev = level(61, 720)
    whole = position_ln_bayes(lev.r_p, lev.phi_p, lev.log_like[0], PRIOR)
    parts = [position_ln_bayes(lev.r_p, lev.phi_p, lev.log_like[0], PRIOR, r_range=s)
             for s in ((0.2, 0.31), (0.31, 0.35), (0.35, 0.5))]
    assert np.logaddexp.reduce(parts) == pytest.approx(whole, abs=1e-3)
    assert position_ln_bayes(lev.r_p, lev.phi_p, lev.log_like[0], PRIOR, r_range=(0.6, 0.7)) == -np.inf
    with pytest.raises(InputError, match="outside the r_p prior"):
        position_ln_bayes(lev.r_p, lev.phi_p, lev.log_like[0], (0.6, 0.7))


def test_refining_around_a_peak_narrower_than_the_cells_recovers_the_quadrature():
    exact = sharp_ln_bayes()
    coarse = level(31, 90, ln_like=sharp_ln_like)   # cells of 0.01" and 4 deg
    assert abs(composite_ln_bayes([coarse], 0, PRIOR) - exact) > 1.0
    levels = [coarse]
    for _ in range(4):
        window = peak_window(levels[-1], {0: 0.0})
        step = float(np.diff(levels[-1].r_p)[0])
        # the window reaches MIN_WINDOW_STEPS steps either side of the grid's peak (within half a step of R0)
        assert min(R0 - window[0], window[1] - R0) >= (MIN_WINDOW_STEPS - 0.5) * step
        n = 2 * int(round((window[1] - window[0]) / step)) + 1
        levels.append(level(n, 2 * levels[-1].phi_p.size, window, sharp_ln_like))
    assert composite_ln_bayes(levels, 0, PRIOR) == pytest.approx(exact, abs=0.01)
    assert composite_ln_bayes(levels, 0, PRIOR, half=True) == pytest.approx(exact, abs=0.05)
    # the radii outside the windows still count: a wide bump away from the peak, integrated on the coarse level
    for lev in levels:
        bump = 35.0 - 0.5 * ((lev.r_p[:, None] - 0.45) / 0.02) ** 2 + 0.0 * lev.phi_p[None, :]
        lev.log_like[1] = np.logaddexp(lev.log_like[0], bump)
    bump_alone = 35.0 + np.log(np.sqrt(2 * np.pi) * 0.02 / 0.3) + np.log(0.5 * (1 + 0.98758))  # Φ(2.5)
    assert composite_ln_bayes(levels, 1, PRIOR) == pytest.approx(np.logaddexp(exact, bump_alone), abs=0.01)
