"""Averaging in time per baseline and in uv cells: the smearing bound against direct sums, the weights,
what the averages keep, the errors, and a planted spiral's Δχ² against the unaveraged data."""

import warnings
from dataclasses import replace

import numpy as np
import pytest

import spiralbayes as sb
from spiralbayes.averaging import average_visibilities, group_smearing
from spiralbayes.exceptions import DataWarning, InputError
from spiralbayes.units import ARCSEC


@pytest.fixture(scope="module")
def fiducial():
    return sb.simulate_observation("fiducial", seed=3)


def _point_sources(u, v, offsets):
    """Visibilities of unit point sources at ``offsets`` [(l, m) arcsec] (the package's sign convention)."""
    return sum(np.exp(2j * np.pi * (u * l + v * m) * ARCSEC) for l, m in offsets)


@pytest.mark.parametrize("mode", ["time", "uv"])
@pytest.mark.parametrize("bound", [1e-3, 1e-2])
def test_the_averaged_model_is_within_the_bound_of_the_model_averaged(fiducial, mode, bound):
    # point sources on the bound's circle: the worst case the bound allows (all the L1 norm at theta)
    theta = 0.8
    angles = np.radians([0.0, 37.0, 90.0, 151.0, 233.0, 300.0])
    offsets = [(theta * np.cos(a), theta * np.sin(a)) for a in angles]
    flux = float(len(offsets))
    model = fiducial.with_V(_point_sources(fiducial.u, fiducial.v, offsets))
    avg = average_visibilities(model, mode, r_out=theta, max_smearing=bound)
    rep = avg.provenance["averaging"]
    assert rep["smearing"] <= bound and rep["n_out"] == avg.n < fiducial.n
    err = np.abs(avg.V - _point_sources(avg.u, avg.v, offsets)) / flux
    assert err.max() <= bound * (1 + 1e-9)
    # and the bound is not loose by orders of magnitude: the worst average uses a good part of it
    assert err.max() > 0.05 * bound


def test_inverse_variance_weights_and_weighted_means_by_hand():
    # two baselines; rows 0-2 at one place on baseline (0, 1), rows 3-4 on (0, 2) a little apart
    u = np.array([1e4, 1e4, 1e4, 2e4, 2e4 + 1.0])
    v = np.array([5e3, 5e3, 5e3, 0.0, 0.0])
    V = np.array([1 + 1j, 3 - 1j, 2 + 0j, 4j, -4j])
    w = np.array([1.0, 2.0, 1.0, 3.0, 1.0])
    vis = sb.Visibilities(u, v, V, w, antenna1=[0, 0, 0, 0, 0], antenna2=[1, 1, 1, 2, 2],
                          time=[0.0, 1.0, 2.0, 0.0, 4.0])
    avg = average_visibilities(vis, "time", r_out=1.0, max_smearing=1e-3)
    order = np.argsort(avg.antenna2)
    assert avg.n == 2
    np.testing.assert_allclose(avg.weights[order], [4.0, 4.0])
    np.testing.assert_allclose(avg.V[order], [(1 + 1j + 2 * (3 - 1j) + 2) / 4, (3 * 4j - 4j) / 4])
    np.testing.assert_allclose(avg.u[order], [1e4, 2e4 + 0.25])
    np.testing.assert_allclose(avg.time[order], [1.0, 1.0])
    assert list(avg.antenna1[order]) == [0, 0] and list(avg.antenna2[order]) == [1, 2]


def test_time_averages_keep_one_baseline_each_and_the_noise_level(fiducial):
    noise = fiducial.with_V(np.zeros(fiducial.n))   # the simulated noise alone: V - model
    rng = np.random.default_rng(7)
    sig = fiducial.sigma
    noise = noise.with_V(sig * (rng.standard_normal(fiducial.n) + 1j * rng.standard_normal(fiducial.n)))
    avg = average_visibilities(noise, "time", r_out=1.2, max_smearing=1e-2)
    assert avg.has_antennas and avg.time is not None and avg.n < noise.n / 2
    # every average's baseline and time come from its own rows
    pairs_in = set(zip(fiducial.antenna1.tolist(), fiducial.antenna2.tolist()))
    assert set(zip(avg.antenna1.tolist(), avg.antenna2.tolist())) <= pairs_in
    assert fiducial.time.min() <= avg.time.min() and avg.time.max() <= fiducial.time.max()
    # inverse-variance weights: chi2 of pure noise stays 2 per average (Re and Im)
    chi2 = np.sum(avg.weights * np.abs(avg.V) ** 2)
    assert chi2 / (2 * avg.n) == pytest.approx(1.0, abs=4 * np.sqrt(1 / avg.n))
    assert avg.weights.sum() == pytest.approx(noise.weights.sum(), rel=1e-12)


