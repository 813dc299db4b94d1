"""Settings dataclasses: the TOML schema is generated from their fields; old keyword arguments still work."""

import dataclasses

import pytest

from spiralbayes.config import SCHEMA, default_config
from spiralbayes.inference.detection import AlternativesSettings, fit_alternatives
from spiralbayes.inference.limits import LimitSettings, compute_limits
from spiralbayes.inference.posterior import SamplingSettings, sample_posterior
from spiralbayes.settings import config_options, from_config, with_overrides

SECTIONS = [("sample", SamplingSettings), ("limits", LimitSettings), ("alternatives", AlternativesSettings)]


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
    s = from_config(SamplingSettings, {"n_steps": 300, "processes": 1, "mcmc_templates": ["a"], "run_name": "x"})
    assert (s.n_steps, s.processes, s.mcmc_templates, s.run_name) == (300, None, ("a",), "x")
    assert from_config(AlternativesSettings, {"models": [], "fit": True}, nthreads=3) == AlternativesSettings(nthreads=3)


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
