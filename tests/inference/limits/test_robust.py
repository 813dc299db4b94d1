"""Issue 22: limits over several families (M_Jup per family's own h_p, no family= needed),
radii next to a detected planet, and exclusion robust to the template morphology."""

import numpy as np
import pytest

from spiralbayes.inference.limits import compute_limits, z_score
from spiralbayes.inference.limits.robust import combined_m_lim, near_planet_mask, price_of_robustness, variant_groups
from spiralbayes.inference.scan import ScanResult
from spiralbayes.units import mth_to_mjup
from tests._support import limits_setup

MASSES = (0.3, 1.0, 3.0)


def multi_family_scan(h_ps=(0.05, 0.07, 0.10), variants=(None,), a_up=(2.0, 0.5, 0.1), r_p=(0.1, 0.2, 0.3),
                      n_phi=4, distance=140.0):
    """Noise-free planet-free scan: A_up = a_up[mass] for every family (A_hat = 0, power = (z/A_up)²);
    ``a_up`` may be a dict ``variant -> a_up`` to give the variants different sensitivities."""
    z = z_score(0.95)
    meta, power = [], []
    for h in h_ps:
        for v in variants:
            ups = a_up[v] if isinstance(a_up, dict) else a_up
            for m, u in zip(MASSES, ups):
                for hand in ("R", "L"):
                    d = {"name": f"t_m{m}_h{h}_{v}_{hand}", "mass": m, "tau0": 0.3, "beta": 10.0, "hand": hand,
                         "h_p": h}
                    if v is not None:
                        d["variant"] = v
                    meta.append(d)
                    power.append(np.full((len(r_p), n_phi), (z / u) ** 2))
    power = np.array(power)
    return ScanResult(meta, np.asarray(r_p, float), 2 * np.pi * np.arange(n_phi) / n_phi, np.zeros_like(power),
                      power, 0.0, 10000, limits_setup.GEOMETRY, distance)


def test_jupiter_masses_use_each_familys_own_aspect_ratio():
    limits = compute_limits(multi_family_scan())
    assert len(limits.families) == 3
    m_th = limits.m_lim[0]  # same A_up in every family: same M_lim in M_th
    for fam in limits.families:
        h = fam.key["h_p"]
        expected = mth_to_mjup(m_th, limits.r_p, 0.8, h_ref=h, r_ref=50.0, flaring=0.25, distance=140.0)
        np.testing.assert_allclose(limits.m_lim_mjup(fam), expected, rtol=1e-9)
    # M_th ∝ h³: the h_p = 0.10 family's planets are (0.10/0.05)³ = 8 times heavier than h_p = 0.05's
    ratio = limits.m_lim_mjup({"h_p": 0.10}) / limits.m_lim_mjup({"h_p": 0.05})
    np.testing.assert_allclose(ratio, 8.0, rtol=1e-9)
    # an explicit h_ref still overrides the families' own
    given = compute_limits(multi_family_scan(), h_ref=0.07)
    np.testing.assert_allclose(given.m_lim_mjup({"h_p": 0.10}), given.m_lim_mjup({"h_p": 0.05}), rtol=1e-12)


def test_table_rows_use_their_familys_aspect_ratio():
    from spiralbayes.inference.limits.table3 import limits_table

    rows = [r for r in limits_table(compute_limits(multi_family_scan())) if r["mass_mth"] == 1.0]
    by_h = {r["family"].split("h_p=")[1]: r["m_min_mjup"] for r in rows}
    assert by_h["0.1"] / by_h["0.05"] == pytest.approx(8.0, rel=1e-9)


