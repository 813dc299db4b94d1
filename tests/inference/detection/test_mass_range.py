"""The verdict's planet mass as a range over morphology variants and H/r, and test 3's spiral label
(issue 22): on scans and alternative fits built by hand, so every expected number follows from the
inputs."""

import json

import numpy as np
import pytest

from spiralbayes.alternatives import DiscGrid
from spiralbayes.exceptions import InputError
from spiralbayes.inference.detection import apply_planet_peak, detect, mass_range
from spiralbayes.inference.detection.alternatives import AlternativeFit, AlternativesResult
from spiralbayes.inference.scan.run import ScanResult
from spiralbayes.units import thermal_mass
from tests._support.helpers import DISTANCE, GEOMETRY

N_DATA = 36_000
SIX_LN_N = 6 * np.log(N_DATA)
SHAPE = (13, 90)
I, J = 6, 10  # the best instance
R_GRID = np.linspace(0.02, 0.5, SHAPE[0])


def meta(variant, mass, h_p, hand):
    prefix = "wake" if variant == "compromise" else variant
    return {"name": f"{prefix}_m{mass:g}_tau3_b0_h{h_p:g}_{hand}", "mass": mass, "tau0": 3.0, "beta": 0.0,
            "hand": hand, "h_p": h_p, "variant": variant}


def peak_map(i, j, value):
    out = np.zeros(SHAPE)
    out[i, j] = value
    return out


# (variant, mass [M_th], h_p, hand, peak Δχ², where): the best is compromise 1 M_th at H/r 0.07
TEMPLATES = [
    ("compromise", 1.0, 0.07, "R", 500.0, (I, J)),
    ("hydro", 0.3, 0.05, "R", 495.0, (I + 1, J + 2)),      # 5 below, one step and 8 deg away: in
    ("wakeflow", 3.0, 0.10, "R", 488.0, (I - 2, J - 3)),   # 12 below, at the window's corner: out at band 10
    ("wakeflow", 0.1, 0.07, "R", 499.0, (I + 4, J)),       # close in Δχ² but four radii away: out
    ("hydro", 3.0, 0.05, "L", 499.5, (I, J)),              # the other hand: out
    ("compromise", 0.1, 0.05, "R", 495.0, (I, (J - 3) % SHAPE[1])),  # 3 azimuth steps back: in
    ("compromise", 1.0, 0.07, "L", 20.0, (I, J + 45)),     # the best one's mirror (test 2)
]


def scan_of(templates=TEMPLATES) -> ScanResult:
    metas = [meta(v, m, h, hand) for v, m, h, hand, _, _ in templates]
    cross = np.stack([peak_map(*where, value) for *_, value, where in templates]) / 2  # power 0: Δχ² = 2 cross
    return ScanResult(metas, R_GRID, 2 * np.pi * np.arange(SHAPE[1]) / SHAPE[1], cross, np.zeros_like(cross), 1e5,
                      N_DATA, GEOMETRY, DISTANCE)


def mjup(mass, h_p, mstar=0.8):
    # independent path: units.thermal_mass with H/r = h_p at the planet's own radius (no flaring)
    return mass * thermal_mass(50.0, mstar, h_ref=h_p, r_ref=50.0, flaring=0.0, unit="Mjup")


def test_mass_range_covers_the_templates_within_the_band_near_the_best():
    m = mass_range(scan_of())
    assert m["mth"] == [0.1, 1.0]
    members = {x["template"] for x in m["members"]}
    assert members == {"wake_m1_tau3_b0_h0.07_R", "hydro_m0.3_tau3_b0_h0.05_R", "wake_m0.1_tau3_b0_h0.05_R"}
    expected = [mjup(0.1, 0.05), mjup(0.3, 0.05), mjup(1.0, 0.07)]
    assert m["mjup"] == pytest.approx([min(expected), max(expected)], rel=1e-12)
    assert m["variants"] == ["compromise", "hydro"] and m["h_ps"] == [0.05, 0.07]
    assert [x["below_best"] for x in m["members"]] == pytest.approx([0.0, 5.0, 5.0])


def test_a_wider_band_takes_in_more_morphologies_and_a_heavier_star_scales_jupiter_masses():
    wide = mass_range(scan_of(), band=12.0, mstar=1.6)
    assert wide["mth"] == [0.1, 3.0] and wide["variants"] == ["compromise", "hydro", "wakeflow"]
    assert wide["mjup"] == pytest.approx([mjup(0.1, 0.05, 1.6), mjup(3.0, 0.10, 1.6)], rel=1e-12)
    narrow = mass_range(scan_of(), band=0.0)
    assert narrow["mth"] == [1.0, 1.0] and len(narrow["members"]) == 1
    with pytest.raises(InputError, match="mass band"):
        mass_range(scan_of(), band=-1.0)


def test_the_verdict_reports_the_range_in_its_sentence_and_json():
    v = detect(scan_of(), mstar=0.8)
    assert v.test1_passed and v.mass_range["mth"] == [0.1, 1.0]
    lo, hi = (f"{x:.2g}" for x in v.mass_range["mjup"])
    assert f"Planet mass 0.1-1 M_th ({lo}-{hi} M_Jup for M_* = 0.8 M_sun)" in v.summary()
    assert "3 templates" in v.summary() and "morphologies compromise, hydro" in v.summary()
    d = json.loads(json.dumps(v.to_dict(), allow_nan=False))
    assert d["mass_range"]["mth"] == [0.1, 1.0] and len(d["mass_range"]["members"]) == 3


