"""The injection algebra: Δχ²_injected = Δχ² + 2 X(a, b), X from the scan's polar uv grid."""

import numpy as np
import pytest

from spiralbayes.inference.limits.injection import (
    Injection,
    InjectionEngine,
    brute_force_injection,
    injected_cross_reference,
)
from spiralbayes.inference.scan.engine import ScanContext, cross_template, with_residual
from spiralbayes.model import perturbation_visibilities
from tests._support import limits_setup


@pytest.fixture(scope="module")
def engine(limits_case):
    vis, model, templates, result = limits_case
    context = ScanContext.build(vis, model, limits_setup.GEOMETRY, result.r_p, result.phi_p.size)
    return InjectionEngine(context, templates, keep=templates[:2])


def test_cross_term_equals_direct_sum_at_every_baseline(engine, limits_case):
    _, _, templates, result = limits_case
    ctx = engine.context
    injections = [Injection(templates[2], 0.25, result.phi_p[7]),           # 1 M_th R on the grid
                  Injection(templates[1], 0.35, 1.234, amplitude=0.5),      # off the grid, half amplitude
                  Injection(templates[4], 0.15, result.phi_p[20])]          # 3 M_th
    x = engine.cross(injections, chunk=2)
    assert x.shape == (3, len(templates), result.r_p.size, result.phi_p.size)
    for a, inj in enumerate(injections):
        power_a = injected_cross_reference(ctx, inj, inj.template, inj.r_p, inj.phi_p) / inj.amplitude
        for t, i, j in [(2, 1, 7), (3, 1, 9), (0, 2, 25), (5, 0, 3), (4, 3, 14)]:
            ref = injected_cross_reference(ctx, inj, templates[t], result.r_p[i], result.phi_p[j])
            scale = np.sqrt(result.power[t, i, j] * power_a)  # Cauchy-Schwarz bound of |X|
            assert x[a, t, i, j] == pytest.approx(ref, abs=5e-5 * scale), (a, t, i, j)  # measured <= 1e-5


def test_cross_term_equals_rescan_of_injected_residual(engine, limits_case):
    vis, model, templates, result = limits_case
    ctx = engine.context
    inj = Injection(templates[2], 0.35, result.phi_p[11])
    dv = perturbation_visibilities(vis.u, vis.v, limits_setup.GEOMETRY, ctx.profile, inj.template, inj.r_p,
                                   inj.phi_p, quad=ctx.quadrature(inj.template, inj.r_p))
    rescan = np.array([cross_template(with_residual(ctx, dv), t) for t in templates])
    fast = engine.cross([inj])[0]
    assert np.max(np.abs(fast - rescan)) <= 1e-3 * np.max(np.abs(rescan))


def test_injected_delta_chi2_equals_brute_force_scan(engine, limits_case):
    """The whole map of the injected dataset: data's Δχ² + 2 X against a scan of V_O + ΔV."""
    vis, model, templates, result = limits_case
    inj = Injection(templates[2], 0.25, result.phi_p[4])
    brute = brute_force_injection(vis, model, templates, inj, limits_setup.GEOMETRY, r_p=result.r_p,
                                  n_phi_p=result.phi_p.size, progress=False)
    fast = result.dchi2 + 2 * engine.cross([inj])[0]
    assert np.max(np.abs(fast - brute.dchi2)) <= 1e-3 * np.max(np.abs(brute.dchi2))
    assert brute.best.template == templates[2].name


def test_injection_beyond_the_grid_is_refused(engine, limits_case):
    templates = limits_case[2]
    with pytest.raises(ValueError, match="beyond the scan's grid"):
        engine.cross([Injection(templates[0], 0.9, 0.0)])
