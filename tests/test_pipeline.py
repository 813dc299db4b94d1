"""The demo, end to end (slow: about a minute on 2 cores; run with `pytest -m slow`)."""


import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
from spiralbayes.axisymmetric import DEFAULT_HYPERPARAMETERS, AxisymmetricModel
from spiralbayes.geometry import ARCSEC, DiscGeometry
from spiralbayes.pipeline import run_axisym
from spiralbayes.visibilities import Visibilities


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


@pytest.mark.slow
def test_scan_config_refits_the_geometry_and_finds_the_planet(tmp_path):
    """A 10 mas phase-centre error hides a planet behind a false peak; the scan run fits the
    alternatives, the geometry error wins test 3, and the run refits frank there, rescans and
    detects the planet (outputs in refit_geometry/)."""
    from spiralbayes.io import save_visibilities
    from spiralbayes.pipeline import run_scan
    from spiralbayes.config import merge_config
    from spiralbayes.simulate import DiscModel, simulate_observation
    from spiralbayes.templates import TemplateBank, make_template

    right = make_template(1.0, 3.0, 10.0, "R")
    TemplateBank([right, right.mirror()]).save(tmp_path / "bank.h5")
    vis = simulate_observation("fiducial", DiscModel(distance=140.0, tau_ref=3.0), DiscGeometry(30.0, 60.0, dRA=-0.01),
                               right, r_p=50 / 140, phi_p=0.0, seed=1)
    save_visibilities(vis, tmp_path / "obs.npz")
    config = merge_config({"data": {"path": str(tmp_path / "obs.npz")}, "geometry": {"inc": 30.0, "PA": 60.0,
                                                                                      "distance": 140.0},
                           "templates": {"bank": str(tmp_path / "bank.h5")}, "scan": {"checkpoint": False},
                           "output": {"dir": str(tmp_path / "out"), "plots": True}})
    run = run_scan(config, progress=False)
    assert not run.verdict.detected and run.verdict.best_alternative == "geometry"
    assert run.follow_up is not None and run.follow_up.verdict.detected
    assert run.follow_up.verdict.r_p_au == pytest.approx(50.0, abs=7)
    sub = tmp_path / "out" / "refit_geometry"
    assert (sub / "verdict.json").exists() and (sub / "axisymmetric.h5").exists()
    assert (tmp_path / "out" / "residual_comparison.png").exists()
