"""The calibration diagnostic recovers the antenna phase errors put into a simulated observation."""

from __future__ import annotations

from dataclasses import replace

import pytest

from spiralbayes.calibration import CalibrationDiagnostic, diagnose_calibration
from spiralbayes.exceptions import InputError
from spiralbayes.simulate import GainErrors, get_preset, simulate_observation


@pytest.fixture(scope="module")
def fiducial():
    """The fiducial coverage (C-4 + C-7, 36120 visibilities) and its noise-free model."""
    cov = get_preset("fiducial").coverage()
    return cov, simulate_observation(coverage=cov, add_noise=False).V


@pytest.mark.parametrize("phase_rms", [3.0, 10.0, 30.0])
def test_recovers_the_antenna_phase_rms(fiducial, phase_rms):
    cov, model = fiducial
    vis = simulate_observation(coverage=cov, gains=GainErrors(phase_rms, 0.03, coherence_s=300.0, seed=1))
    diag = diagnose_calibration(vis, model)
    assert diag.phase_rms_deg == pytest.approx(phase_rms, rel=0.3)
    assert diag.amp_rms == pytest.approx(0.03, rel=0.3)
    assert diag.n_intervals == 40  # 10 (C-4) + 30 (C-7) integrations of 60 s
    # antennas with a baseline of model S/N >= 5 (the outer C-7 antennas see too little flux)
    assert 60 < len(diag.antenna_phase_rms_deg) <= 86 and max(diag.antenna_phase_rms_deg) < 86
    if phase_rms >= 10.0:
        assert f"~{diag.phase_rms_deg:.2g} deg rms" in diag.warning
        assert "self-calibrate" in diag.summary()
    assert diag.reduced_chi2 > 1.1


def test_no_gain_errors_gives_no_phase_and_no_warning(fiducial):
    cov, model = fiducial
    diag = diagnose_calibration(simulate_observation(coverage=cov), model)
    assert diag.phase_rms_deg < 2.0
    assert diag.amp_rms < 0.015  # the noise floor of 86 antennas x 20 integrations
    assert diag.warning is None
    assert diag.reduced_chi2 == pytest.approx(1.0, abs=0.03)
    assert "phase rms" in diag.summary() and "\n" not in diag.summary()


@pytest.mark.parametrize("seed", [5000, 5001, 8000])
def test_sparse_subset_without_gain_errors_gives_no_warning(fiducial, seed):
    """Every 4th row: some integrations' baselines form bipartite antenna graphs, whose amplitude
    equations are singular; they must be skipped, not solved into huge amplitudes (few rows per
    antenna leave a noise floor of several per cent in amplitude)."""
    import numpy as np

    cov, model = fiducial
    keep = np.arange(0, model.size, 4)
    vis = simulate_observation(coverage=cov, seed=seed).subset(keep)
    diag = diagnose_calibration(vis, model[keep])
    assert diag.phase_rms_deg < 2.0 and diag.amp_rms < 0.015
    assert diag.warning is None


def test_sparse_subset_recovers_the_amplitude_errors(fiducial):
    """Antennas on one or two baselines have amplitudes the data barely constrain; weighted down,
    they no longer hide the others' errors (the unweighted mean square read 0 % here)."""
    import numpy as np

    cov, model = fiducial
    keep = np.arange(0, model.size, 4)
    for amp in (0.05, 0.09):
        vis = simulate_observation(coverage=cov, seed=3, gains=GainErrors(3.0, amp, coherence_s=300.0, seed=3))
        diag = diagnose_calibration(vis.subset(keep), model[keep])
        assert diag.amp_rms == pytest.approx(amp, rel=0.2)
        assert diag.amp_significance > 10 and "amplitude errors" in diag.warning


def test_significance_is_unit_normal_without_gain_errors(fiducial):
    """Without gain errors the scatter estimates are noise: their significance ~ N(0, 1)."""
    import numpy as np

    cov, model = fiducial
    keep = np.arange(0, model.size, 4)
    z = np.array([[d.phase_significance, d.amp_significance]
                  for d in (diagnose_calibration(simulate_observation(coverage=cov, seed=seed).subset(keep),
                                                 model[keep]) for seed in range(30))])
    assert np.all(np.abs(z.mean(axis=0)) < 0.6)  # 30 draws: standard error 0.18
    assert np.all((z.std(axis=0) > 0.6) & (z.std(axis=0) < 1.5))


