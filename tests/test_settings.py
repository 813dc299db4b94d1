"""Settings dataclasses: the TOML schema is generated from their fields; old keyword arguments still work."""

import dataclasses

import pytest

from spiralbayes.axisymmetric import FrankSettings, fit_axisymmetric
from spiralbayes.calibration import CalibrationSettings
from spiralbayes.config import SCHEMA, SECTION_SETTINGS, default_config
from spiralbayes.exceptions import InputError
from spiralbayes.inference.detection import AlternativesSettings, DetectionSettings, detect, fit_alternatives
from spiralbayes.inference.limits import (
    CompletenessSettings,
    ForecastSettings,
    LimitSettings,
    completeness,
    compute_limits,
    forecast,
)
from spiralbayes.inference.posterior import PriorSettings, SamplingSettings, sample_posterior
from spiralbayes.settings import DEFAULT_MSTAR_MSUN, config_options, from_config, with_overrides

SECTIONS = [("sample", SamplingSettings), ("limits", LimitSettings), ("alternatives", AlternativesSettings),
            ("frank", FrankSettings), ("priors", PriorSettings), ("calibration", CalibrationSettings)]


def test_every_settings_section_is_pinned_here():
    assert {(section, cls) for section, cls in SECTION_SETTINGS.items()} <= set(SECTIONS)


@pytest.mark.parametrize("section, cls", SECTIONS)
def test_schema_defaults_are_the_dataclass_defaults(section, cls):
    config_fields = [f for f in dataclasses.fields(cls) if f.metadata["config"]]
    assert config_fields, cls
    for f in config_fields:
        default, doc = SCHEMA[section][f.name]
        assert doc == f.metadata["doc"] and doc
        toml = f.metadata.get("toml", f.default)
        assert default == (list(toml) if isinstance(toml, tuple) else toml), f"{section}.{f.name}"
    # the default file read back gives the default settings (TOML's 0 / [] become None)
    assert from_config(cls, default_config()[section]) == cls()


def test_from_config_maps_values_and_sentinels():
    s = from_config(LimitSettings, {"resolution": 0.1, "h_ref": 0.0, "inject_hand": ["R", "L"], "cl": 0.9})
    assert (s.resolution, s.h_ref, s.inject_hand, s.cl) == (0.1, None, ("R", "L"), 0.9)
    s = from_config(SamplingSettings, {"n_steps": 300, "processes": 0, "mcmc_templates": ["a"], "run_name": "x"})
    assert (s.n_steps, s.processes, s.mcmc_templates, s.run_name) == (300, None, ("a",), "x")
    assert from_config(SamplingSettings, {"processes": 1}).processes == 1  # "none", not "automatic"
    built = from_config(AlternativesSettings, {"models": [], "fit": True}, nthreads=3)
    assert built == AlternativesSettings(nthreads=3)


def test_overrides_replace_fields_and_unknown_keys_are_named():
    base = SamplingSettings(n_walkers=16)
    s = with_overrides(base, SamplingSettings, {"n_steps": 50, "seed": 3}, "sample_posterior")
    assert (s.n_walkers, s.n_steps, s.seed) == (16, 50, 3) and base.n_steps is None
    assert with_overrides(None, LimitSettings, {}, "compute_limits") == LimitSettings()
    with pytest.raises(TypeError, match="must be a SamplingSettings"):
        with_overrides(LimitSettings(), SamplingSettings, {}, "sample_posterior")
    # each public function refuses an unknown keyword before doing any work, naming it
    for call in (lambda: sample_posterior(None, None, [], n_walker=32),
                 lambda: compute_limits(None, confidence=0.9),
                 lambda: fit_alternatives(None, None, n_start=3)):
        with pytest.raises(TypeError, match=r"unknown keyword argument\(s\) \['(n_walker|confidence|n_start)'\]"):
            call()


def test_settings_check_their_values():
    with pytest.raises(ValueError, match="n_walkers = 4"):
        SamplingSettings(n_walkers=4)
    with pytest.raises(ValueError, match="convergence"):
        with_overrides(None, SamplingSettings, {"convergence": "maybe"}, "sample_posterior")
    with pytest.raises(ValueError, match="planet_prior"):
        SamplingSettings(planet_prior=1.0)


def test_config_options_keep_the_requested_order():
    assert list(config_options(SamplingSettings, ["seed", "run_name"])) == ["seed", "run_name"]
    assert "pool" not in config_options(SamplingSettings) and "pool" not in SCHEMA["sample"]


def test_detect_takes_settings_and_the_old_keywords():
    from tests._support.result_builders import scan_result

    result = scan_result()
    default = detect(result)
    assert default.test1_passed  # the builder plants one clear peak
    # a threshold above the peak's Delta BIC fails test 1, given as settings or as the old keyword
    strict = DetectionSettings(bic_threshold_value=default.delta_bic + 1.0)
    assert not detect(result, settings=strict).test1_passed
    assert not detect(result, bic_threshold_value=default.delta_bic + 1.0).test1_passed
    assert detect(result, settings=strict, bic_threshold_value=0.0).test1_passed  # the keyword wins
    with pytest.warns(FutureWarning, match="scan_result"):
        assert detect(result=result).delta_bic == default.delta_bic
    with pytest.raises(InputError, match="is not a scan result: pass the ScanResult returned by sb.scan"):
        detect(None)
    with pytest.raises(TypeError, match=r"unknown keyword argument\(s\) \['threshold'\]"):
        detect(result, threshold=3)


