"""Simulation-based calibration, small version (slow): 6 planets and 2 planet-free datasets of the
Taurus set-up (6,300 visibilities), short chains, tolerant thresholds. The full run is
``benchmarks/bench_sbc.py`` (>= 30 planets, >= 5 planet-free, fiducial set-up)."""

import numpy as np
import pytest

from spiralbayes.inference.validation.sbc import CalibrationSetup, ranks, run_dataset, summarise
from spiralbayes.inference.posterior.results import SAMPLE_NAMES


def test_ranks_of_a_truth_among_samples():
    rng = np.random.default_rng(0)
    samples = np.column_stack([rng.normal(0, 1, 4000) for _ in SAMPLE_NAMES])
    samples[:, 1] = rng.normal(0.0, 0.1, 4000) % (2 * np.pi)  # phi_p around the seam
    truth = dict.fromkeys(SAMPLE_NAMES, 0.0)
    truth["phi_p"] = 2 * np.pi - 0.1  # one sigma below the mean, on the other side of 0
    r = ranks(samples, truth)
    assert r["phi_p"] == pytest.approx(0.16, abs=0.03)
    assert r["r_p"] == pytest.approx(0.5, abs=0.03)


@pytest.mark.slow
def test_small_simulation_based_calibration(tmp_path):
    from spiralbayes.simulate import preset_coverage

    setup = CalibrationSetup(preset="taurus", r_p=(0.15, 0.45),
                             sampler={"n_walkers": 16, "n_steps": 300, "evidence_draws": 300})
    coverage = preset_coverage("taurus")
    template = setup.make_template()
    records = [run_dataset(setup, i, tmp_path, planet=True, coverage=coverage, template=template, seed=5)
               for i in range(6)]
    records += [run_dataset(setup, i, tmp_path, planet=False, coverage=coverage, template=template, seed=5)
                for i in range(2)]
    s = summarise(records)
    pooled95 = np.mean([r["inside95"][k] for r in records if r["planet"] for k in r["inside95"]])
    pooled68 = np.mean([r["inside68"][k] for r in records if r["planet"] for k in r["inside68"]])
    assert pooled95 >= 0.8, s  # 42 parameter-dataset pairs; nominal 0.95
    assert 0.4 <= pooled68 <= 0.95, s
    assert np.mean(s["null_p_planet"]) < 0.5, s
    strong = [p for a, p in s["planet_p_planet"] if a > 0.5]
    assert not strong or np.mean(strong) > 0.5, s


def test_ranks_include_the_mass_of_a_continuous_mass_run():
    from spiralbayes.inference.posterior.results import MASS_SAMPLE_NAMES

    rng = np.random.default_rng(1)
    samples = np.column_stack([rng.normal(0, 1, 4000) for _ in MASS_SAMPLE_NAMES])
    samples[:, 7] = np.exp(rng.normal(0.0, 0.5, 4000))  # M_p log-normal around 1 M_th
    truth = dict.fromkeys(SAMPLE_NAMES, 0.0) | {"M_p": float(np.exp(0.5))}  # one sigma above in ln M
    r = ranks(samples, truth)
    assert r["M_p"] == pytest.approx(0.84, abs=0.02)
    assert "M_p_MJup" not in r  # not drawn, so not ranked


def test_a_continuous_setup_draws_the_mass_log_uniformly():
    from spiralbayes.inference.validation.sbc import draw_truth

    setup = CalibrationSetup(mass="continuous", mass_range=(0.1, 3.0))
    rng = np.random.default_rng(2)
    ln_m = np.log([draw_truth(setup, rng)["M_p"] for _ in range(4000)])
    assert ln_m.min() >= np.log(0.1) and ln_m.max() <= np.log(3.0)
    assert np.histogram(ln_m, bins=4, range=(np.log(0.1), np.log(3.0)))[0] == pytest.approx([1000] * 4, rel=0.12)
    assert "M_p" not in draw_truth(CalibrationSetup(), rng)
