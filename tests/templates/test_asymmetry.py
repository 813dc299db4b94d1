"""The competing explanations as templates (spiralbayes.templates.asymmetry) against the alternatives' own
fields (spiralbayes.alternatives.fields), an independent implementation of the same models."""

import numpy as np
import pytest

from spiralbayes.alternatives import DiscGrid
from spiralbayes.alternatives.fields import FIELD_MODELS, ProfileContext
from spiralbayes.axisymmetric import AxisymmetricModel
from spiralbayes.exceptions import InputError
from spiralbayes.templates.asymmetry import (ARC_CONTRAST, RING_ECCENTRICITY, RingProfile, arc_template,
                                             asymmetry_kind, asymmetry_templates, perturbation_profile, ring_template)
from spiralbayes.templates.template import template_metadata


def _profile(r):
    r = np.asarray(r, dtype=float)
    return 4e10 * (np.exp(-r / 0.3) + 0.8 * np.exp(-0.5 * ((r - 0.45) / 0.05) ** 2)) * (r < 1.0)


@pytest.fixture(scope="module")
def model():
    return AxisymmetricModel.from_profile(_profile, N=120, Rmax=1.2)


def _on_grid(template, profile, grid, r_c, phi_c):
    """The template's perturbation ``p(r) delta(r / r_c, phi - phi_c)`` on the grid's cells."""
    r, phi = np.meshgrid(grid.r, grid.phi, indexing="ij")
    return profile(grid.r)[:, None] * template.evaluate(r, phi, r_c, phi_c)


def test_an_arc_template_is_the_arc_alternatives_field(model):
    grid = DiscGrid(1.0, 400, 1024)
    ctx = ProfileContext.build(model.brightness, grid)
    r_c, phi_c, width, s_phi, contrast = 0.4, 1.1, 0.06, 20.0, 0.2
    field = FIELD_MODELS["arc"].field([contrast, r_c, phi_c, width * r_c, np.radians(s_phi)], ctx)
    ours = (contrast / ARC_CONTRAST) * _on_grid(arc_template(width, s_phi), model.brightness, grid, r_c, phi_c)
    assert np.abs(ours - field).max() <= 0.01 * np.abs(field).max()


def test_a_ring_template_is_the_eccentric_ring_to_first_order_in_e(model):
    grid = DiscGrid(1.0, 400, 1024)
    ctx = ProfileContext.build(model.brightness, grid)
    r_c, omega, width = 0.45, 2.0, 0.2
    ours = _on_grid(ring_template(width), RingProfile(model).brightness, grid, r_c, omega)
    errors = []
    for e in (0.02, 0.01):
        theta = [e * np.cos(omega), e * np.sin(omega), r_c, width * r_c]
        field = FIELD_MODELS["eccentric_ring"].field(theta, ctx)
        errors.append(np.abs((e / RING_ECCENTRICITY) * ours - field).max() / np.abs(field).max())
    # first order: the relative error halves with e; it is e r_c / (2 l) for a profile varying on l (the
    # ring here is 0.05 arcsec wide at 0.45 arcsec: 0.09 at e = 0.02)
    assert errors[0] < 0.1 and errors[1] < 0.55 * errors[0], errors


def test_the_ring_profile_is_r_times_the_slope(model):
    r = np.linspace(0.05, 0.95, 400)
    fine = np.linspace(0.0, 1.1, 110001)
    slope = np.interp(r, fine, np.gradient(model.brightness(fine), fine))
    np.testing.assert_allclose(RingProfile(model).brightness(r), r * slope, rtol=1e-4,
                               atol=1e-6 * np.abs(r * slope).max())
    assert RingProfile(model).brightness(np.array([1.2, 1.5])).tolist() == [0.0, 0.0]


def test_kinds_metadata_and_profiles(model):
    arcs, rings = asymmetry_templates("arc"), asymmetry_templates("eccentric_ring")
    assert {asymmetry_kind(t) for t in arcs} == {"arc"} and {asymmetry_kind(t) for t in rings} == {"eccentric_ring"}
    meta = template_metadata(arcs[0])
    assert meta["kind"] == "arc" and asymmetry_kind(meta) == "arc" and "sigma_phi_deg" in meta
    assert perturbation_profile(arcs[0], model) == model.brightness
    assert isinstance(perturbation_profile(rings[0], model).__self__, RingProfile)
    # every member's delta has zero mean on each ring (the axisymmetric part is frank's)
    assert max(np.abs(t.delta.mean(axis=1)).max() for t in arcs + rings) < 1e-12
    assert len({t.name for t in arcs + rings}) == len(arcs) + len(rings)


@pytest.mark.parametrize("call, match", [
    (lambda: asymmetry_templates("vortex"), "unknown competing explanation 'vortex'"),
    (lambda: arc_template(0.0, 10.0), "width"),
    (lambda: arc_template(0.05, 120.0), "sigma_phi_deg"),
    (lambda: ring_template(-1.0), "width"),
])
def test_bad_shapes_name_themselves(call, match):
    with pytest.raises(InputError, match=match):
        call()