def test_uv_averages_fold_onto_one_half_plane_and_conjugate(fiducial):
    offsets = [(0.3, -0.2)]
    model = fiducial.with_V(_point_sources(fiducial.u, fiducial.v, offsets))
    avg = average_visibilities(model, "uv", r_out=0.5, max_smearing=1e-3)
    assert (avg.v >= 0).all() and not avg.has_antennas
    np.testing.assert_allclose(avg.V, _point_sources(avg.u, avg.v, offsets), atol=1e-3)


def test_group_smearing_is_half_of_two_pi_theta_squared_times_the_trace():
    u = np.array([0.0, 10.0, 0.0, 0.0])
    v = np.array([0.0, 0.0, 0.0, 6.0])
    w = np.ones(4)
    eps = group_smearing(u, v, w, np.array([0, 0, 1, 1]), theta=1.0)
    # each group: two points, separation d -> tr C = d^2 / 4
    theta = ARCSEC
    np.testing.assert_allclose(eps, 0.5 * (2 * np.pi * theta) ** 2 * np.array([25.0, 9.0]))


def test_time_averaging_needs_antennas_and_times(fiducial):
    bare = sb.Visibilities(fiducial.u, fiducial.v, fiducial.V, fiducial.weights)
    with pytest.raises(InputError, match="average = 'time' needs the antennas and time.*average = 'uv'"):
        average_visibilities(bare, "time", r_out=1.0)


@pytest.mark.parametrize("kwargs, match", [({"mode": "sideways"}, "average = 'sideways'"),
                                           ({"max_smearing": 0.5}, "max_smearing = 0.5"),
                                           ({"time_bin": -3.0}, "time_bin = -3"),
                                           ({"r_out": 0.0}, "r_out = 0.0")])
def test_bad_options_name_themselves(fiducial, kwargs, match):
    options = {"mode": "time", "r_out": 1.0, **kwargs}
    mode = options.pop("mode")
    with pytest.raises(InputError, match=match):
        average_visibilities(fiducial, mode, **options)


def test_a_time_bin_beyond_the_bound_warns_with_the_bound_and_the_fix(fiducial):
    with pytest.warns(DataWarning, match=r"time_bin = 3600 s would smear.*max_smearing = 1\.0e-03.*pass max_smearing"):
        avg = average_visibilities(fiducial, "time", r_out=1.2, max_smearing=1e-3, time_bin=3600.0)
    rep = avg.provenance["averaging"]
    assert rep["smearing"] <= 1e-3 < rep["requested_smearing"] and rep["n_split"] > 0
    # a bin within the bound is silent
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataWarning)
        average_visibilities(fiducial, "time", r_out=0.05, max_smearing=1e-2, time_bin=120.0)


def _planted_dchi2(vis, tpl, disc, geometry, r_p, averaged):
    from spiralbayes.inference.scan.run import scan
    from spiralbayes.simulate.discs import disc_visibilities

    data = vis if averaged is None else average_visibilities(vis, "time", r_out=averaged, geometry=geometry)
    profile = disc.profile(vis.wavelength)
    V_A = disc_visibilities(data.u, data.v, profile, geometry, disc.r_max, r_min=disc.r_min)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = scan(data, (profile, V_A), [tpl], geometry, r_p=r_p, n_phi_p=90, progress=False)
    return data, result.delta_chi2()[0]


def _check_planted(preset, tau0, seed):
    disc = sb.DiscModel(distance=140.0, r_ref=50.0, tau_ref=tau0)
    geometry = sb.DiscGeometry(30.0, 60.0)
    tpl = sb.make_template(mass=1.0, tau0=tau0, beta=0.0, wavelength=preset.wavelength)
    r_true = 50.0 / 140.0
    vis = sb.simulate_observation(preset, disc, geometry, tpl, r_p=r_true, phi_p=np.radians(40.0), seed=seed)
    r_p = r_true + 0.02 * np.arange(-2, 3)
    _, raw = _planted_dchi2(vis, tpl, disc, geometry, r_p, None)
    avg_vis, avg = _planted_dchi2(vis, tpl, disc, geometry, r_p, 1.1 * disc.r_max)
    return vis, avg_vis, raw, avg