def test_stellar_mass_and_thresholds_have_one_default():
    import inspect

    from spiralbayes.inference.detection.verdict import mass_range
    from spiralbayes.inference.limits.table3 import THRESHOLDS
    from spiralbayes.inference.posterior import PosteriorResult

    mstar_defaults = {inspect.signature(f).parameters["mstar"].default
                      for f in (mass_range, PosteriorResult.mass_range)}
    assert {DetectionSettings().mstar, LimitSettings().mstar, *mstar_defaults} == {DEFAULT_MSTAR_MSUN}
    assert LimitSettings().thresholds == THRESHOLDS
    assert CompletenessSettings().detection.alternative_threshold == AlternativesSettings().threshold
    assert (LimitSettings().n_azimuths, LimitSettings().inject_hand) == (CompletenessSettings().n_azimuths,
                                                                         CompletenessSettings().hands)


def test_stage_functions_refuse_bad_settings_before_any_work():
    # None for the data: each call must stop at its settings, naming the option
    with pytest.raises(InputError, match="N = 1"):
        fit_axisymmetric(None, N=1)
    with pytest.raises(TypeError, match=r"unknown keyword argument\(s\) \['rmax'\]"):
        fit_axisymmetric(None, rmax=1.0)
    with pytest.raises(InputError, match="hands = "):
        completeness(None, None, [], None, hands=("X",))
    with pytest.raises(InputError, match="mstar = -1"):
        completeness(None, None, [], None, mstar=-1.0)  # a detection option, routed to settings.detection
    with pytest.raises(TypeError, match=r"unknown keyword argument\(s\) \['n_azimuth'\]"):
        completeness(None, None, [], None, n_azimuth=3)
    with pytest.warns(FutureWarning, match="scan_result"), pytest.raises(TypeError, match="n_walker"):
        sample_posterior(None, None, [], scan=object(), n_walker=32)
    with pytest.raises(InputError, match="n_phi = 0 must be an integer >= 1"):
        forecast(None, None, 0.1, n_phi=0)
    with pytest.raises(InputError, match="time_on_source = -5"):
        forecast(None, None, 0.1, settings=ForecastSettings(time_on_source=-5.0))


def test_completeness_routes_detection_overrides():
    from spiralbayes.inference.limits.recovery import _settings

    s = _settings(CompletenessSettings(n_azimuths=4), {"max_rp_steps": 1, "bic_threshold_value": 15.0}, "completeness")
    assert (s.n_azimuths, s.max_rp_steps, s.detection.bic_threshold_value) == (4, 1, 15.0)
    assert s.detection.mass_band == DetectionSettings().mass_band


def test_fit_axisymmetric_settings_equal_keywords():
    import numpy as np

    from spiralbayes.geometry import DiscGeometry
    from spiralbayes.visibilities import Visibilities

    rng = np.random.default_rng(3)
    u, v = rng.uniform(-2e5, 2e5, (2, 400))
    q = np.hypot(u, v)
    V = 0.1 * np.exp(-2 * (np.pi * q * 0.3 / 206265) ** 2) + rng.normal(0, 1e-3, 400)
    vis = Visibilities(u, v, V.astype(complex), np.full(400, 1e6))
    geometry = DiscGeometry(0.0, 0.0)
    a = fit_axisymmetric(vis, geometry, settings=FrankSettings(N=40, Rmax=1.0), progress=False)
    b = fit_axisymmetric(vis, geometry, N=40, Rmax=1.0, progress=False)
    assert a.hyperparameters["N"] == b.hyperparameters["N"] == 40
    np.testing.assert_array_equal(a.I, b.I)


def test_prior_settings_make_the_priors():
    from types import SimpleNamespace

    from spiralbayes.geometry import DiscGeometry

    from spiralbayes.inference.posterior import Priors

    disc = SimpleNamespace(geometry=DiscGeometry(30.0, 60.0), Rmax=1.2, R_eff=lambda: 0.5)
    priors = PriorSettings().priors(disc)
    assert priors.r_p == (0.02, 0.5) and priors.inc == (30.0, 5.0) and priors.amplitude_max == 2.0
    # the command line (the default [priors] section) and the notebook (Priors.default) agree
    assert from_config(PriorSettings, default_config()["priors"]).priors(disc) == priors == Priors.default(disc)
    priors = PriorSettings(r_p_max=0.4, PA_sigma=2.0, amplitude_max=0.0).priors(disc)
    assert priors.r_p == (0.02, 0.4) and priors.PA == (60.0, 2.0) and priors.amplitude_max is None
    with pytest.raises(InputError, match="r_p_min = 0.5 must be smaller than r_p_max = 0.3"):
        PriorSettings(r_p_min=0.5, r_p_max=0.3)


def test_settings_take_numpy_numbers_and_refuse_booleans():
    import numpy as np

    assert DetectionSettings(neighbourhood=np.int64(3), mstar=np.float32(1.0)).neighbourhood == 3
    assert FrankSettings(N=np.int64(50)).N == 50 and SamplingSettings(n_walkers=np.int64(12)).n_walkers == 12
    with pytest.raises(InputError, match="n_azimuths = True"):
        CompletenessSettings(n_azimuths=True)


@pytest.mark.parametrize("name", ["ScanSettings", "FrankSettings", "DetectionSettings", "AlternativesSettings",
                                  "CompletenessSettings", "ForecastSettings", "LimitSettings", "PriorSettings",
                                  "SamplingSettings"])
def test_help_lists_every_field_with_its_description_and_default(name):
    """``help(sb.XSettings)`` shows what ``--print-config`` shows: each field, its description, its default."""
    import dataclasses
    import pydoc

    import spiralbayes as sb

    cls = getattr(sb, name)
    text = " ".join(pydoc.render_doc(cls, renderer=pydoc.plaintext).replace(" |", " ").split())  # help() margins
    for f in dataclasses.fields(cls):
        default = "automatic" if f.default is None else repr(f.default)
        assert f"{f.name} {' '.join(f.metadata['doc'].split())} (default: {default})" in text, f.name
