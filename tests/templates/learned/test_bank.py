"""The learned model's template bank: its predictions on a grid of disc physics, for the scan."""

from __future__ import annotations

import numpy as np
import pytest

from spiralbayes.exceptions import InputError
from spiralbayes.templates import TemplateBank
from spiralbayes.templates.learned import learned_bank, model_key
from spiralbayes.templates.template import metadata_variant, template_metadata

GRID = {"masses": (0.3, 1.0), "h_ps": (0.06,), "slopes": (1.0,), "alphas": (1e-3,), "orbits": (20.0, 100.0),
        "tau0s": (0.3, 3.0)}


def test_bank_holds_the_models_templates_and_round_trips(model, tmp_path, monkeypatch):
    bank = learned_bank(model, **GRID, cache_dir=tmp_path)
    assert len(bank) == 2 * 2 * 2 * 2 and len(set(bank.names)) == len(bank)
    for t in bank:
        point = t.provenance["learned"]["point"]
        expected = model.predict(**point, tau0=t.tau0, hand=t.hand)
        assert t.name == expected.name
        np.testing.assert_array_equal(t.delta, expected.delta)
        assert (t.mass, t.h_p, t.beta) == (point["mass"], point["h_p"], 0.0)
    # one disc (slope, α, age) is one mass family of the scan's variants
    variants = {metadata_variant(template_metadata(t)) for t in bank}
    assert variants == {"learned_p1_a0.001_o20", "learned_p1_a0.001_o100"}
    assert sorted(bank.select(hand="L").names) == sorted(n[:-1] + "L" for n in bank.select(hand="R").names)

    path = bank.save(tmp_path / "bank.h5")
    back = TemplateBank.load(path)
    assert back.names == bank.names
    np.testing.assert_array_equal(back.parameters, bank.parameters)
    for a, b in zip(bank, back):
        np.testing.assert_allclose(b.delta, a.delta, rtol=1e-6, atol=1e-7 * np.max(np.abs(a.delta)))  # float32
        assert b.provenance["learned"]["point"] == a.provenance["learned"]["point"]
    assert back.provenance["model_key"] == model_key(model)

    # the second call is the cached bank: nothing is predicted
    cached = list(tmp_path.glob("learned-*.h5"))
    assert len(cached) == 1

    def no_prediction(*args, **kwargs):
        raise AssertionError("the cached bank was predicted again")

    monkeypatch.setattr(model, "predict", no_prediction)
    again = learned_bank(model, **GRID, cache_dir=tmp_path)
    assert again.names == bank.names and again.provenance["learned_bank_key"] == bank.provenance["learned_bank_key"]


def test_bank_grid_is_checked_before_predicting(model, tmp_path):
    with pytest.raises(InputError, match=r"mass = 9 outside .*extrapolate=True"):
        learned_bank(model, **{**GRID, "masses": (1.0, 9.0)}, cache_dir=tmp_path)
    with pytest.raises(InputError, match="repeats a value"):
        learned_bank(model, **{**GRID, "masses": (1.0, 1.0)}, cache_dir=tmp_path)
    with pytest.raises(InputError, match="hands"):
        learned_bank(model, **GRID, hands=("R", "R"), cache_dir=tmp_path)
    left = learned_bank(model, **{**GRID, "masses": 9.0, "tau0s": 0.3, "orbits": 20.0}, hands="L", extrapolate=True,
                        cache_dir=tmp_path)
    assert left.names == ["learned_m9_tau0.3_b0_h0.06_p1_a0.001_o20_L"]
    assert not left[0].provenance["learned"]["inside_box"]


