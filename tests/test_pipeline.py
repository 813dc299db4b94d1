"""The demo, end to end (slow: about a minute on 2 cores; run with `pytest -m slow`)."""


import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
from spiralbayes.axisymmetric import DEFAULT_HYPERPARAMETERS, AxisymmetricModel
from spiralbayes.geometry import ARCSEC, DiscGeometry  # noqa: E402
from spiralbayes.pipeline import run_axisym
from spiralbayes.visibilities import Visibilities  # noqa: E402


@pytest.mark.slow
def test_demo_detects_the_planted_planet(tmp_path):
    from spiralbayes.pipeline import run_demo

    demo = run_demo(tmp_path / "demo", progress=False)
    assert demo.verdict.detected
    assert demo.verdict.template == "wake_m1_tau3_b10_h0.07_R"
    assert demo.verdict.r_p_au == pytest.approx(50.0, abs=7)
    assert all(path.exists() for path in demo.files)
    assert any(path.name.startswith("heatmap_") for path in demo.files)


def random_baselines(rng, n, q_min=1e4, q_max=2.5e6):
    """Log-uniform baseline lengths, uniform angles [lambda]."""
    q = 10 ** rng.uniform(np.log10(q_min), np.log10(q_max), n)
    theta = rng.uniform(0, 2 * np.pi, n)
    return q * np.cos(theta), q * np.sin(theta)


def gaussian_disc_visibilities(rng, n, sigma_arcsec, flux, geometry, noise):
    """Analytic visibilities of an inclined, offset Gaussian disc (optically thick)."""
    u, v = random_baselines(rng, n, q_max=1.5e6)
    up, vp = geometry.deproject_uv(u, v)
    s = sigma_arcsec * ARCSEC
    V = flux * geometry.cos_inc * np.exp(-2 * np.pi ** 2 * s ** 2 * (up ** 2 + vp ** 2))
    V = V * geometry.phase_factor(u, v)
    V = V + noise * (rng.normal(size=n) + 1j * rng.normal(size=n))
    return Visibilities(u, v, V, np.full(n, noise ** -2))


def test_run_axisym_writes_model_and_plots(tmp_path):
    g = DiscGeometry(inc=30.0, PA=20.0)
    vis = gaussian_disc_visibilities(np.random.default_rng(7), 2000, 0.2, 0.05, g, 2e-3)
    model = run_axisym(vis, tmp_path / "out", geometry=g, N=60, progress=False, distance=140.0)
    names = sorted(p.name for p in (tmp_path / "out").iterdir())
    assert names == ["axisym_model.h5", "axisym_profile.png", "axisym_visibilities.png"]
    loaded = AxisymmetricModel.load(tmp_path / "out" / "axisym_model.h5")
    np.testing.assert_array_equal(loaded.I, model.I)
    assert loaded.hyperparameters["N"] == 60
    assert DEFAULT_HYPERPARAMETERS["weights_smooth"] == loaded.hyperparameters["weights_smooth"]
