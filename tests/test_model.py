"""The spiral perturbation's visibilities: NUFFT vs direct sum vs a converged image."""

import numpy as np
import pytest

from spiralbayes import DiscGeometry
from spiralbayes.fourier import dirty_image, image_axes, sample_image
from spiralbayes.model import (
    make_quadrature,
    perturbation_visibilities,
    perturbation_visibilities_dft,
    render_perturbation_image,
)


def power_law_profile(r):
    r = np.asarray(r, dtype=float)
    return np.where((r > 0.05) & (r < 0.8), 1e10 * (np.maximum(r, 1e-3) / 0.3) ** -1, 0.0)


@pytest.fixture(scope="module")
def template():
    from spiralbayes.templates import make_template

    return make_template(1.0, 0.3, 0.0, "R", n_x=160, n_phi=360)


def baselines(n, uv_max, seed=0):
    rng = np.random.default_rng(seed)
    q = rng.uniform(2e4, uv_max, n)
    t = rng.uniform(0, 2 * np.pi, n)
    return q * np.cos(t), q * np.sin(t)


def test_template_on_quadrature_is_the_templates_own_interpolant(template):
    from spiralbayes.model import template_on_quadrature

    quad = make_quadrature(template, 0.4, 4e6, rule="midpoint")
    assert quad.n_phi % 90 == 0 and quad.x_edges[0] == template.x[0] and quad.x_edges[-1] == template.x[-1]
    xx, pp = np.meshgrid(quad.x, quad.phi, indexing="ij")
    np.testing.assert_allclose(template_on_quadrature(template, quad), template.evaluate(xx, pp, 1.0, 0.0),
                               atol=1e-12)
    cell = np.diff(quad.x_edges).max() * 0.4 * np.pi / 180 / 3600
    assert cell <= 1 / (20 * 4e6) * 1.0001  # no cell wider than 1/(cell_factor u_max)


def test_nufft_matches_direct_sum(template):
    u, v = baselines(200, 2e6)
    geom = DiscGeometry(40.0, 120.0, 0.02, -0.01)
    quad = make_quadrature(template, 0.25, 2e6, cell_factor=3, rule="midpoint")
    fast = perturbation_visibilities(u, v, geom, power_law_profile, template, 0.25, 1.0, quad=quad)
    slow = perturbation_visibilities_dft(u, v, geom, power_law_profile, template, 0.25, 1.0, quad=quad)
    assert np.max(np.abs(fast - slow)) / np.max(np.abs(slow)) < 1e-7


def test_quadrature_matches_converged_image(template):
    """The polar quadrature and a supersampled few-mas image of the same continuous model agree."""
    u, v = baselines(1500, 2e6, seed=1)
    geom = DiscGeometry(35.0, 60.0, 0.01, -0.02)
    r_p, phi_p = 0.25, np.radians(40.0)
    quad_vis = perturbation_visibilities(u, v, geom, power_law_profile, template, r_p, phi_p)
    rel = []
    for pixel in (0.004, 0.002, 0.001):
        n = int(2 * 2.3 * r_p / pixel) + 8
        n += n % 2
        image = render_perturbation_image(power_law_profile, template, r_p, phi_p, geom.inc, (n, n), pixel)
        img_vis = sample_image(image, pixel, u, v, PA=geom.PA, dRA=geom.dRA, dDec=geom.dDec)
        rel.append(np.sqrt(np.mean(np.abs(img_vis - quad_vis) ** 2) / np.mean(np.abs(quad_vis) ** 2)))
    assert rel[2] < rel[0]  # the image converges towards the quadrature
    assert rel[2] < 2e-3


def test_planet_position_lands_where_geometry_says(template):
    """A compact bright spot of a template, placed at (r_p, phi_p), shows up there in the dirty image.

    The spot (a Gaussian of 0.02 r_p at x = 1.2, φ = 30°) replaces the wake so that the brightest
    point of the map is also the brightest after the beam (the wake's own maximum need not be).
    """
    from spiralbayes.templates import SpiralTemplate

    X, P = np.meshgrid(template.x, template.phi, indexing="ij")
    x0, p0 = 1.2, np.radians(30.0)
    d2 = X**2 + x0**2 - 2 * X * x0 * np.cos(P - p0)
    template = SpiralTemplate(x=template.x, phi=template.phi, delta=np.exp(-0.5 * d2 / 0.02**2))
    i, j = np.unravel_index(np.argmax(template.delta), template.delta.shape)
    geom = DiscGeometry(45.0, 30.0, 0.05, 0.02)
    r_p, phi_p = 0.3, np.radians(110.0)
    u, v = baselines(4000, 6e6, seed=2)
    flat = lambda r: np.where(np.asarray(r) < 1.0, 1e10, 0.0)  # noqa: E731
    dV = perturbation_visibilities(u, v, geom, flat, template, r_p, phi_p)
    n, pixel = 400, 0.005
    dirty = dirty_image(u, v, dV, np.ones(u.size), (n, n), pixel)
    iy, ix = np.unravel_index(np.argmax(dirty), dirty.shape)
    l_axis, m_axis = image_axes((n, n), pixel)
    l_exp, m_exp = geom.disc_to_sky(r_p * template.x[i], phi_p + template.phi[j])
    assert np.hypot(l_axis[ix] - l_exp, m_axis[iy] - m_exp) < 0.03  # arcsec, well inside the beam