def test_summary_excluded_and_plot_work_without_family_on_the_default_bank_layout(tmp_path):
    a_up = {"compromise": (2.0, 0.5, 0.1), "hydro": (2.0, 2.0, 0.5)}  # hydro excludes only 3 M_th
    limits = compute_limits(multi_family_scan(variants=("compromise", "hydro"), a_up=a_up))
    assert len(limits.families) == 6
    text = limits.summary()
    assert "Over all 6 template families" in text and "variant=hydro" in text
    assert "aspect ratios" not in text  # the test scan's families are at tau0 <= 1
    # robust: 1 M_th is excluded by the compromise variant but not by hydro, so not at all
    assert not limits.excluded(mass=1.0).any() and limits.excluded(mass=3.0).all()
    assert limits.excluded().shape == (3, 3)
    m_lim, status = combined_m_lim(limits)
    single = limits.m_lim[limits.family_index({"h_p": 0.07, "variant": "compromise"})]
    hydro = limits.m_lim[limits.family_index({"h_p": 0.07, "variant": "hydro"})]
    np.testing.assert_allclose(m_lim, np.maximum(single, hydro))
    assert set(status) == {"limit"}
    group = [g for g in variant_groups(limits.families) if g["key"]["h_p"] == 0.07][0]
    np.testing.assert_allclose(price_of_robustness(limits, group), hydro / single)
    assert "price of robustness" in text and f"{np.min(hydro / single):.2g}" in text
    assert limits.excluded_ranges(mass=3.0) == [(0.1, 0.3)] and limits.excluded_ranges(mass=1.0) == []
    from spiralbayes.plotting.limits import plot_mass_radius

    plot_mass_radius(limits).savefig(tmp_path / "mr.png")
    assert (tmp_path / "mr.png").stat().st_size > 0


def test_limits_name_their_morphologies_and_the_price_of_robustness(tmp_path):
    """Robust limits (several variants) name the set and the price M_lim(robust)/M_lim(compromise) in
    the summary, the machine-readable attributes and the mass-radius plot; a single morphology is
    named as such and said not to be robust."""
    from spiralbayes.plotting.limits import plot_mass_radius

    a_up = {"compromise": (2.0, 0.5, 0.1), "hydro": (2.0, 2.0, 0.5)}  # compromise: M_lim < 1; hydro: 1-3
    limits = compute_limits(multi_family_scan(variants=("compromise", "hydro"), a_up=a_up))
    assert limits.morphologies == ["compromise", "hydro"]
    single = limits.m_lim[limits.family_index({"h_p": 0.07, "variant": "compromise"})]
    hydro = limits.m_lim[limits.family_index({"h_p": 0.07, "variant": "hydro"})]
    assert np.all(hydro > 1.0) and np.all(single < 1.0)
    np.testing.assert_allclose(limits.price_of_robustness(), hydro / single)
    np.testing.assert_allclose(limits.price_of_robustness({"h_p": 0.05, "variant": "hydro"}), hydro / single)
    assert limits.price_of_robustness_median() == pytest.approx(np.median(hydro / single))
    note = limits.morphology_note()
    assert "every morphology (compromise, hydro)" in note and f"median {np.median(hydro / single):.2g}" in note
    assert note in limits.summary()
    assert limits.summary({"h_p": 0.07, "variant": "hydro"}).endswith(
        "This family assumes the hydro morphology only; the limits robust to the spiral's shape are those over "
        "every morphology (compromise, hydro).")
    fig = plot_mass_radius(limits)
    assert note in fig.get_suptitle()
    assert any("compromise, hydro" in t.get_text() for t in fig.axes[0].get_legend().get_texts())
    # the same limits from the compromise alone: one morphology, a price of 1, and the warning
    alone = compute_limits(multi_family_scan(variants=("compromise",), a_up=a_up))
    assert alone.morphologies == ["compromise"]
    np.testing.assert_allclose(alone.price_of_robustness(), 1.0)
    assert "assume the compromise morphology only; not robust to the spiral's shape" in alone.summary()
    assert "compromise morphology only" in plot_mass_radius(alone).get_suptitle()
    # saved and loaded, the limits still know their morphologies
    again = type(limits).load(limits.save(tmp_path / "limits.h5"))
    assert again.morphologies == limits.morphologies and again.morphology_note() == note


def test_a_learned_banks_discs_are_robust_over_each_other_with_the_price_not_measured():
    """A learned bank's discs are morphologies of their own: a mass is excluded only where every disc excludes
    it (the largest of their limits), and with no compromise family the price of robustness is not measured
    (NaN, and the note and Table 3 say so) rather than 1."""
    from spiralbayes.inference.limits.table3 import price_text

    discs = ("learned_p0.5_a0.001_o200", "learned_p1.5_a0.001_o200")
    a_up = {discs[0]: (2.0, 0.5, 0.1), discs[1]: (2.0, 2.0, 0.5)}
    limits = compute_limits(multi_family_scan(variants=discs, a_up=a_up))
    assert limits.morphologies == list(discs)
    weak = limits.m_lim[limits.family_index({"h_p": 0.07, "variant": discs[1]})]
    robust, _ = combined_m_lim(limits)
    np.testing.assert_allclose(robust, weak)
    assert np.all(np.isnan(limits.price_of_robustness()))
    note = limits.morphology_note()
    assert "every morphology (learned_p0.5_a0.001_o200, learned_p1.5_a0.001_o200)" in note
    assert "no compromise family was scanned, so the price of robustness is not measured" in note
    assert price_text(limits) == "not measured"


