"""χ², log-likelihood, BIC and the Δχ² decomposition."""

import numpy as np
import pytest

from spiralbayes.inference.scan.statistics import (
    bic_threshold,
    chi2,
    delta_bic,
    delta_chi2_from_terms,
    fitted_amplitude,
    gaussian_log_likelihood,
)


def test_chi2_and_likelihood_match_scipy():
    from scipy.stats import norm

    rng = np.random.default_rng(0)
    sigma = rng.uniform(0.5, 2, 50)
    obs = rng.normal(size=50) + 1j * rng.normal(size=50)
    model = rng.normal(size=50) + 1j * rng.normal(size=50)
    w = 1 / sigma ** 2
    assert chi2(model, obs, w) == pytest.approx(np.sum(np.abs(model - obs) ** 2 / sigma ** 2))
    ref = norm.logpdf(obs.real, model.real, sigma).sum() + norm.logpdf(obs.imag, model.imag, sigma).sum()
    assert gaussian_log_likelihood(model, obs, w) == pytest.approx(ref)


def test_bic_threshold_is_the_papers_6_ln_N():
    # Table 1 of Stevenson et al. (2024): 63 for the fiducial set-up (N ~ 3.6e4)
    assert bic_threshold(36_000) == pytest.approx(6 * np.log(36_000))
    assert round(bic_threshold(36_000)) == 63
    assert delta_bic(100.0, 36_000) == pytest.approx(100 - 6 * np.log(36_000))
    with pytest.raises(ValueError, match="n_data"):
        bic_threshold(0)


def test_decomposition_equals_direct_chi2_difference():
    rng = np.random.default_rng(1)
    n = 200
    w = rng.uniform(0.5, 2, n)
    VA = rng.normal(size=n) + 1j * rng.normal(size=n)
    dV = 0.3 * (rng.normal(size=n) + 1j * rng.normal(size=n))
    VO = VA + 0.7 * dV + 0.1 * (rng.normal(size=n) + 1j * rng.normal(size=n))
    R = VO - VA
    cross = np.sum(w * (np.conj(R) * dV).real)
    power = np.sum(w * np.abs(dV) ** 2)
    direct = chi2(VA, VO, w) - chi2(VA + dV, VO, w)
    assert delta_chi2_from_terms(cross, power) == pytest.approx(direct)
    # free amplitude: the best A = 0.7-ish, and no fixed A does better
    best = delta_chi2_from_terms(cross, power, "free")
    grid = [chi2(VA, VO, w) - chi2(VA + a * dV, VO, w) for a in np.linspace(0, 2, 401)]
    assert best >= max(grid) - 1e-9
    assert best == pytest.approx(max(grid), rel=1e-4)
    amplitudes = np.linspace(0, 2, 401)
    a_best = fitted_amplitude(cross, power, "free")
    assert abs(a_best - amplitudes[int(np.argmax(grid))]) <= amplitudes[1]  # the brute-force argmax
    assert fitted_amplitude(cross, power) == 1.0 and fitted_amplitude(cross, power, 0.5) == 0.5
    assert fitted_amplitude(-cross, power, "free") == 0.0  # anti-correlated: no spiral
    with pytest.raises(ValueError, match="amplitude"):
        delta_chi2_from_terms(cross, power, "best")