def test_a_band_holding_one_template_names_it_alone():
    v = detect(scan_of(), mstar=0.8, mass_band=0.0)
    text = v.summary()
    assert v.mass_range["mth"] == [1.0, 1.0] and len(v.mass_range["members"]) == 1
    assert "Planet mass 1 M_th" in text and "the only template of that hand within Delta BIC 0" in text
    assert "morphology compromise; H/r 0.07, its own M_th)." in text
    assert "range of the 1 templates" not in text and "not a single template's label" not in text


def test_no_mass_is_quoted_without_a_significant_spiral():
    weak = [(v, m, h, hand, 0.5 * SIX_LN_N, where) for v, m, h, hand, _, where in TEMPLATES]
    v = detect(scan_of(weak))
    assert not v.test1_passed and v.mass_range is None
    assert "Planet mass" not in v.summary()


def alternatives(**dchi2) -> AlternativesResult:
    fits = {name: AlternativeFit(name, name.replace("_", " "), 5 if name in ("arc", "m2") else 4, value, [0.0] * 4, {})
            for name, value in dchi2.items()}
    return AlternativesResult(fits, N_DATA, 1e5, GEOMETRY, DiscGrid(1.0, 4, 8))


def test_the_planet_peak_rescues_a_planet_from_the_arc_and_the_verdict_says_so():
    """Issue 22's failure: the arc sits on the planet's compact peak and beats the bare spiral.
    Scored as spiral + peak (7 parameters) the planet wins; against an extended alternative the
    bare spiral's ΔBIC still counts."""
    result = scan_of()
    spiral_bic = 500.0 - SIX_LN_N
    alts = alternatives(arc=spiral_bic + 5 * np.log(N_DATA) + 29.0, lopsided=100.0)
    bare = detect(result, alternatives=alts)
    assert not bare.test3_passed and bare.best_alternative == "arc" and bare.test3_spiral_model == "spiral"
    peak = {"delta_chi2": 600.0, "delta_bic": 600.0 - 7 * np.log(N_DATA), "template": bare.template}
    rescored = apply_planet_peak(bare, alts, peak)
    arc_bic = alts.fits["arc"].delta_bic(N_DATA)
    assert rescored.test3_passed and rescored.detected
    assert rescored.test3_spiral_model == "spiral + compact peak at the planet"
    assert rescored.delta_bic_vs_alternative == pytest.approx(peak["delta_bic"] - arc_bic)
    assert "spiral + compact peak at the planet" in rescored.summary()
    # the same peak does not help against an extended impostor that beats the bare spiral
    lop = alternatives(arc=0.0, lopsided=600.0)
    against_lopsided = apply_planet_peak(detect(result, alternatives=lop), lop, peak)
    assert not against_lopsided.test3_passed and against_lopsided.best_alternative == "lopsided"
    assert against_lopsided.test3_spiral_model == "spiral"
    lopsided_bic = lop.fits["lopsided"].delta_bic(N_DATA)
    assert against_lopsided.delta_bic_vs_alternative == pytest.approx(spiral_bic - lopsided_bic)


def test_tests_1_and_2_take_the_best_variant_and_its_own_mirror():
    """On a bank with morphology variants (templates read through templates.variants), the verdict's
    template is the best over every variant, and test 2's mirror is the other hand of that variant:
    another variant's left hand, however well it fits, is not the mirror."""
    from spiralbayes.templates.template import template_metadata
    from spiralbayes.templates.variants import variant_template

    opts = {"n_x": 40, "n_phi": 64}
    metas = [template_metadata(variant_template(1.0, 3.0, 0.0, hand, v, h_p=0.07, **opts))
             for v in ("compromise", "hydro", "wakeflow") for hand in "RL"]
    assert [m["variant"] for m in metas] == ["compromise"] * 2 + ["hydro"] * 2 + ["wakeflow"] * 2
    # hydro R is the best (400); its own mirror reaches 80 near it; compromise L reaches 390 there
    values = {("compromise", "R"): 300.0, ("compromise", "L"): 390.0, ("hydro", "R"): 400.0, ("hydro", "L"): 80.0,
              ("wakeflow", "R"): 350.0, ("wakeflow", "L"): 10.0}
    maps = [peak_map(I, J if m["hand"] == "R" else J + 40, values[(m["variant"], m["hand"])]) for m in metas]
    cross = np.stack(maps) / 2
    result = ScanResult(metas, R_GRID, 2 * np.pi * np.arange(SHAPE[1]) / SHAPE[1], cross, np.zeros_like(cross), 1e5,
                        N_DATA, GEOMETRY, DISTANCE)
    v = detect(result)
    assert v.template == metas[2]["name"] and metas[2]["name"].startswith("hydro_m1_tau3_b0_h0.07_R")
    assert v.handedness_ratio == pytest.approx(80.0 / 400.0) and v.test2_passed and v.detected
    # the mass range lists the other variants' right hands within the band (350 is 50 below: out)
    assert [x["template"] for x in v.mass_range["members"]] == [metas[2]["name"]]
    assert mass_range(result, band=60.0)["variants"] == ["hydro", "wakeflow"]  # compromise R is 100 below


def test_a_simulated_map_in_the_range_is_named_a_simulation_not_the_compromise():
    result = scan_of()
    result.templates[1] = {"name": "fargo3d_run_gas_40_tau3_R", "mass": 0.3, "tau0": 3.0, "beta": None, "hand": "R",
                           "h_p": 0.05, "kind": "simulation"}
    m = mass_range(result)
    assert "fargo3d_run_gas_40_tau3_R" in {x["template"] for x in m["members"]}
    assert m["variants"] == ["compromise", "simulation"]
