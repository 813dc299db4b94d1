"""Variant banks scanned through their building blocks (issue 22, speed) against the plain engine.

The reference is the plain per-template path of the same engine (every template scanned on its own,
``building_blocks=False``), which the exactness suite (test_exactness.py) ties to a converged
quadrature. Every template, every position of a whole small grid, both power paths, on synthetic
data with a planted variant spiral (so large Δχ² are tested too): the two must agree within the
engine's tolerance ``0.05 + 1e-4 |Δχ²|``, each term within 1e-6 (cross relative to
``max(|cross|, sqrt(power))``), the generator templates' cross terms bit for bit, and the two paths' error
estimates must cover the difference but for the templates' float32 storage (the building blocks
scan ``s T + a B`` in double precision, the plain path its float32 rounding).
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
import pytest

from spiralbayes import DiscGeometry
from spiralbayes.axisymmetric import AxisymmetricModel
from spiralbayes.exceptions import AccuracyWarning, ResumeMismatchError
from spiralbayes.inference.scan.building_blocks import building_block_groups
from spiralbayes.inference.scan.run import ScanResult, scan
from spiralbayes.model import perturbation_visibilities
from spiralbayes.templates.variants import DEFAULT_VARIANTS, VARIANTS, variant_grid
from spiralbayes.visibilities import Visibilities

GEOMETRY = DiscGeometry(35.0, 70.0, 0.006, -0.004)  # inclined, offset phase centre
R_P = np.array([0.06, 0.18, 0.3, 0.42])
N_PHI = 30


def _profile(r):
    r = np.asarray(r, dtype=float)
    return 4e10 * np.exp(-r / 0.25 - (r / 0.7) ** 6) * (1 + 0.5 * np.exp(-0.5 * ((r - 0.4) / 0.03) ** 2))


@pytest.fixture(scope="module")
def bank():
    """Every default variant at two masses, one τ0, both β and both hands (24 templates, coarse grid)."""
    return variant_grid(DEFAULT_VARIANTS, masses=(0.3, 1.0), taus=(0.3,), betas=(0.0, 10.0), n_x=120, n_phi=240)


@pytest.fixture(scope="module")
def data(bank):
    """3000 baselines to 3 Mlambda, a ringed disc, the hydro variant of a 1 M_th planet at 0.3 arcsec."""
    rng = np.random.default_rng(22)
    n = 3000
    q = 3e6 * np.sqrt(rng.uniform(1e-3, 1, n))
    th = rng.uniform(0, 2 * np.pi, n)
    u, v = q * np.cos(th), q * np.sin(th)
    model = AxisymmetricModel.from_profile(_profile, GEOMETRY, N=300, Rmax=1.2)
    planet = next(t for t in bank if t.provenance["variant"] == "hydro" and t.mass == 1.0 and t.hand == "R")
    dV = perturbation_visibilities(u, v, GEOMETRY, model.brightness, planet, 0.3, 1.0)
    sigma = np.sqrt(np.sum(np.abs(dV) ** 2) / 400.0)  # the planet alone: Δχ² ~ 400
    V = model.visibilities(u, v, GEOMETRY) + dV + sigma * (rng.normal(size=n) + 1j * rng.normal(size=n))
    return Visibilities(u, v, V, np.full(n, sigma ** -2)), model


def _one_mass(bank):
    """The three variants of 1 M_th, β = 0, both hands (6 templates)."""
    return [t for t in bank if t.mass == 1.0 and t.beta == 0.0]


def _scan(data, templates, **options):
    vis, model = data
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)  # neither path may doubt itself here
        return scan(vis, model, templates, GEOMETRY, r_p=R_P, n_phi_p=N_PHI, progress=False, **options)


def test_the_default_variants_form_groups_sharing_one_peak(bank):
    groups, plain = building_block_groups(bank)
    assert plain == []
    assert sorted(i for g in groups for i in g.indices) == list(range(len(bank)))
    # one near-planet peak per (mass, τ0, H/r): shared by both β and both hands; per (β, hand) the
    # generator T (compromise, wakeflow) and the hydro variant's own T' = δ - a B (its broad wake)
    assert VARIANTS["hydro"].broad != 0.0 and VARIANTS["wakeflow"].broad == 0.0
    assert len(groups) == 2 and all(len(g.generators) == 8 for g in groups)
    hydro = {i for i, t in enumerate(bank) if t.provenance["variant"] == "hydro"}
    for g in groups:
        for gen in g.generators:
            rows = {m[0] for m in gen.members}
            assert rows <= hydro or not rows & hydro  # a hydro member is a generator of its own
            if rows <= hydro:
                assert len(rows) == 1 and gen.members[0][1] == 1.0


@pytest.mark.parametrize("power_path", ["polar", "direct"])
def test_building_blocks_match_the_plain_scan_on_a_whole_grid(data, bank, power_path):
    fast = _scan(data, bank, power_path=power_path)
    plain = _scan(data, bank, power_path=power_path, building_blocks=False)
    assert fast.provenance["quadrature"]["power_path_used"] == power_path
    assert "structure" in fast.provenance["resume_key"] and "structure" not in plain.provenance["resume_key"]
    assert fast.templates == plain.templates
    for name in ("cross", "power", "cross_error", "power_error"):
        assert getattr(fast, name).shape == getattr(plain, name).shape
    assert np.nanmax(plain.dchi2) > 200  # the planted spiral is found: large Δχ² are compared too

    d_fast, d_plain = fast.dchi2, plain.dchi2
    diff = np.abs(d_fast - d_plain)
    dP = np.abs(fast.power - plain.power) / plain.power
    dC = np.abs(fast.cross - plain.cross) / np.maximum(np.abs(plain.cross), np.sqrt(plain.power))
    print(f"{power_path}: max |d dchi2| {diff.max():.2e}, max |dP|/P {dP.max():.2e}, max |dC| {dC.max():.2e}, "
          f"largest estimate {np.nanmax(fast.delta_chi2_error()):.2e}")
    assert np.all(diff <= 0.05 + 1e-4 * np.abs(d_plain))
    assert dP.max() < 1e-6 and dC.max() < 1e-6
    # each path's error estimate bounds its distance to the exact Δχ² of what it scanned; the two
    # perturbations differ by the bank's float32 storage of δ (2^-24 of δ per cell), allowed 1e-6
    rounding = 1e-6 * (2 * np.maximum(np.abs(plain.cross), np.sqrt(plain.power)) + plain.power)
    assert np.all(diff <= fast.delta_chi2_error() + plain.delta_chi2_error() + rounding)
    assert not fast.accuracy_violations().any()

    generators = [i for i, t in enumerate(bank) if t.provenance["variant"] == "compromise"]
    np.testing.assert_array_equal(fast.cross[generators], plain.cross[generators])  # the same calls
    if power_path == "direct":  # the polar path sends two blocks through one transform
        for name in ("power", "cross_error", "power_error"):
            np.testing.assert_array_equal(getattr(fast, name)[generators], getattr(plain, name)[generators])
    else:
        assert 0 < fast.provenance["power_check"]["pairs"] < 1e-7
    # the building blocks' bound is subadditive: never below the plain bound (up to rounding)
    assert np.all(fast.delta_chi2_error() >= plain.delta_chi2_error() * (1 - 1e-9))


@pytest.mark.parametrize("variant", ["wakeflow", "hydro"])
def test_a_template_that_is_not_its_variant_is_scanned_plainly(data, bank, variant):
    """A template whose δ was changed after it was made keeps its provenance. The peak B is recovered
    from the variant without a broad wake (wakeflow; its right hand): changed, the other members in
    the span of T and B fail the check instead. The hydro variant (broad wake) is a generator of its
    own, ``δ - a B`` from its stored δ, so it stays exact, changed or not, and nothing is scanned
    plainly."""
    templates = _one_mass(bank)
    k = next(i for i, t in enumerate(templates) if t.provenance["variant"] == variant and t.hand == "R")
    delta = np.array(templates[k].delta)
    delta[40:60, 100:140] *= 1.01
    templates[k] = replace(templates[k], delta=delta)
    groups, plain = building_block_groups(templates)
    others = [i for i, t in enumerate(templates) if t.provenance["variant"] != "compromise" and i != k]
    in_span = [i for i in others if templates[i].provenance["variant"] == "wakeflow"]
    assert plain == (in_span if variant == "wakeflow" else [])
    fast = _scan(data, templates)
    reference = _scan(data, templates, building_blocks=False)
    np.testing.assert_array_equal(fast.cross[plain], reference.cross[plain])
    np.testing.assert_array_equal(fast.power[plain], reference.power[plain])
    assert np.all(np.abs(fast.dchi2 - reference.dchi2) <= 0.05 + 1e-4 * np.abs(reference.dchi2))


def test_resume_keys_tell_the_paths_apart(tmp_path, data, bank):
    vis, model = data
    templates = _one_mass(bank)
    kwargs = dict(r_p=R_P[:2], n_phi_p=10, progress=False)
    checkpoint = tmp_path / "scan.h5"
    first = scan(vis, model, templates, GEOMETRY, checkpoint=checkpoint, **kwargs)
    again = scan(vis, model, templates, GEOMETRY, checkpoint=checkpoint, **kwargs)  # resumed, nothing to do
    np.testing.assert_array_equal(again.dchi2, first.dchi2)
    assert ScanResult.load(checkpoint).completed.all()
    with pytest.raises(ResumeMismatchError, match="building blocks"):
        scan(vis, model, templates, GEOMETRY, checkpoint=checkpoint, building_blocks=False, **kwargs)


def test_dask_runs_the_groups_as_the_serial_scan(data, bank):
    from dask.distributed import Client, LocalCluster

    vis, model = data
    templates = _one_mass(bank) + [t for t in bank if t.mass == 0.3 and t.beta == 10.0]  # two groups
    kwargs = dict(r_p=R_P[1:3], n_phi_p=10, progress=False)
    serial = scan(vis, model, templates, GEOMETRY, **kwargs)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        parallel = scan(vis, model, templates, GEOMETRY, scheduler=client, **kwargs)
    assert "structure" in parallel.provenance["resume_key"]
    np.testing.assert_allclose(parallel.dchi2, serial.dchi2, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("power_path", ["polar", "direct"])
def test_pair_terms_give_the_cross_power_of_two_templates(data, bank, power_path):
    """The cross power ``Re Σ w ΔV_1 conj ΔV_2`` against two references: the polarisation identity
    of the plain engine's powers (``P(1 + 2) - P(1) - P(2)``, three independent scans of whole
    templates) on the whole grid, and the visibilities themselves at a few positions; the single
    terms equal the plain engine's."""
    from spiralbayes.inference.scan import ScanContext, pair_terms, scan_template
    from spiralbayes.templates.variants import coorbital_template

    vis, model = data
    first = next(t for t in bank if t.provenance["variant"] == "compromise" and t.mass == 1.0 and t.hand == "R")
    second = coorbital_template(1.0, 0.3, 0.0, "R", n_x=120, n_phi=240)
    both = replace(second, delta=np.asarray(first.delta, float) + np.asarray(second.delta, float))
    ctx = ScanContext.build(vis, model, GEOMETRY, R_P, N_PHI, power_path=power_path)
    c1, p1, c2, p2, p12 = pair_terms(ctx, first, second)
    for (c, p), template in (((c1, p1), first), ((c2, p2), second)):
        terms = scan_template(ctx, template)
        np.testing.assert_allclose(c, terms[0], rtol=1e-9, atol=1e-9 * np.sqrt(np.max(terms[1])))
        np.testing.assert_allclose(p, terms[1], rtol=1e-7)
    identity = 0.5 * (scan_template(ctx, both)[1] - p1 - p2)
    scale = np.sqrt(p1 * p2)
    print(f"largest correlation {np.max(np.abs(p12) / scale):.3f}")
    assert np.max(np.abs(p12) / scale) > 0.05  # the two blocks overlap: a non-trivial check
    assert np.max(np.abs(p12 - identity) / scale) < 1e-6

    for i, j in ((1, 0), (2, 7), (3, 19)):
        dv = [perturbation_visibilities(vis.u, vis.v, GEOMETRY, model.brightness, t, R_P[i], 2 * np.pi * j / N_PHI,
                                        quad=ctx.quadrature(t, R_P[i])) for t in (first, second)]
        exact = float(np.sum(vis.weights * (dv[0] * np.conj(dv[1])).real))
        assert abs(p12[i, j] - exact) <= 1e-6 * np.sqrt(p1[i, j] * p2[i, j])


def test_pair_terms_refuse_templates_on_different_grids(data, bank):
    from spiralbayes.exceptions import InputError
    from spiralbayes.inference.scan import ScanContext, pair_terms
    from spiralbayes.templates.variants import coorbital_template

    vis, model = data
    ctx = ScanContext.build(vis, model, GEOMETRY, R_P[:1], N_PHI)
    with pytest.raises(InputError, match="different"):
        pair_terms(ctx, bank[0], coorbital_template(1.0, 0.3, 0.0, "R"))
