"""The continuous template family against the generator's exact templates (family_accuracy.py)."""

import numpy as np
import pytest

from spiralbayes.exceptions import InputError
from spiralbayes.templates.family import H_NODES, TemplateFamily, lagrange_weights, shift_rows
from spiralbayes.templates.variants import variant_template

from .family_accuracy import loss, table


@pytest.mark.parametrize("value", [0.05, 0.3, 1.7, 2.99, 4.0])
def test_lagrange_weights_reproduce_a_cubic_exactly(value):
    nodes = np.array([0.0, 0.4, 1.1, 1.5, 2.6, 3.0, 4.0])
    idx, w = lagrange_weights(nodes, value)
    cubic = lambda x: 2 - x + 0.5 * x**2 - 0.3 * x**3  # noqa: E731
    assert len(idx) == 4 and nodes[idx[0]] <= value <= nodes[idx[-1]]
    assert np.sum(w * cubic(nodes[idx])) == pytest.approx(cubic(value), abs=1e-12)


def test_shift_rows_is_a_rotation_by_whole_pixels():
    rng = np.random.default_rng(1)
    delta = rng.normal(size=(3, 64))
    step = 2 * np.pi / 64
    out = shift_rows(delta, np.array([0.0, 3 * step, -5 * step]))
    np.testing.assert_allclose(out[0], delta[0], atol=1e-12)
    np.testing.assert_allclose(out[1], np.roll(delta[1], 3), atol=1e-12)
    np.testing.assert_allclose(out[2], np.roll(delta[2], -5), atol=1e-12)


def test_at_a_node_is_the_generator_template_and_hand_l_is_the_mirror():
    fam = TemplateFamily.build(0.3, 0.0, "compromise", masses=[0.3, 1.0])
    exact = variant_template(1.0, 0.3, 0.0, "R", "compromise")
    np.testing.assert_allclose(fam.at(1.0).delta, exact.delta, atol=1e-7)
    left = TemplateFamily.build(0.3, 0.0, "compromise", "L", masses=[0.3, 1.0]).at(0.5)
    np.testing.assert_allclose(left.delta, fam.at(0.5).mirror().delta, atol=1e-12)
    assert (left.hand, left.mass, left.name) == ("L", 0.5, "wake_m0.5_tau0.3_b0_h0.07_L")


def test_out_of_range_and_missing_h_p_are_clear_errors():
    fam = TemplateFamily.build(3.0, 0.0, masses=[0.3, 1.0])
    with pytest.raises(InputError, match=r"outside the family's range \[0.3, 1\]"):
        fam.at(2.0)
    spanning = TemplateFamily.build(3.0, 0.0, masses=[0.3, 1.0], h_p=(0.05, 0.07))
    with pytest.raises(InputError, match="give h_p="):
        spanning.at(0.5)
    with pytest.raises(InputError, match="H/r range"):
        spanning.at(0.5, 0.09)


@pytest.mark.parametrize(("mass", "h_p"), [(0.5, None), (2.0, None), (1.0, 0.06), (2.0, 0.08)])
def test_interpolated_template_costs_less_chi2_than_the_scan_tolerance(mass, h_p):
    """Fiducial observation, τ0 3 (the brightest spirals): the χ² lost by the family's template
    against the generator's exact one stays below the scan's accuracy tolerance."""
    fam = TemplateFamily.build(3.0, 0.0, "compromise", h_p=0.07 if h_p is None else H_NODES)
    row = loss(fam, mass, h_p)
    assert row["own"] > 10  # the comparison means something: the planet is seen
    assert row["loss"] < row["tolerance"], row


def test_plain_average_over_aspect_ratio_would_not_do():
    """Why the arms are aligned first: averaging the bank's H/r 0.05 and 0.07 maps at 0.06 loses
    a large part of the spiral (the two maps' arms sit at different azimuths)."""
    from .family_accuracy import _dv, _observation

    exact = variant_template(1.0, 3.0, 0.0, "R", h_p=0.06)
    a, b = (variant_template(1.0, 3.0, 0.0, "R", h_p=h) for h in (0.05, 0.07))
    plain = exact.__class__(exact.x, exact.phi, 0.5 * (a.delta + b.delta))
    w = _observation()[2]
    e = _dv(exact, 3.0)
    own, lost = np.sum(w * np.abs(e) ** 2), np.sum(w * np.abs(e - _dv(plain, 3.0)) ** 2)
    aligned = loss(TemplateFamily.build(3.0, 0.0, h_p=(0.05, 0.07), masses=[0.3, 1.0, 3.0]), 1.0, 0.06)["loss"]
    assert lost > 0.2 * own and aligned < 0.01 * lost


@pytest.mark.slow
def test_whole_grid_below_the_scan_tolerance():
    """Every (variant, τ0, β) family of the bank at 0.2, 0.5, 2 M_th and H/r 0.06, 0.07, 0.08."""
    rows = table()
    assert len(rows) == 3 * 4 * 2 * 12
    bad = [r for r in rows if not r["loss"] < r["tolerance"]]
    assert not bad, bad
