"""The gain solver recovers the antenna gains put into a simulated observation, within their noise.

The reference is the simulated truth (:class:`spiralbayes.simulate.GainErrors`, which draws the gains
independently of the solver). With 60-s intervals, one per 60-s integration of the fiducial coverage,
each interval has one true gain per antenna; the phase common to an interval's antennas cannot be
measured, so solved and true phases are compared after subtracting their mean over the interval's
solved antennas (and with ``keep_position=False``: a solve that keeps the disc's position leaves the
part of the true phases linear in the antennas' uv positions, tested separately). The tolerance is the
solver's own least-squares noise ``phase_sigma_deg``: the normalised errors ``z`` of 1180 solutions
must have rms 1 within 0.15 (its sampling scatter is ~0.02) and no |z| above 5 (chance ~1e-3 for 1180 Gaussian values).
"""

from __future__ import annotations

import numpy as np
import pytest

from spiralbayes.calibration import CalibrationSettings, GainSolution, solve_gains
from spiralbayes.exceptions import InputError
from spiralbayes.simulate import GainErrors, antenna_gain_series, get_preset, simulate_observation

ERRORS = GainErrors(10.0, 0.05, coherence_s=300.0, seed=1)


@pytest.fixture(scope="module")
def fiducial():
    """Coverage, noise-free true model, clean and corrupted data (same noise draw)."""
    cov = get_preset("fiducial").coverage()
    model = simulate_observation(coverage=cov, add_noise=False).V
    clean = simulate_observation(coverage=cov, seed=3)
    corrupted = simulate_observation(coverage=cov, seed=3, gains=ERRORS)
    return cov, model, clean, corrupted


def _true_gains(solution: GainSolution, vis) -> np.ndarray:
    times = np.unique(vis.time)
    g = antenna_gain_series(ERRORS, times, int(max(vis.antenna1.max(), vis.antenna2.max())) + 1)
    nearest = np.abs(times[None, :] - solution.time[:, None]).argmin(axis=1)
    return g[nearest][:, solution.antennas]


def _centred(phase: np.ndarray, solved: np.ndarray) -> np.ndarray:
    out = np.full_like(phase, np.nan)
    for i, row in enumerate(solved):
        out[i, row] = phase[i, row] - phase[i, row].mean()
    return out


def test_phases_match_the_truth_within_their_noise(fiducial):
    _, model, _, vis = fiducial
    sol = solve_gains(vis, model, mode="phase", interval_s=60.0, keep_position=False)
    assert sol.n_intervals == 40  # 10 (C-4) + 30 (C-7) integrations
    truth = _true_gains(sol, vis)
    solved = np.isfinite(sol.gains)
    assert solved.sum() > 1000
    d = _centred(np.angle(sol.gains), solved) - _centred(np.angle(truth), solved)
    z = np.degrees(np.angle(np.exp(1j * d[solved]))) / sol.phase_sigma_deg[solved]
    assert np.sqrt(np.mean(z ** 2)) == pytest.approx(1.0, abs=0.15)
    assert np.abs(z).max() < 5.0
    # the reference antenna has phase 0 wherever it is solved
    ref_col = np.searchsorted(sol.antennas, sol.reference)
    assert np.allclose(np.angle(sol.gains[np.arange(sol.n_intervals), ref_col]), 0.0)
    assert sol.phase_rms_deg == pytest.approx(10.0, rel=0.3)


def test_amplitudes_match_the_truth_within_their_noise(fiducial):
    _, model, _, vis = fiducial
    sol = solve_gains(vis, model, mode="amplitude+phase", interval_s=60.0, keep_position=False)
    truth = _true_gains(sol, vis)
    solved = np.isfinite(sol.gains)
    z = (np.abs(sol.gains) - np.abs(truth))[solved] / sol.amp_sigma[solved]
    assert np.sqrt(np.mean(z ** 2)) == pytest.approx(1.0, abs=0.15)
    assert np.abs(z).max() < 5.0


def test_applying_the_solution_restores_the_clean_chi2(fiducial):
    _, model, clean, vis = fiducial
    sol = solve_gains(vis, model, settings=CalibrationSettings(solve="amplitude+phase", interval_s=60.0,
                                                                      keep_position=False))
    corrected = sol.apply(vis)

    def chi2(v, rows=slice(None)):
        return float(np.sum((v.weights * np.abs(v.V - model) ** 2)[rows]))

    used = np.abs(model) * np.sqrt(vis.weights) >= sol.min_snr
    n_params = 2 * int(np.isfinite(sol.gains).sum()) - sol.n_intervals  # amplitudes + phases - references
    # least squares: on the rows it used, the corrected chi2 is the clean one minus what the gains absorb
    # of the noise, a chi2 of n_params degrees of freedom
    absorbed = chi2(clean, used) - chi2(corrected, used)
    assert absorbed == pytest.approx(n_params, abs=5 * np.sqrt(2 * n_params))
    # over all rows: the rows of never-solved antennas keep their (weak) errors; < 1 % of the damage stays
    damage = chi2(vis) - chi2(clean)
    assert damage > 3e5
    assert abs(chi2(corrected) - chi2(clean)) < 0.01 * damage


