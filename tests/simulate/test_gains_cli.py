"""``spiralbayes simulate --phase-rms/--amp-rms/--gain-coherence``."""

from __future__ import annotations

import numpy as np
import pytest

from spiralbayes.cli import main
from spiralbayes.io import load_visibilities


def test_simulate_with_gain_errors_writes_antennas_and_corrupted_data(tmp_path, capsys):
    clean, noisy = tmp_path / "clean.h5", tmp_path / "gains.h5"
    assert main(["simulate", "--out", str(clean), "--seed", "3"]) == 0
    assert main(["simulate", "--out", str(noisy), "--seed", "3", "--phase-rms", "20", "--amp-rms", "0.05",
                 "--gain-coherence", "120"]) == 0
    a, b = load_visibilities(clean), load_visibilities(noisy)
    assert b.provenance["gain_errors"] == {"phase_rms_deg": 20.0, "amp_rms": 0.05, "coherence_s": 120.0,
                                           "amp_coherence_s": None, "seed": 3}
    assert "gain_errors" not in a.provenance
    np.testing.assert_array_equal(a.antenna1, b.antenna1)
    np.testing.assert_array_equal(a.time, b.time)
    # the bright short baselines carry the gain phases: far above the noise there
    bright = np.abs(a.V) * np.sqrt(a.weights) > 20
    dphase = np.degrees(np.angle(b.V[bright] / a.V[bright]))
    assert np.sqrt(np.mean(dphase ** 2)) == pytest.approx(np.sqrt(2) * 20.0, rel=0.25)


@pytest.mark.parametrize("argv, word", [
    (["--amp-rms", "0.5"], "--amp-rms"),
    (["--phase-rms", "-3"], "--phase-rms"),
    (["--gain-coherence", "0"], "--gain-coherence"),
    (["--gain-coherence", "60"], "--gain-coherence needs --phase-rms"),
])
def test_bad_gain_options_exit_2_naming_the_option(tmp_path, capsys, argv, word):
    argv = ["simulate", "--out", str(tmp_path / "x.h5"), *argv]
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert word in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x.h5").exists()


def test_simulate_help_lists_the_gain_options(capsys):
    with pytest.raises(SystemExit):
        main(["simulate", "-h"])
    text = " ".join(capsys.readouterr().out.split())
    assert "--phase-rms DEG" in text and "--amp-rms FRAC" in text and "(none: 300 s)" in text
