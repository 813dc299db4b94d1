"""Morphology variants (issue 22): the building blocks, names and families, and the acceptance
criteria against the reference maps (noise-free A_up at the truth >= 1 with the matching family,
robust over variants; leave one source out)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("h5py")

from spiralbayes.inference.limits.families import template_families  # noqa: E402
from spiralbayes.templates import make_template  # noqa: E402
from spiralbayes.templates.template import template_metadata  # noqa: E402
from spiralbayes.templates.variants import (  # noqa: E402
    DEFAULT_VARIANTS,
    VARIANTS,
    blob_template,
    variant_template,
)
from tests.templates import fidelity as F  # noqa: E402
from tests.templates import variant_fit as VF  # noqa: E402

SMALL = dict(n_x=120, n_phi=360)
CASES = {c.label: c for c in F.reference_cases()}


def test_a_variant_is_scale_times_the_generator_plus_the_near_planet_peak():
    v = VARIANTS["hydro"]
    t = variant_template(1.0, 0.3, 0.0, "R", "hydro", h_p=0.07, **SMALL)
    base = make_template(1.0, 0.3, 0.0, "R", h_p=0.07, **SMALL)
    blob = blob_template(1.0, 0.3, 0.0, "R", h_p=0.07, width=v.blob_width, **SMALL)
    np.testing.assert_allclose(t.delta, v.scale * base.delta + v.blob * blob.delta, rtol=1e-5, atol=1e-7)
    np.testing.assert_array_equal(variant_template(1.0, 0.3, 0.0, "R", "compromise", h_p=0.07, **SMALL).delta,
                                  base.delta)
    # the peak sits at the planet: its largest |delta| lies within one H_p of (x, phi) = (1, 0)
    i, j = np.unravel_index(np.argmax(np.abs(blob.delta)), blob.delta.shape)
    assert abs(blob.x[i] - 1) < 0.07 and min(blob.phi[j], 2 * np.pi - blob.phi[j]) < 0.07


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
    temps = [variant_template(case.mu, tau0, 0.0, "R", v, h_p=case.h_p) for v in variants]
    cross, power = VF.truth_products(ref, temps, tau0)
    a_up = cross[1:] / power[1:] + VF.Z95 / np.sqrt(power[1:])
    return dict(zip(variants, a_up))


BEFORE_FAILING = [("fargo3d:h0.07_mu1", 0.3), ("fargo3d:h0.07_mu1", 3.0), ("wakeflow:h0.07_mu1", 3.0)]


@pytest.mark.parametrize("label,tau0", BEFORE_FAILING, ids=[f"{c}-tau{t:g}" for c, t in BEFORE_FAILING])
def test_reference_spirals_wrongly_excluded_by_one_template_are_not_by_the_variants(label, tau0):
    """Measured: compromise A_up 0.558 / 0.961 / 0.949; robust (max over variants) 1.35 / 2.03 / 1.75."""
    ups = robust_upper_limits(label, tau0)
    assert ups["compromise"] < 1.0, ups  # the single-template limit excludes the planet that is there
    assert max(ups.values()) >= 1.0, ups


@pytest.mark.slow
@pytest.mark.parametrize("label", sorted(CASES))
@pytest.mark.parametrize("tau0", F.TAUS)
def test_no_reference_spiral_is_excluded_without_noise(label, tau0):
    ups = robust_upper_limits(label, tau0)
    print(label, tau0, {k: round(float(v), 3) for k, v in ups.items()})
    assert max(ups.values()) >= 1.0, ups


def _refit_and_plant(fit_rows, planted_rows):
    """Variants refitted to ``fit_rows`` (plus the compromise): robust A_up of each planted row."""
    fit = VF.fit_source(fit_rows)
    out = []
    for case, tau0, g in planted_rows:
        ups = [VF.upper_limit(g, 1.0, 0.0)[1],
               VF.upper_limit(g, fit["scale_final"], fit["blob_final"] * case.mu ** fit["slope"])[1]]
        out.append((case.label, tau0, max(ups)))
    return out


def test_leave_one_source_out_fast():
    """Variants built from FARGO3D's τ0 = 0.3 maps only, planted: wakeflow's worst case before."""
    fit_rows = [(CASES[c], 0.3, VF.case_gram(CASES[c], 0.3)) for c in ("fargo3d:h0.07_mu0.3", "fargo3d:h0.07_mu1")]
    held = CASES["wakeflow:h0.07_mu1"]
    result = _refit_and_plant(fit_rows, [(held, 3.0, VF.case_gram(held, 3.0))])
    assert result[0][2] >= 1.0, result


@pytest.mark.slow
def test_leave_wakeflow_out():
    rows = [(c, t, VF.case_gram(c, t)) for c in CASES.values() for t in F.TAUS]
    result = _refit_and_plant([r for r in rows if r[0].source == "fargo3d"], [r for r in rows if r[0].source == "wakeflow"])
    print(result)
    assert all(a >= 1.0 for _, _, a in result), result


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="known (issue 22 report): variants fitted to wakeflow alone do not cover "
                   "the FARGO3D 1 M_th spiral at tau0 0.3 (robust A_up 0.74)")
def test_leave_fargo3d_out():
    rows = [(c, t, VF.case_gram(c, t)) for c in CASES.values() for t in F.TAUS]
    result = _refit_and_plant([r for r in rows if r[0].source == "wakeflow"], [r for r in rows if r[0].source == "fargo3d"])
    print(result)
    assert all(a >= 1.0 for _, _, a in result), result


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
