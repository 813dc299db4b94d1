"""The demo, end to end (slow: about a minute on 2 cores; run with `pytest -m slow`)."""

import pytest


@pytest.mark.slow
def test_demo_detects_the_planted_planet(tmp_path):
    from spiralbayes.pipeline import run_demo

    demo = run_demo(tmp_path / "demo", progress=False)
    assert demo.verdict.detected
    assert demo.verdict.template == "wake_m1_tau3_b10_R"
    assert demo.verdict.r_p_au == pytest.approx(50.0, abs=7)
    assert all(path.exists() for path in demo.files)
    assert any(path.name.startswith("heatmap_") for path in demo.files)
