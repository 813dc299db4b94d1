"""Antenna gain errors: checked against what a point source at the phase centre must show."""

from __future__ import annotations

import numpy as np
import pytest

from spiralbayes.exceptions import InputError
from spiralbayes.simulate import GainErrors, antenna_gain_series, observe, simulate_observation, uv_coverage

LAM = 0.87e-3


@pytest.fixture(scope="module")
def small_cov():
    """Ten antennas (45 baselines) for two hours at 30 s: 240 integrations."""
    pos = np.random.default_rng(4).uniform(-300.0, 300.0, size=(10, 3)) * [1, 1, 0.01]
    return uv_coverage(pos, -25.0, (-1.0, 1.0), 30.0, LAM)


def _point_source(cov, gains):
    return observe(np.ones(cov.n), cov, sigma=1.0, add_noise=False, gains=gains)


def test_baseline_phase_rms_is_sqrt2_times_the_antenna_rms(small_cov):
    # V = 1: arg V'_pq = phi_p - phi_q, the difference of two independent antennas
    gains = GainErrors(phase_rms_deg=8.0, coherence_s=60.0, seed=11)
    vis = _point_source(small_cov, gains)
    rms = np.degrees(np.sqrt(np.mean(np.angle(vis.V) ** 2)))
    # 10 antennas x 240 times over 2 h with 60-s coherence: ~1200 independent values per antenna
    assert rms == pytest.approx(np.sqrt(2.0) * 8.0, rel=0.05)
    assert np.allclose(np.abs(vis.V), 1.0)  # amp_rms = 0


def test_amplitude_rms_of_a_baseline(small_cov):
    vis = _point_source(small_cov, GainErrors(phase_rms_deg=0.0, amp_rms=0.04, coherence_s=60.0, seed=2))
    # |V'| = a_p a_q ~ 1 + alpha_p + alpha_q: rms sqrt(2) x 4 %
    assert np.std(np.abs(vis.V)) == pytest.approx(np.sqrt(2.0) * 0.04, rel=0.08)
    assert np.allclose(np.angle(vis.V), 0.0)


def test_closure_phases_vanish(small_cov):
    vis = _point_source(small_cov, GainErrors(phase_rms_deg=30.0, amp_rms=0.05, coherence_s=120.0, seed=5))
    index = {(a, b, t): k for k, (a, b, t) in enumerate(zip(vis.antenna1, vis.antenna2, vis.time))}
    t = vis.time[0]
    closures = []
    for p, q, r in [(0, 1, 2), (1, 4, 7), (2, 5, 9), (0, 3, 8)]:
        v_pq, v_qr, v_pr = (vis.V[index[(a, b, t)]] for a, b in ((p, q), (q, r), (p, r)))
        closures.append(np.angle(v_pq * v_qr * np.conj(v_pr)))
    assert np.max(np.abs(closures)) < 1e-12
    # the baseline phases themselves are far from zero
    assert np.degrees(np.std(np.angle(vis.V))) > 20.0


def test_autocorrelation_falls_to_1_over_e_at_the_coherence_time():
    tau = 300.0
    times = np.arange(0.0, 200_000.0, 30.0)
    g = antenna_gain_series(GainErrors(phase_rms_deg=10.0, coherence_s=tau, seed=7), times, 8)
    phase = np.angle(g)
    lag = int(tau / 30.0)
    rho = np.mean(phase[lag:] * phase[:-lag]) / np.mean(phase ** 2)
    assert rho == pytest.approx(np.exp(-1.0), abs=0.04)
    assert np.degrees(phase.std()) == pytest.approx(10.0, rel=0.05)
    rho_short = np.mean(phase[1:] * phase[:-1]) / np.mean(phase ** 2)
    assert rho_short == pytest.approx(np.exp(-30.0 / tau), abs=0.02)


def test_amplitude_coherence_is_its_own():
    times = np.arange(0.0, 100_000.0, 10.0)
    g = antenna_gain_series(GainErrors(0.0, 0.05, coherence_s=1000.0, amp_coherence_s=50.0, seed=1), times, 6)
    a = np.abs(g) - 1.0
    rho = np.mean(a[5:] * a[:-5]) / np.mean(a ** 2)
    assert rho == pytest.approx(np.exp(-1.0), abs=0.04)


def test_no_gains_is_bit_for_bit_the_old_data(small_cov):
    plain = observe(np.ones(small_cov.n), small_cov, sigma=0.3, seed=3)
    none = observe(np.ones(small_cov.n), small_cov, sigma=0.3, seed=3, gains=None)
    assert np.array_equal(plain.V, none.V)
    # gains applied before the noise: the same noise draw on top of corrupted model
    corrupted = observe(np.ones(small_cov.n), small_cov, sigma=0.3, seed=3, gains=GainErrors(10.0, seed=1))
    model = GainErrors(10.0, seed=1).corrupt(np.ones(small_cov.n), plain.antenna1, plain.antenna2, plain.time)
    assert np.allclose(corrupted.V - model, plain.V - 1.0, atol=1e-12)
    assert corrupted.provenance["gain_errors"]["phase_rms_deg"] == 10.0


def test_simulate_observation_keeps_antennas_and_times(short_cov):
    vis = simulate_observation(coverage=short_cov, gains=GainErrors(5.0, seed=2), add_noise=False)
    clean = simulate_observation(coverage=short_cov, add_noise=False)
    assert np.array_equal(vis.antenna1, short_cov.antenna1) and np.array_equal(vis.antenna2, short_cov.antenna2)
    assert vis.time.min() == 0.0 and np.all(np.diff(vis.time[short_cov.configuration == 0]) >= 0)
    # configuration 1 is observed a sidereal day (86164.09 s) later: equal hour angles, different times
    later = short_cov.configuration == 1
    first, second = np.flatnonzero(~later)[0], np.flatnonzero(later)[0]
    hour_angle_step_s = (short_cov.hour_angle[second] - short_cov.hour_angle[first]) * 3600.0 / 1.002737909
    assert vis.time[second] - vis.time[first] - hour_angle_step_s == pytest.approx(86164.09, abs=0.01)
    assert not np.allclose(vis.V, clean.V)
    assert np.allclose(np.abs(vis.V), np.abs(clean.V))


@pytest.mark.parametrize("kwargs, word", [
    ({"phase_rms_deg": -1.0}, "phase_rms_deg"), ({"amp_rms": 0.5}, "amp_rms"),
    ({"coherence_s": 0.0}, "coherence_s"), ({"amp_coherence_s": -5.0}, "amp_coherence_s"),
])
def test_bad_gain_errors_name_the_option(kwargs, word):
    with pytest.raises(InputError, match=word):
        GainErrors(**kwargs)


def test_gains_need_a_coverage_with_antennas(small_cov):
    from dataclasses import replace

    bare = replace(small_cov, antenna1=None, antenna2=None)
    with pytest.raises(InputError, match="gains="):
        observe(np.ones(bare.n), bare, sigma=1.0, gains=GainErrors())
    with pytest.raises(InputError, match="gains="):
        simulate_observation(backend="casa", gains=GainErrors())