@pytest.mark.parametrize("tau0", [0.3, 3.0])
def test_a_planted_spirals_delta_chi2_survives_default_averaging(tau0):
    vis, avg_vis, raw, avg = _check_planted(sb.PRESETS["fiducial"], tau0, seed=2)
    assert avg_vis.n < 0.75 * vis.n
    assert abs(avg.max() / raw.max() - 1) <= 0.01
    assert np.unravel_index(avg.argmax(), avg.shape) == np.unravel_index(raw.argmax(), raw.shape)


@pytest.mark.slow
def test_a_planted_spiral_in_a_million_visibilities_survives_default_averaging():
    # the high-sensitivity set-up in 26-s integrations: ~1e6 visibilities
    preset = replace(sb.PRESETS["high_sensitivity"], integration_time=26.0)
    vis, avg_vis, raw, avg = _check_planted(preset, 0.3, seed=4)
    assert vis.n > 9e5 and avg_vis.n < vis.n / 4
    assert abs(avg.max() / raw.max() - 1) <= 0.01
    assert np.abs(avg - raw).max() <= 0.01 * raw.max()


def test_the_configuration_averages_every_command_the_same(tmp_path, fiducial):
    from spiralbayes.config import load_config
    from spiralbayes.exceptions import ConfigError
    from spiralbayes.pipeline.inputs import load_data

    sb.save_visibilities(fiducial, tmp_path / "disc.h5")
    sb.save_visibilities(sb.Visibilities(fiducial.u, fiducial.v, fiducial.V, fiducial.weights), tmp_path / "bare.npz")
    text = '[data]\npath = "{}"\naverage = "{}"\nmax_smearing = 1e-2\n[frank]\nRmax = 1.0\n'
    (tmp_path / "a.toml").write_text(text.format("disc.h5", "time"))
    config = load_config(tmp_path / "a.toml")
    vis = load_data(config["data"], config=config)
    expected = average_visibilities(fiducial, "time", r_out=1.0, max_smearing=1e-2)
    assert vis.n == expected.n and vis.provenance["averaging"]["r_out"] == 1.0
    np.testing.assert_allclose(np.sort(vis.weights), np.sort(expected.weights))
    # with a gain solve, averages stay within one solution interval
    config["calibration"]["solve"] = "phase"
    assert load_data(config["data"], config=config).provenance["averaging"]["time_bin"] == 60.0
    (tmp_path / "b.toml").write_text(text.format("bare.npz", "time"))
    config = load_config(tmp_path / "b.toml")
    with pytest.raises(InputError, match=r"\[data\] average = 'time': .*needs the antennas"):
        load_data(config["data"], config=config)
    (tmp_path / "c.toml").write_text(text.format("bare.npz", "hourly"))
    with pytest.raises(ConfigError, match="average"):
        load_config(tmp_path / "c.toml")


@pytest.mark.slow
def test_the_posterior_medians_survive_default_averaging(tmp_path):
    # the fiducial observation in 20-s integrations (1.1e5 visibilities), a 1 M_th planet at tau0 3;
    # frank fitted to each data set as a user would, the same chain seed for both
    from spiralbayes.inference.posterior.priors import Priors

    preset = replace(sb.PRESETS["fiducial"], integration_time=20.0)
    disc = sb.DiscModel(distance=140.0, r_ref=50.0, tau_ref=3.0)
    geometry = sb.DiscGeometry(30.0, 60.0)
    tpl = sb.make_template(mass=1.0, tau0=3.0, beta=0.0, wavelength=preset.wavelength)
    vis = sb.simulate_observation(preset, disc, geometry, tpl, r_p=50 / 140, phi_p=np.radians(40.0), seed=5)
    avg = average_visibilities(vis, "time", r_out=sb.FrankSettings().Rmax, geometry=geometry)
    assert avg.n < vis.n / 2
    stats = []
    for k, data in enumerate((vis, avg)):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            model = sb.fit_axisymmetric(data, geometry, progress=False)
            post = sb.sample_posterior(data, model, [tpl], priors=Priors.default(model, r_p=(0.25, 0.45)),
                                       run_name=f"run{k}", chains_dir=tmp_path, n_steps=400, n_walkers=16,
                                       convergence="ignore", seed=1, progress=False)
        stats.append(post.best.percentiles())
    raw, averaged = stats
    for name in ("r_p", "phi_p", "A", "inc", "PA", "dRA", "dDec"):
        sigma = 0.5 * (raw[name]["hi"] - raw[name]["lo"])
        assert abs(averaged[name]["median"] - raw[name]["median"]) <= 0.1 * sigma, (name, raw[name], averaged[name])