def test_amplitude_errors_alone_warn(fiducial):
    """5 % amplitude errors and no phase errors (the level at which an m = 2 pattern is named on
    the fiducial planet-free data) warn; 1 % does not."""
    cov, model = fiducial
    for amp, warns in ((0.05, True), (0.01, False)):
        diag = diagnose_calibration(simulate_observation(coverage=cov, seed=11,
                                                         gains=GainErrors(0.0, amp, coherence_s=180.0, seed=11)), model)
        assert diag.amp_rms == pytest.approx(amp, rel=0.3)
        assert (diag.warning is not None and "amplitude" in diag.warning) is warns


def test_model_object_and_solution_interval(fiducial):
    cov, model = fiducial
    vis = simulate_observation(coverage=cov, gains=GainErrors(10.0, coherence_s=3000.0, seed=4))

    class Model:
        def visibilities(self, u, v):
            assert u is not None and v is not None
            return model

    one = diagnose_calibration(vis, Model())
    # 5-minute intervals of 5 integrations: 2 over the 10-minute C-4 track, 6 over the 30-minute C-7 one
    longer = diagnose_calibration(vis, model, interval_s=300.0)
    assert longer.n_intervals == 8
    assert longer.phase_rms_deg == pytest.approx(one.phase_rms_deg, rel=0.3)


def test_without_antennas_reports_the_reduced_chi2(fiducial):
    cov, model = fiducial
    vis = simulate_observation(coverage=cov)
    bare = replace(vis, antenna1=None, antenna2=None, time=None, layout=None)
    diag = diagnose_calibration(bare, model)
    assert diag.phase_rms_deg is None and diag.warning is None
    assert diag.reduced_chi2 == pytest.approx(1.0, abs=0.03)
    # weights twice too large: chi2 doubles, in every annulus
    wrong = diagnose_calibration(bare.with_weights(2 * bare.weights, "x2"), model)
    assert wrong.reduced_chi2 == pytest.approx(2.0, rel=0.03)
    assert all(b > 1.7 for b in wrong.chi2_bins["reduced_chi2"])
    assert "reduced chi2 2" in wrong.warning and "no antennas" in wrong.summary()
    assert isinstance(wrong, CalibrationDiagnostic)


def test_bad_input_names_the_option(fiducial):
    cov, model = fiducial
    vis = simulate_observation(coverage=cov)
    with pytest.raises(InputError, match="model has 3"):
        diagnose_calibration(vis, model[:3])
    with pytest.raises(InputError, match="min_snr"):
        diagnose_calibration(vis, model, min_snr=0.0)
    with pytest.raises(InputError, match="interval_s"):
        diagnose_calibration(vis, model, interval_s=-1.0)
    with pytest.raises(InputError, match="min_snr"):
        diagnose_calibration(vis, model, min_snr=1e6)


def _frank_diagnostic(cov, phase_rms: float):
    from spiralbayes.axisymmetric.fit import fit_axisymmetric
    from spiralbayes.geometry import DiscGeometry

    gains = GainErrors(phase_rms, 0.03 if phase_rms else 0.0, coherence_s=300.0, seed=1)
    vis = simulate_observation(coverage=cov, gains=gains)
    return diagnose_calibration(vis, fit_axisymmetric(vis, DiscGeometry(30.0, 60.0)))


def test_recovers_the_phase_rms_from_the_residuals_of_a_frank_fit(fiducial):
    """The real use: the model is frank's fit to the corrupted data itself (~8 s)."""
    diag = _frank_diagnostic(fiducial[0], 10.0)
    assert diag.phase_rms_deg == pytest.approx(10.0, rel=0.3)
    assert "self-calibrate" in diag.warning


@pytest.mark.slow
@pytest.mark.parametrize("phase_rms", [0.0, 3.0, 30.0])
def test_frank_residuals_at_other_levels(fiducial, phase_rms):
    diag = _frank_diagnostic(fiducial[0], phase_rms)
    if phase_rms == 0.0:
        assert diag.phase_rms_deg < 2.0 and diag.warning is None
    else:
        assert diag.phase_rms_deg == pytest.approx(phase_rms, rel=0.3)
