"""Evidence estimators against closed forms: a Gaussian x periodic (von Mises) target, flat directions
that must not raise, and the Savage–Dickey ratio of the amplitude."""

import numpy as np
import pytest
from scipy.special import i0

from spiralbayes.inference.posterior.evidence import (
    GaussianGeometry,
    StudentT,
    hessian_cov,
    importance_evidence,
    laplace_evidence,
    savage_dickey_log_bayes,
)
from spiralbayes.inference.posterior.likelihood import log_amplitude_integral


def _target(kappa):
    """ln(L pi) on (r, phi, g): r ~ U(0, 1) prior, phi ~ U(0, 2 pi), g ~ N(0, 1) prior."""
    def lp(x):
        r, phi, g = x
        if not 0 <= r <= 1:
            return -np.inf
        prior = -np.log(2 * np.pi) - 0.5 * g * g - 0.5 * np.log(2 * np.pi)
        like = -0.5 * ((r - 0.4) / 0.02) ** 2 + kappa * np.cos(phi - 0.1) - 0.5 * ((g - 0.3) / 0.1) ** 2
        return prior + like

    # closed form: int over r (Gaussian well inside [0, 1]), phi (von Mises), g (product of Gaussians)
    lnz_r = np.log(0.02 * np.sqrt(2 * np.pi))
    lnz_phi = np.log(i0(kappa))  # (1 / 2 pi) int exp(kappa cos) = I0(kappa)
    s2 = 1.0 / (1.0 + 1.0 / 0.01)
    mean = s2 * 0.3 / 0.01
    lnz_g = 0.5 * np.log(s2) + 0.5 * mean ** 2 / s2 - 0.5 * 0.3 ** 2 / 0.01
    return lp, lnz_r + lnz_phi + lnz_g


@pytest.mark.parametrize("kappa", [30.0, 0.0])
def test_defensive_importance_sampling_matches_closed_form(kappa):
    lp, lnz = _target(kappa)
    rng = np.random.default_rng(0)
    # a "chain": draws near the mode (for kappa = 0 phi is uniform: the plateau component covers it)
    chain = np.column_stack([rng.normal(0.4, 0.02, 2000), (0.1 + rng.normal(0, 0.2, 2000)) % (2 * np.pi),
                             rng.normal(0.3 / 1.01, 0.1, 2000)])
    centred = chain.copy()
    centred[:, 1] = (centred[:, 1] + np.pi) % (2 * np.pi) - np.pi
    scales = np.array([0.3, 1.8, 1.0])
    fit = StudentT(centred.mean(0), np.cov(centred, rowvar=False) * 1.44, scales, periodic=(1,))
    plateau = GaussianGeometry(np.array([0.3]), np.array([[0.02]]), np.array([1.0]), r_range=(0.0, 1.0))
    ev = importance_evidence(lp, [fit, plateau], [0.7, 0.3], 4000, rng)
    assert abs(ev["ln_evidence"] - lnz) < max(5 * ev["ln_evidence_err"], 0.05), (ev, lnz)


def test_flat_directions_give_the_prior_width_not_an_error():
    def f(x):  # flat in x[1], curved in x[0], not negative definite in x[2]
        return -0.5 * (x[0] / 0.1) ** 2 + 0.0 * x[1] + 0.5 * x[2] ** 2

    cov = hessian_cov(f, np.zeros(3), np.array([0.1, 1.0, 1.0]), max_var=np.array([1.0, 4.0, 9.0]))
    assert np.all(np.isfinite(cov)) and np.all(np.linalg.eigvalsh(cov) > 0)
    assert cov[0, 0] == pytest.approx(0.01, rel=1e-3)
    assert cov[1, 1] == pytest.approx(4.0) and cov[2, 2] == pytest.approx(9.0)
    assert np.isfinite(laplace_evidence(0.0, cov))


def test_savage_dickey_equals_the_amplitude_integral_when_exact():
    c1, c2 = np.full(50, 4.0), np.full(50, 2.0)
    assert savage_dickey_log_bayes(c1, c2, 2.0) == pytest.approx(log_amplitude_integral(4.0, 2.0, 2.0))


def test_importance_draws_resample_to_the_posterior():
    """``with_draws=True`` returns the draws and ln(L pi / q) behind ln Z (their mean weight is Z); resampled
    by weight they follow the posterior (reference: the closed-form posterior of g, N(0.297, 0.0995))."""
    from scipy.special import logsumexp

    lp, lnz = _target(0.0)
    rng = np.random.default_rng(3)
    proposal = StudentT(np.array([0.4, 0.0, 0.3]), np.diag([0.03, 2.0, 0.15]) ** 2, np.array([0.3, 1.8, 1.0]),
                        periodic=(1,))
    ev = importance_evidence(lp, [proposal], [1.0], 6000, rng, with_draws=True)
    draws, lw = ev["draws"], ev["log_weights"]
    assert draws.shape == (6000, 3) and lw.shape == (6000,)
    assert logsumexp(lw) - np.log(lw.size) == pytest.approx(ev["ln_evidence"], abs=1e-12)
    assert abs(ev["ln_evidence"] - lnz) < max(5 * ev["ln_evidence_err"], 0.05)
    w = np.exp(lw - lw.max())
    g = draws[rng.choice(lw.size, size=lw.size, p=w / w.sum()), 2]
    sd = np.sqrt(1.0 / (1.0 + 1.0 / 0.01))
    assert abs(g.mean() - 0.3 / 1.01) < 5 * sd / np.sqrt(ev["ess"]) and abs(g.std() / sd - 1) < 0.1
    assert "draws" not in importance_evidence(lp, [proposal], [1.0], 100, rng)  # only when asked