def test_keep_position_removes_only_a_phase_gradient(fiducial):
    """Phases linear in the antennas' uv positions shift the image: kept out, the rest is the full solve."""
    _, model, clean, vis = fiducial
    full = solve_gains(vis, model, mode="phase", interval_s=60.0, keep_position=False)
    kept = solve_gains(vis, model, mode="phase", interval_s=60.0)
    layout = vis.layout
    assert layout is not None
    for i in (0, 17, 39):
        rows = np.flatnonzero(np.isclose(vis.time, full.time[i]))
        ok = np.isfinite(full.gains[i])
        ants = full.antennas[ok]
        # antenna uv positions at this time from the simulation's baselines (u = U[antenna2] - U[antenna1])
        A = np.zeros((rows.size, ants.size))
        A[np.arange(rows.size), np.searchsorted(ants, vis.antenna2[rows]).clip(0, ants.size - 1)] += 1
        A[np.arange(rows.size), np.searchsorted(ants, vis.antenna1[rows]).clip(0, ants.size - 1)] -= 1
        inside = np.isin(vis.antenna1[rows], ants) & np.isin(vis.antenna2[rows], ants)
        uv = np.linalg.lstsq(A[inside], np.column_stack([vis.u[rows], vis.v[rows]])[inside], rcond=None)[0]
        diff = np.angle(full.gains[i, ok] * np.conj(kept.gains[i, ok]))
        basis = np.column_stack([np.ones(ants.size), 2 * np.pi * uv])
        fit = basis @ np.linalg.lstsq(basis, diff, rcond=None)[0]
        assert np.abs(diff - fit).max() < 1e-6  # a constant and a gradient, nothing else
        assert np.abs(diff - diff.mean()).max() > 1e-3  # and the gradient is not nothing
    # the gradient of 86 random antenna phases is a small part of them: the correction is nearly as good

    def chi2(v):
        return float(np.sum(v.weights * np.abs(v.V - model) ** 2))
    assert chi2(kept.apply(vis)) - chi2(full.apply(vis)) < 0.01 * (chi2(vis) - chi2(clean))


def test_phase_mode_leaves_amplitudes_untouched(fiducial):
    _, model, _, vis = fiducial
    sol = solve_gains(vis, model, mode="phase", interval_s=60.0)
    solved = np.isfinite(sol.gains)
    assert np.allclose(np.abs(sol.gains[solved]), 1.0) and np.all(np.isnan(sol.amp_sigma))
    corrected = sol.apply(vis)
    assert np.allclose(np.abs(corrected.V), np.abs(vis.V))
    assert np.allclose(corrected.weights, vis.weights)
    assert not np.allclose(corrected.V, vis.V)


def test_refant_is_the_phase_reference(fiducial):
    _, model, _, vis = fiducial
    sol = solve_gains(vis, model, mode="phase", interval_s=60.0, refant=5)
    col = int(np.searchsorted(sol.antennas, 5))
    solved = np.isfinite(sol.gains[:, col])
    assert solved.any() and np.allclose(sol.gains[solved, col], 1.0)
    assert np.all(sol.reference[solved] == 5)
    other = solve_gains(vis, model, mode="phase", interval_s=60.0)
    # only the reference differs: phase differences between antennas are the same
    both = np.isfinite(sol.gains) & np.isfinite(other.gains)
    ratio = (sol.gains * np.conj(other.gains))
    for i in range(sol.n_intervals):
        r = ratio[i, both[i]]
        assert np.allclose(r, r[0])


def test_summary_save_and_load(fiducial, tmp_path):
    _, model, _, vis = fiducial
    sol = solve_gains(vis, model, mode="phase")
    assert sol.interval_s == CalibrationSettings().interval_s
    assert sol.note().startswith("antenna gains solved (phase, 60 s intervals, ")
    assert "\n" not in sol.summary()
    back = GainSolution.load(sol.save(tmp_path / "gains.h5"))
    np.testing.assert_array_equal(back.gains, sol.gains)
    assert np.allclose(back.apply(vis).V, sol.apply(vis).V)


def test_bad_input(fiducial):
    from dataclasses import replace

    _, model, _, vis = fiducial
    with pytest.raises(InputError, match=r"\[calibration\] solve"):
        solve_gains(replace(vis, antenna1=None, antenna2=None, time=None, layout=None), model)
    with pytest.raises(InputError, match="mode"):
        solve_gains(vis, model, mode="amplitude")
    with pytest.raises(InputError, match="interval_s"):
        solve_gains(vis, model, interval_s=0.0)
    with pytest.raises(TypeError, match="unknown keyword"):
        solve_gains(vis, model, intervals=60.0)
    with pytest.raises(InputError, match="candidate_min_snr = -1.0 must be a signal-to-noise ratio >= 0"):
        CalibrationSettings(candidate_min_snr=-1.0)
    assert CalibrationSettings(candidate_min_snr=0).candidate_min_snr == 0  # 0: no second solve


def test_plot_gain_phases(fiducial):
    from spiralbayes.plotting import plot_gain_phases

    _, model, _, vis = fiducial
    fig = plot_gain_phases(solve_gains(vis, model, mode="amplitude+phase"), max_antennas=5)
    assert len(fig.axes) == 2 and len(fig.axes[0].lines) == 5