def test_a_templates_limit_margin_divides_its_upper_limit():
    """A template with ``limit_margin`` m (a learned bank's) stands for m times itself: its A_up is the
    scan's divided by m, so it excludes where the template scaled by m is excluded, and the limiting mass
    moves up accordingly; templates without a margin are unchanged."""
    from spiralbayes.templates.template import LEARNED_LIMIT_MARGIN

    scan = multi_family_scan(h_ps=(0.07,))
    plain = compute_limits(scan)
    for meta in scan.templates:
        meta["limit_margin"] = 0.4
    scaled = compute_limits(scan)
    np.testing.assert_allclose(scaled.upper_limit, plain.upper_limit / 0.4)
    # A_up = a_up[mass] (0.3, 1, 3 M_th: 2, 0.5, 0.1): 1 and 3 M_th excluded, M_lim between 0.3 and 1; with the
    # margin A_up = 5, 1.25, 0.25: only 3 M_th is, M_lim between 1 and 3
    assert np.all((plain.m_lim[0] > 0.3) & (plain.m_lim[0] < 1.0))
    assert np.all((scaled.m_lim[0] > 1.0) & (scaled.m_lim[0] < 3.0))
    # templates R, L of 0.3, 1 and 3 M_th: the 1 M_th pair is excluded everywhere without the margin, nowhere with it
    assert np.all(plain.excluded_fraction[2:] == 1.0)
    assert np.all(scaled.excluded_fraction[2:4] == 0.0) and np.all(scaled.excluded_fraction[4:] == 1.0)
    assert 0 < LEARNED_LIMIT_MARGIN < 1


def test_generator_templates_without_a_variant_are_the_compromise_morphology():
    """The compromise bank's templates carry no variant: named by the generator's ``wake_`` prefix."""
    scan = multi_family_scan(h_ps=(0.07,))
    assert compute_limits(scan).morphologies == ["unlabelled"]
    for meta in scan.templates:
        meta["name"] = "wake_" + meta["name"]
    limits = compute_limits(scan)
    assert limits.morphologies == ["compromise"]
    assert limits.summary().endswith("These limits assume the compromise morphology only; not robust to the "
                                     "spiral's shape.")


def test_single_family_summary_is_unchanged():
    limits = compute_limits(multi_family_scan(h_ps=(0.07,)))
    assert limits.summary().startswith("Planets of >= 3 M_th (template family tau0=0.3, beta=10, h_p=0.07)")


def test_near_planet_mask_is_one_beam():
    mask = near_planet_mask([0.1, 0.2, 0.3, 0.4, 0.5], [0.3], 0.1)
    assert mask.tolist() == [False, True, True, True, False]
    assert not near_planet_mask([0.1, 0.2], [], 0.1).any()


@pytest.fixture(scope="module")
def planted_planet_limits():
    """A 1 M_th planet (the family's own template) at 50 au = 0.357 arcsec, noise small; scanned at
    radii around it with the planet *not* in the model."""
    from spiralbayes.inference.scan import scan

    r_p = np.array([0.15, 0.25, 0.3, 0.357, 0.4, 0.45])
    templates = list(limits_setup.family(tau0=0.3, beta=10.0))
    planet = templates[2]  # 1 M_th, R
    from spiralbayes.inference.scan.engine import ScanContext
    from spiralbayes.model import perturbation_visibilities

    vis = limits_setup.observation(40e-6, seed=3)
    ctx = ScanContext.build(vis, limits_setup.disc_model(), limits_setup.GEOMETRY, [0.357], limits_setup.N_PHI)
    dv = perturbation_visibilities(vis.u, vis.v, limits_setup.GEOMETRY, ctx.profile, planet, 0.357,
                                   2 * np.pi * 3 / limits_setup.N_PHI, quad=ctx.quadrature(planet, 0.357))
    vis = _add(vis, dv)
    result = scan(vis, limits_setup.disc_model(), templates, limits_setup.GEOMETRY, r_p=r_p, n_phi_p=limits_setup.N_PHI,
                  distance=limits_setup.DISTANCE, progress=False)
    return vis, result