def test_the_scan_takes_a_learned_bank(model, planet_observation, tmp_path):
    """The fiducial planet (1 M_th, τ0 3, hand R at 50 au, φ 0) scanned with a learned bank of one disc:
    the best template is the 1 M_th, hand R one, within one radius step of the grid point nearest the
    planet and 8° of its azimuth."""
    from spiralbayes.inference.scan.run import scan
    from spiralbayes.units import wrap_angle

    from tests._support.helpers import DISTANCE, GEOMETRY, R_P_TRUE, SCAN_RP

    vis, axisym = planet_observation
    bank = learned_bank(model, masses=(0.3, 1.0, 3.0), h_ps=0.07, slopes=1.0, alphas=2e-3, orbits=20.0, tau0s=3.0,
                        cache_dir=tmp_path)
    result = scan(vis, axisym, bank, GEOMETRY, r_p=SCAN_RP, distance=DISTANCE, progress=False)
    best = result.best
    assert best.template == "learned_m1_tau3_b0_h0.07_p1_a0.002_o20_R"
    assert abs(best.i_rp - int(np.argmin(np.abs(SCAN_RP - R_P_TRUE)))) <= 1
    assert abs(np.degrees(wrap_angle(best.phi_p))) < 8


def test_configuration_bank_learned_predicts_the_sections_grid(model, tmp_path, monkeypatch):
    """``[templates] bank = "learned"``: the saved model's templates at the section's mass, h_p, slope,
    alpha, orbits, tau0 and hand (the same as learned_bank's at that grid); empty options take the built-in
    banks' masses, H/r and τ0 and the learned bank's slope, α and age defaults; β may only hold 0."""
    from spiralbayes.config import load_config
    from spiralbayes.pipeline import inputs
    from spiralbayes.templates.bank import DEFAULT_H_PS
    from spiralbayes.templates.learned import DEFAULT_ALPHAS, DEFAULT_ORBITS, DEFAULT_SLOPES
    from spiralbayes.templates.wake import PAPER_MASSES, PAPER_TAUS

    monkeypatch.setenv("SPIRALBAYES_CACHE", str(tmp_path / "cache"))
    model.save(tmp_path / "model.h5")
    path = tmp_path / "c.toml"
    path.write_text('[data]\npath = "d.txt"\n[geometry]\ninc = 30\nPA = 60\n[templates]\nbank = "learned"\n'
                    'learned_model = "model.h5"\nmass = [0.3, 1.0]\nh_p = [0.06]\nslope = [1.0]\nalpha = [1e-3]\n'
                    'orbits = [20.0, 100.0]\ntau0 = [0.3, 3.0]\nhand = ["r", "L"]\n')
    config = load_config(path)
    assert config["templates"]["learned_model"] == str(tmp_path / "model.h5")
    chosen = inputs.load_templates(config["templates"])
    expected = learned_bank(model, **GRID, cache_dir=tmp_path / "direct")
    assert [t.name for t in chosen] == expected.names
    for a, b in zip(chosen, expected):
        np.testing.assert_allclose(a.delta, b.delta, rtol=1e-6, atol=1e-7 * np.max(np.abs(b.delta)))

    seen = {}

    def capture(model, masses, h_ps, slopes, alphas, orbits, tau0s, hands, **kw):
        seen.update(masses=tuple(masses), h_ps=tuple(h_ps), slopes=tuple(slopes), alphas=tuple(alphas),
                    orbits=tuple(orbits), tau0s=tuple(tau0s), hands=tuple(hands))
        return expected

    monkeypatch.setattr("spiralbayes.templates.learned.learned_bank", capture)
    empty = {**config["templates"], **{k: [] for k in ("mass", "h_p", "slope", "alpha", "orbits", "tau0", "hand")}}
    inputs.load_templates(empty)
    assert seen == {"masses": PAPER_MASSES, "h_ps": DEFAULT_H_PS, "slopes": DEFAULT_SLOPES, "alphas": DEFAULT_ALPHAS,
                    "orbits": DEFAULT_ORBITS, "tau0s": PAPER_TAUS, "hands": ("R", "L")}
    with pytest.raises(InputError, match=r"beta = \[10.0\].*isothermal"):
        inputs.load_templates({**config["templates"], "beta": [10.0]})
    monkeypatch.undo()
    monkeypatch.setenv("SPIRALBAYES_CACHE", str(tmp_path / "cache"))
    with pytest.raises(InputError, match=r"\[templates\] bank = 'learned' .*mass = 9 outside"):
        inputs.load_templates({**config["templates"], "mass": [9.0]})
