"""Morphology variants (issue 22): the building blocks, names and families, and the acceptance
criteria against the reference maps (noise-free A_up at the truth >= 1 with the matching family,
robust over variants; leave one source out, noise-free here — with noise in
``tests/inference/validation/test_robust_calibration.py``).

The reference cases are ``fidelity.acceptance_cases()``: every wakeflow map, the two runs of
``fargo3d_isothermal.h5`` and the library's finished ``role = library`` runs, each at every τ0 it
was reduced for (library: 0.1, 0.3, 1, 3), against the generator of its own (M_p, H/r, τ0, β)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("h5py")

from spiralbayes.inference.limits.families import template_families
from spiralbayes.templates import make_template
from spiralbayes.templates.template import template_metadata
from spiralbayes.templates.variants import (
    DEFAULT_VARIANTS,
    VARIANTS,
    blob_template,
    coorbital_template,
    variant_template,
)
from tests.templates import fidelity as F
from tests.templates import variant_fit as VF

SMALL = dict(n_x=120, n_phi=360)
CASES = {c.label: c for c in F.acceptance_cases()}
GRID_CASES = [(label, t) for label, c in CASES.items() for t in c.taus]


@pytest.mark.parametrize("mass", [1.0, 3.0])
def test_a_variant_is_scale_times_the_generator_plus_the_near_planet_peak_and_the_broad_wake(mass):
    v = VARIANTS["hydro"]
    t = variant_template(mass, 0.3, 0.0, "R", "hydro", h_p=0.07, **SMALL)
    base = make_template(mass, 0.3, 0.0, "R", h_p=0.07, **SMALL)
    blob = blob_template(mass, 0.3, 0.0, "R", h_p=0.07, width=v.blob_width, **SMALL)
    wide = make_template(mass, 0.3, 0.0, "R", h_p=0.07, profile_width=v.broad_width * 0.95, **SMALL)
    k = dict(v.mass_factors)[mass]  # the docstring's law, by hand, at a reference mass
    scale, peak, broad = (k * v.scale * mass**v.scale_slope, k * v.blob * mass**v.blob_slope,
                          k * v.broad * mass**v.scale_slope)
    np.testing.assert_allclose(t.delta, scale * base.delta + peak * blob.delta + broad * wide.delta,
                               rtol=1e-5, atol=1e-6)
    np.testing.assert_array_equal(variant_template(mass, 0.3, 0.0, "R", "compromise", h_p=0.07, **SMALL).delta,
                                  base.delta)
    # the peak sits at the planet: its largest |delta| lies within one H_p of (x, phi) = (1, 0)
    i, j = np.unravel_index(np.argmax(np.abs(blob.delta)), blob.delta.shape)
    assert abs(blob.x[i] - 1) < 0.07 and min(blob.phi[j], 2 * np.pi - blob.phi[j]) < 0.07


@pytest.mark.parametrize("tau0", [0.1, 0.3, 1.0, 3.0])
@pytest.mark.parametrize("mass", [0.3, 1.0, 3.0])
def test_the_coorbital_block_is_the_linearised_isothermal_slab(mass, tau0):
    """Reference: an isothermal slab's brightness ``∝ 1 − exp(−τ)``, so a small ``δΣ/Σ`` changes it by
    ``δ = τ / (exp τ − 1) δΣ/Σ`` with ``τ = τ0 Σ(x)/Σ_0(r_p)`` (the generator's gapped profile):
    the band ``−exp(−(x − 1)²/2w²) sin φ`` dimmed where the disc is thick."""
    from spiralbayes.templates.wake import WakeSettings, gap_profile

    d = coorbital_template(mass, tau0, 0.0, "R", h_p=0.07, width=1.0, **SMALL)
    st = WakeSettings(h_p=0.07, **SMALL)
    tau = tau0 * d.x ** -st.sigma_slope * gap_profile(d.x, mass, st)
    expected = (tau / np.expm1(tau) * np.exp(-0.5 * ((d.x - 1.0) / 0.07) ** 2))[:, None] * -np.sin(d.phi)[None, :]
    # the block is a central difference with a step of 1e-3 in δΣ/Σ: its error is of order 1e-6
    assert np.max(np.abs(d.delta - expected)) < 1e-5 * np.max(np.abs(expected))
    assert d.provenance["width_Hp"] == 1.0 and d.name.startswith("coorbital_")


def test_the_coorbital_block_alone_does_not_tell_the_hands_apart():
    """Dust piles up behind the planet, so the block is handed (L is R mirrored: ``+ sin φ``), but
    the left-handed block half a turn on is the right-handed one: only arms can tell the hands apart."""
    right = coorbital_template(1.0, 0.3, 0.0, "R", h_p=0.07, **SMALL)
    left = coorbital_template(1.0, 0.3, 0.0, "L", h_p=0.07, **SMALL)
    np.testing.assert_allclose(left.delta, -right.delta, atol=1e-10)
    half = right.phi.size // 2
    np.testing.assert_allclose(np.roll(left.delta, half, axis=1), right.delta, atol=1e-10)
    behind = (right.phi > np.pi + 0.01) & (right.phi < 2 * np.pi - 0.01)  # behind a planet moving towards +φ
    ahead = (right.phi > 0.01) & (right.phi < np.pi - 0.01)
    ring = np.argmin(np.abs(right.x - 1.0))
    assert np.all(right.delta[ring, behind] > 0.01) and np.all(right.delta[ring, ahead] < -0.01)


def test_variant_is_carried_by_names_metadata_mirror_and_families():
    templates = []
    for name in DEFAULT_VARIANTS:
        for m in (0.3, 1.0):
            right = variant_template(m, 0.3, 0.0, "R", name, h_p=0.07, **SMALL)
            templates += [right, right.mirror()]
    names = [t.name for t in templates]
    assert "wake_m1_tau0.3_b0_h0.07_R" in names and "hydro_m1_tau0.3_b0_h0.07_L" in names
    assert len(set(names)) == len(names)
    meta = [template_metadata(t) for t in templates]
    assert {m["variant"] for m in meta} == set(DEFAULT_VARIANTS)
    fams = template_families(meta)
    assert [f.key["variant"] for f in fams] == sorted(DEFAULT_VARIANTS)
    assert all(f.masses == [0.3, 1.0] and f.hands == ["R", "L"] for f in fams)
    assert "variant=hydro" in [f.label for f in fams][1]

    class _Result:  # mirror matching only reads the metadata
        pass

    from spiralbayes.inference.detection import mirror_index

    res = _Result()
    res.templates = meta
    for k, m in enumerate(meta):
        j = mirror_index(res, k)
        assert meta[j]["variant"] == m["variant"] and meta[j]["hand"] != m["hand"] and meta[j]["mass"] == m["mass"]


def test_every_fitted_constant_names_its_reference_cases():
    for v in VARIANTS.values():
        if v.name == "compromise":
            continue
        assert v.fitted_to, v
        for ref in v.fitted_to:
            file, group = ref.split(":")
            assert any(c.file == file and c.group == group for c in CASES.values()), ref
        assert "binding case" in v.note and any(ref in v.note for ref in v.fitted_to)


def robust_upper_limits(label: str, tau0: float, variants=DEFAULT_VARIANTS) -> dict:
    """Noise-free A_up at the truth of each variant's true-mass template (matching family)."""
    case = CASES[label]
    ref = F.reference_template(case, tau0)
    temps = [variant_template(case.mu, tau0, case.beta, "R", v, h_p=case.h_p) for v in variants]
    cross, power = VF.truth_products(ref, temps, tau0)
    a_up = cross[1:] / power[1:] + VF.Z95 / np.sqrt(power[1:])
    return dict(zip(variants, a_up))


BEFORE_FAILING = [("fargo3d:h0.07_mu1", 0.3), ("fargo3d:h0.07_mu1", 3.0), ("wakeflow:h0.07_mu1", 3.0),
                  ("fargo3dlib:h0.07_mu3", 0.3), ("fargo3dlib:h0.07_mu1_beta10", 0.3),
                  ("fargo3dlib:h0.07_mu1_st0.03", 0.3)]
"""One case per source that the single (compromise) template excludes without noise."""


@pytest.mark.parametrize("label,tau0", BEFORE_FAILING, ids=[f"{c}-tau{t:g}" for c, t in BEFORE_FAILING])
def test_reference_spirals_wrongly_excluded_by_one_template_are_not_by_the_variants(label, tau0):
    """Measured: compromise A_up 0.56 / 0.96 / 0.95 / 0.21 / 0.64 / 0.63; robust (max over
    variants, the hydro variant each time) 1.58 / 2.07 / 1.60 / 1.37 / 1.55 / 1.67."""
    ups = robust_upper_limits(label, tau0)
    assert ups["compromise"] < 1.0, ups  # the single-template limit excludes the planet that is there
    assert max(ups.values()) >= 1.0, ups


@pytest.mark.slow
@pytest.mark.parametrize("label,tau0", GRID_CASES, ids=[f"{c}-tau{t:g}" for c, t in GRID_CASES])
def test_no_reference_spiral_is_excluded_without_noise(label, tau0):
    """Every reference case × τ0 (docs/templates.md lists the minimum per source)."""
    ups = robust_upper_limits(label, tau0)
    print(label, tau0, {k: round(float(v), 3) for k, v in ups.items()})
    assert max(ups.values()) >= 1.0, ups


def _refit_and_plant(fit_rows, planted_rows):
    """Variants refitted to ``fit_rows`` (plus the compromise): robust A_up of each planted row."""
    fits = VF.fit_variants(fit_rows)
    out = []
    for case, tau0, g in planted_rows:
        ups = [VF.upper_limit(g, 1.0, 0.0)[1]] + [VF.upper_limit(g, *VF.fitted_amplitudes(f, case.mu))[1]
                                                    for f in fits.values()]
        out.append((case.label, tau0, round(max(ups), 3)))
    return out


def test_leave_one_source_out_fast():
    """Variants built from the library's three H/r 0.07 isothermal maps at τ0 0.3 only, planted:
    the old FARGO3D 1 M_th run and the dust run (compromise A_up 0.56 and 0.63; measured 1.39 and 1.44)."""
    fit_rows = [(CASES[c], 0.3, VF.case_gram(CASES[c], 0.3))
                for c in ("fargo3dlib:h0.07_mu0.3", "fargo3dlib:h0.07_mu1", "fargo3dlib:h0.07_mu3")]
    held = [(CASES[c], 0.3, VF.case_gram(CASES[c], 0.3)) for c in ("fargo3d:h0.07_mu1", "fargo3dlib:h0.07_mu1_st0.03")]
    result = _refit_and_plant(fit_rows, held)
    assert all(a >= 1.0 for _, _, a in result), result


@pytest.mark.slow
@pytest.mark.parametrize("source", VF.SOURCES)
def test_leave_one_source_out(source):
    """Variants refitted without ``source``; every map of ``source`` at every τ0 has robust A_up >= 1."""
    rows = VF.reference_rows()
    result = _refit_and_plant([r for r in rows if VF.calibration_source(r[0]) != source],
                              [r for r in rows if VF.calibration_source(r[0]) == source])
    print(source, result)
    assert result and all(a >= 1.0 for _, _, a in result), result


def test_held_out_run_sets_are_in_no_fit():
    """The ``physics`` and ``dust2`` run sets are planted by the checks but never fitted: rows of
    them, however they pull, leave the fitted constants as they are (synthetic inner products)."""
    rng = np.random.default_rng(3)

    def gram(scale):
        a = rng.normal(size=(4, 4)) * scale
        m = a @ a.T + 4 * np.eye(4)  # S, T, B, W
        names = "STBW"
        return {names[i] + names[j]: float(m[i, j]) for i in range(4) for j in range(i, 4)}

    gas = [c for c in CASES.values() if VF.calibration_source(c) == "library_gas"][:4]
    dust2 = [c for c in CASES.values() if c.batch == "dust2"]
    assert dust2 and all(VF.calibration_source(c) == "dust2" for c in dust2)
    assert set(VF.HELD_OUT_SOURCES) == {"physics", "dust2"}
    fitted = [(c, 0.3, gram(1.0)) for c in gas]
    held = [(c, 0.3, gram(5.0)) for c in dust2]
    assert VF.fit_variants(fitted + held) == VF.fit_variants(fitted)
    assert VF.fit_variants(held) == {}


@pytest.mark.slow
def test_the_hydro_and_wakeflow_constants_are_the_fit_to_the_current_references():
    """tools/fit_variants.py on today's references reproduces the constants (a library that gained
    cases fails here: refit and update VARIANTS and docs/templates.md)."""
    fits = VF.fit_variants(VF.reference_rows())
    for name, f in fits.items():
        v = VARIANTS[name]
        assert f["scale_slope"] == pytest.approx(v.scale_slope) and f["slope"] == pytest.approx(v.blob_slope)
        assert f["scale_final"] == pytest.approx(v.scale, rel=2e-3)
        assert f["blob_final"] == pytest.approx(v.blob, rel=2e-3)
        assert f["broad_final"] == pytest.approx(v.broad, rel=2e-3, abs=1e-12)
        assert v.broad == 0.0 or v.broad_width == VF.BROAD_WIDTH
        assert dict(v.mass_factors) == pytest.approx(f["mass_factors"], rel=2e-3)
        binding = f["binding"].split()[0]
        assert binding.split(":")[1] in v.note
    hydro_refs = {f"{c.file}:{c.group}" for c in CASES.values()
                  if c.source != "wakeflow" and c.label not in VF.FIT_EXCLUDED
                  and VF.calibration_source(c) not in VF.HELD_OUT_SOURCES}
    assert set(VARIANTS["hydro"].fitted_to) == hydro_refs


def test_compute_limits_is_robust_over_variants_for_a_planted_hydro_spiral():
    """FARGO3D 1 M_th (τ0 0.3) planted noise-free at 50 au: the compromise family alone rules out
    1 M_th at the planet's radius; over the three variants it is not ruled out, and the summary names
    the morphology set and prints the price of robustness."""
    from spiralbayes.inference.limits import compute_limits

    case = CASES["fargo3d:h0.07_mu1"]
    ref = F.reference_template(case, 0.3)
    temps = []
    for v in DEFAULT_VARIANTS:
        for m in (0.3, 1.0, 3.0):
            right = variant_template(m, 0.3, 0.0, "R", v, h_p=0.07)
            temps += [right, right.mirror()]
    result, _, _ = F.observe_and_scan(ref, temps, 0.3, VF.INC, VF.PHI_P_DEG, n_rp=1)
    keep = [i for i, t in enumerate(result.templates) if t.get("variant")]  # drop the reference itself
    result.templates = [result.templates[i] for i in keep]
    result.cross, result.power = result.cross[keep], result.power[keep]
    limits = compute_limits(result, resolution=0.0)
    single = {"tau0": 0.3, "beta": 0.0, "h_p": 0.07, "variant": "compromise"}
    assert limits.excluded(single, 1.0)[0]
    assert not limits.excluded(mass=1.0)[0]
    text = limits.summary()
    assert "{compromise, hydro, wakeflow}" in text and "price of robustness" in text


def test_a_variant_is_rebuilt_from_its_templates_constants():
    """The scan reads a template's variant back from ``provenance["variant_constants"]``."""
    from spiralbayes.templates.variants import Variant

    for v in VARIANTS.values():
        t = variant_template(3.0, 0.3, 0.0, "R", v, h_p=0.07, **SMALL)
        back = Variant.from_constants(t.provenance["variant"], t.provenance["variant_constants"])
        assert back.constants() == v.constants() and back.name == v.name
        assert back.scale_at(3.0) == v.scale_at(3.0) and back.broad_at(3.0) == v.broad_at(3.0)
    old = {"scale": 0.5, "blob": 0.1, "blob_slope": 1.0, "blob_width_Hp": 0.5}  # a bank from before W
    assert Variant.from_constants("hydro", old).broad == 0.0 and Variant.from_constants("hydro", old).factor_at(3) == 1
