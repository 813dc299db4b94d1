"""The product rule against an independent high-order reference: exact to ~1e-12, within its bound."""

import numpy as np
import pytest

from spiralbayes import DiscGeometry
from spiralbayes.model import perturbation_visibilities
from spiralbayes.quadrature import TemplateSpectrum, make_product_quadrature
from tests._support.quadrature_reference import reference_visibilities

GEOMETRY = DiscGeometry(35.0, 60.0, 0.004, -0.003)
UV_MAX = 4e6


def smooth_profile(r):
    r = np.asarray(r, dtype=float)
    return 1e10 * np.exp(-0.5 * ((r - 0.35) / 0.15) ** 2) + 3e9 * np.exp(-r / 0.2)


def truncated_profile(r):
    """Zero beyond 0.6 arcsec: a jump inside the template's reach (frank's Rmax does this)."""
    r = np.asarray(r, dtype=float)
    return np.where(r < 0.6, smooth_profile(r), 0.0)


@pytest.fixture(scope="module")
def template():
    from spiralbayes.templates import make_template

    return make_template(0.3, 0.3, 0.0, "R", n_x=120, n_phi=240)


@pytest.fixture(scope="module")
def baselines():
    rng = np.random.default_rng(3)
    q = UV_MAX * np.sqrt(rng.uniform(4e-4, 1, 300))
    t = rng.uniform(0, 2 * np.pi, q.size)
    return q * np.cos(t), q * np.sin(t)


@pytest.mark.parametrize("radial,r_p", [("gauss", 0.05), ("gauss", 0.3), ("sinc", 0.3), ("auto", 0.45)])
def test_product_rule_is_exact_within_its_bound(template, baselines, radial, r_p):
    u, v = baselines
    phi_p = 1.1
    quad = make_product_quadrature(template, r_p, UV_MAX, radial=radial)
    fast = perturbation_visibilities(u, v, GEOMETRY, smooth_profile, template, r_p, phi_p, quad=quad, epsilon=1e-13)
    ref = reference_visibilities(u, v, GEOMETRY, smooth_profile, template, r_p, phi_p, order_r=8, order_phi=6)
    ref2 = reference_visibilities(u, v, GEOMETRY, smooth_profile, template, r_p, phi_p, order_r=10, order_phi=8)
    peak = np.max(np.abs(ref))
    assert np.max(np.abs(ref - ref2)) < 1e-12 * peak  # the reference has converged
    err = np.max(np.abs(fast - ref))
    bound = GEOMETRY.cos_inc * quad.error_bound(smooth_profile, TemplateSpectrum(template))["total"]
    assert err <= bound + 2e-13 * peak  # the bound holds (NUFFT rounding aside)
    assert err < 1e-10 * peak
    old = perturbation_visibilities(u, v, GEOMETRY, smooth_profile, template, r_p, phi_p, rule="midpoint")
    assert np.max(np.abs(old - ref)) > 1e3 * max(err, 1e-13 * peak)  # the midpoint cells: second order


def test_profile_edge_is_integrated_exactly_when_given(template, baselines):
    u, v = baselines
    r_p = 0.4  # the template reaches 0.88 arcsec, the profile stops at 0.6
    ref = reference_visibilities(u, v, GEOMETRY, truncated_profile, template, r_p, 0.3, order_r=8, order_phi=6,
                                 support=0.6)
    quad = make_product_quadrature(template, r_p, UV_MAX, support=0.6)
    fast = perturbation_visibilities(u, v, GEOMETRY, truncated_profile, template, r_p, 0.3, quad=quad, epsilon=1e-13)
    assert np.max(np.abs(fast - ref)) < 1e-10 * np.max(np.abs(ref))
    # without the edge the jump sits inside a piece: less exact, and the rule's estimate says so
    blind = make_product_quadrature(template, r_p, UV_MAX)
    rough = perturbation_visibilities(u, v, GEOMETRY, truncated_profile, template, r_p, 0.3, quad=blind,
                                      epsilon=1e-13)
    err = np.max(np.abs(rough - ref))
    assert err > 100 * np.max(np.abs(fast - ref))
    assert GEOMETRY.cos_inc * blind.error_bound(truncated_profile, TemplateSpectrum(template))["fine"] > 0.1 * err


def test_declared_jumps_inside_the_disc_are_integrated_exactly(template, baselines):
    """A cavity edge at 0.5 arcsec (a model disc's inner edge): with ``breaks`` the rule splits there and
    is exact; its error estimate was what flagged the jump before."""
    u, v = baselines
    r_p, edge = 0.4, 0.5

    def holed(r):
        r = np.asarray(r, dtype=float)
        return np.where(r >= edge, smooth_profile(r), 0.0)

    def inside(r):
        r = np.asarray(r, dtype=float)
        return np.where(r < edge, smooth_profile(r), 0.0)

    # the reference is linear in the profile: smooth minus its part inside the edge (cut exactly there)
    ref = (reference_visibilities(u, v, GEOMETRY, smooth_profile, template, r_p, 0.3, order_r=8, order_phi=6)
           - reference_visibilities(u, v, GEOMETRY, inside, template, r_p, 0.3, order_r=8, order_phi=6, support=edge))
    spectrum = TemplateSpectrum(template)
    split = make_product_quadrature(template, r_p, UV_MAX, breaks=(edge,))
    fast = perturbation_visibilities(u, v, GEOMETRY, holed, template, r_p, 0.3, quad=split, epsilon=1e-13)
    peak = np.max(np.abs(ref))
    assert np.max(np.abs(fast - ref)) < 1e-10 * peak
    assert split.at(0.3).breaks == (edge,)  # smaller radii keep the break (at another x)
    blind = make_product_quadrature(template, r_p, UV_MAX)
    bound_blind = blind.error_bound(holed, spectrum)["total"]
    assert bound_blind > 1e3 * split.error_bound(holed, spectrum)["total"]


def test_rule_serves_smaller_radii_on_the_same_nodes(template, baselines):
    u, v = baselines
    big = make_product_quadrature(template, 0.5, UV_MAX)
    small = big.at(0.2)
    np.testing.assert_array_equal(small.positions_x(), big.positions_x())
    fast = perturbation_visibilities(u, v, GEOMETRY, smooth_profile, template, 0.2, 2.0, quad=small, epsilon=1e-13)
    ref = reference_visibilities(u, v, GEOMETRY, smooth_profile, template, 0.2, 2.0, order_r=8, order_phi=6)
    assert np.max(np.abs(fast - ref)) < 1e-10 * np.max(np.abs(ref))
    spectrum = TemplateSpectrum(template)
    np.testing.assert_allclose(small.flux(smooth_profile, spectrum),
                               small.weights(smooth_profile, spectrum) * (0.2 * np.pi / 648000) ** 2, rtol=1e-12)
    with pytest.raises(ValueError, match="built for r_p <= 0.5"):
        big.at(0.6)


def test_node_count_follows_the_data_not_the_template(template):
    """Nodes grow with (u_max r_p)^2, not with the template grid or a cell size."""
    sizes = {(uv, r): make_product_quadrature(template, r, uv).size for uv in (1e6, 4e6) for r in (0.1, 0.4)}
    assert sizes[(1e6, 0.1)] < sizes[(4e6, 0.1)] < sizes[(4e6, 0.4)]
    assert sizes[(4e6, 0.4)] < 0.2 * template.delta.size * 16  # far below the midpoint cells at cf 20