def _add(vis, dv):
    import dataclasses

    return dataclasses.replace(vis, V=vis.V + dv)


def test_radii_within_a_beam_of_a_detected_planet_are_not_excluded(planted_planet_limits):
    from spiralbayes.inference.detection import detect
    from spiralbayes.inference.limits import data_resolution

    vis, result = planted_planet_limits
    verdict = detect(result)
    assert verdict.test1_passed and abs(verdict.r_p - 0.357) < 0.06
    beam = 0.08  # [arcsec]: a narrower guard than this C-4 set-up's beam, so that far radii remain
    assert data_resolution(vis) > beam
    plain = compute_limits(result, resolution=0.0)
    guarded = compute_limits(result, resolution=0.0, planets=verdict, planet_beam=beam)
    near = np.abs(result.r_p - verdict.r_p) <= beam
    assert near.sum() >= 3
    # without the guard the planet's neighbourhood reads as "3 M_th ruled out" somewhere near it
    assert plain.excluded(mass=3.0)[near].any()
    assert not guarded.excluded().any(axis=0)[near].any()
    assert set(guarded.flags[near]) == {"near_planet"} and np.all(np.isnan(guarded.m_lim[:, near]))
    # far from the planet nothing changes
    np.testing.assert_array_equal(guarded.excluded()[:, ~near], plain.excluded()[:, ~near])
    assert "near_planet" in guarded.flags.tolist()


def test_spiralbayes_limits_writes_the_robust_summary_and_plot_on_several_families(tmp_path):
    """`spiralbayes limits` (pipeline.limits.run_limits) on the default bank's layout: no family= needed;
    the summary's first line is the limit over every family, then one line per family."""
    from spiralbayes.pipeline.limits import run_limits

    a_up = {"compromise": (2.0, 0.5, 0.1), "hydro": (2.0, 2.0, 0.5)}
    scan = multi_family_scan(variants=("compromise", "hydro"), a_up=a_up)
    run = run_limits(None, None, None, scan, tmp_path, limits_config={"completeness": False, "resolution": 0.05},
                     distance=140.0, plots=True)
    lines = (tmp_path / "limits_summary.txt").read_text().splitlines()
    assert lines[0] == run.limits.summary() and "Over all 6 template families" in lines[0]
    assert lines[1:] == [run.limits.summary(f) for f in run.limits.families]
    assert (tmp_path / "mass_radius_all_families.png").stat().st_size > 0
    single = run_limits(None, None, None, multi_family_scan(h_ps=(0.07,)), tmp_path / "one",
                        limits_config={"completeness": False, "resolution": 0.05}, distance=140.0, plots=False)
    assert (tmp_path / "one" / "limits_summary.txt").read_text().splitlines() == [single.limits.summary()]


def test_a_familys_own_summary_quotes_jupiter_masses_with_its_own_h_p():
    """limits.summary(family) on a scan of several H/r: the excluded ranges' M_Jup use that family's h_p
    (it raised "several h_p" before)."""
    limits = compute_limits(multi_family_scan())
    for fam in limits.families:
        lo, hi = limits.excluded_ranges(fam, 3.0)[0]
        m = [f"{x:.2g}" for x in mth_to_mjup(3.0, np.array([lo, hi]), 0.8, h_ref=fam.key["h_p"], r_ref=50.0,
                                              flaring=0.25, distance=140.0)]
        assert f"({m[0]}-{m[1]} M_Jup)" in limits.summary(fam)


def _verdict_with_alternative(delta_bic: float, r_c: float = 0.45, sigma_r: float = 0.02) -> dict:
    """A planet-free verdict (test 1 failed) whose lopsided-ring alternative has this ΔBIC."""
    return {"test1_passed": False, "r_p": 0.25, "candidate": None,
            "alternatives": {"lopsided": {"label": "lopsided ring", "delta_chi2": delta_bic + 46.0,
                                          "delta_bic": delta_bic, "n_params": 4,
                                          "params": {"r_c": r_c, "sigma_r": sigma_r, "amplitude": 0.1}},
                             "geometry": {"label": "geometry error", "delta_bic": 50.0, "params": {"d_inc_deg": 1.0}}}}


def test_radii_near_a_significant_asymmetry_are_flagged_not_excluded(planted_planet_limits, tmp_path):
    """An alternative with ΔBIC > 10 (here a lopsided ring at 0.45″, σ_r 0.02″) flags the radii within
    one beam of r_c ± 2σ_r; one below the threshold, or without an annulus (geometry), flags nothing."""
    from spiralbayes.inference.limits import asymmetry_bands

    _, result = planted_planet_limits
    beam = 0.05
    plain = compute_limits(result, resolution=0.0)
    guarded = compute_limits(result, resolution=0.0, planets=_verdict_with_alternative(25.0), planet_beam=beam)
    band = (result.r_p >= 0.41 - beam - 1e-12) & (result.r_p <= 0.49 + beam + 1e-12)
    assert band.tolist() == [False, False, False, False, True, True]
    assert set(guarded.flags[band]) == {"near_asymmetry"} and np.all(np.isnan(guarded.m_lim[:, band]))
    assert not guarded.excluded().any(axis=0)[band].any()
    np.testing.assert_array_equal(guarded.excluded()[:, ~band], plain.excluded()[:, ~band])
    assert "lopsided at 0.41-0.49 arcsec, Delta BIC 25" in guarded.summary()
    assert "asymmetr" not in plain.summary()
    weak = compute_limits(result, resolution=0.0, planets=_verdict_with_alternative(8.0), planet_beam=beam)
    np.testing.assert_array_equal(weak.flags, plain.flags)
    bands = asymmetry_bands(_verdict_with_alternative(25.0))
    assert [b["model"] for b in bands] == ["lopsided"]
    assert bands[0]["r_min"] == pytest.approx(0.41) and bands[0]["r_max"] == pytest.approx(0.49)
    back = type(guarded).load(guarded.save(tmp_path / "limits.h5"))
    assert back.provenance["near_asymmetries"] == bands and back.summary() == guarded.summary()
    # an eccentric bright ring's band: its width for σ_r, widened by the ellipse's reach e r_c
    ring = {"test1_passed": False, "alternatives": {"eccentric_excess": {
        "delta_bic": 30.0, "params": {"r_c": 0.3, "width": 0.02, "e": 0.1, "omega_deg": 10.0, "contrast": 0.5}}}}
    assert asymmetry_bands(ring) == [{"model": "eccentric_excess", "r_min": pytest.approx(0.23),
                                      "r_max": pytest.approx(0.37), "delta_bic": 30.0}]


def test_a_verdict_dict_flags_the_planet_as_the_verdict_does(planted_planet_limits):
    from spiralbayes.inference.detection import detect

    _, result = planted_planet_limits
    verdict = detect(result)
    a = compute_limits(result, resolution=0.0, planets=verdict, planet_beam=0.08)
    b = compute_limits(result, resolution=0.0, planets=verdict.to_dict(), planet_beam=0.08)
    np.testing.assert_array_equal(a.flags, b.flags)
    assert "near_planet" in b.flags.tolist()


def test_aspect_ratio_note_only_where_the_templates_are_optically_thick():
    """Families with τ0 above H_P_SENSITIVE_TAU0 get the sentence naming their aspect ratios (those
    of the optically thick families only); families at τ0 <= 1 do not."""
    from types import SimpleNamespace

    from spiralbayes.inference.limits.robust import H_P_SENSITIVE_TAU0, aspect_ratio_note

    def limits(h_ps, taus):
        return SimpleNamespace(families=[SimpleNamespace(key={"h_p": h, "tau0": t, "variant": "hydro"})
                                         for h in h_ps for t in taus])

    note = aspect_ratio_note(limits((0.05, 0.07, 0.10), (0.3, 3.0)))
    assert "(H/r = 0.05, 0.07, 0.1) only" in note and f"tau0 > {H_P_SENSITIVE_TAU0:g}" in note
    assert "(H/r = 0.07) only" in aspect_ratio_note(limits((0.07,), (3.0,)))
    assert aspect_ratio_note(limits((0.05, 0.07, 0.10), (0.1, 0.3, 1.0))) == ""
