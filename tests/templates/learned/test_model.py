"""The learned template model: reproduces its training runs, keeps to its box, saves and loads, and —
held out one run at a time (slow) — recovers the held-out run's own Δχ² at the truth.

The model is fitted once per test process on the committed reference files (``common.FILES``); the
full leave-one-run-out table is ``tools/learned_model_loro.py`` (docs/templates.md).
"""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from spiralbayes.exceptions import DataFileError, InputError
from spiralbayes.templates.learned import LEARNED_KIND, LearnedTemplateModel
from spiralbayes.templates.template import metadata_variant, template_kind, template_metadata

from .. import fidelity as F
from .common import reference, run_named


@pytest.mark.parametrize("name", ["library:h0.07_mu1", "continuum:h0.10_mu0.72_slope0.85_alpha3.2e-03"])
def test_model_reproduces_a_training_run_at_its_parameters(model, runs, name):
    """Not held out, the model returns the run's own map: the beam-smoothed δ correlates at ≥ 0.97
    and recovers ≥ 0.9 of its power (uniform uv weights, fidelity.beam_metrics), at τ0 0.3 and 3."""
    run = run_named(runs, name)
    for tau0 in (0.3, 3.0):
        t = model.predict(**run.parameters, tau0=tau0)
        m = F.beam_metrics(reference(run, tau0), t)
        assert m["beam_ncc"] > 0.97, (tau0, m)
        assert m["beam_recovery"] > 0.9, (tau0, m)


def test_predicted_surface_density_is_the_runs(model, runs):
    run = run_named(runs, "physics:h0.07_mu1_slope1.5")
    dsigma, gap = model.predict_dsigma(**run.parameters)
    rows = np.searchsorted(run.x, model.x[0]) + np.arange(model.x.size)
    truth = run.dsigma[rows]
    w = model.weight[:, None] ** 2
    ncc = np.sum(w * dsigma * truth) / np.sqrt(np.sum(w * dsigma**2) * np.sum(w * truth**2))
    assert ncc > 0.95
    np.testing.assert_allclose(dsigma.mean(axis=1), 0.0, atol=1e-12)  # δΣ/Σ has no axisymmetric part
    np.testing.assert_allclose(gap, run.gap[rows], rtol=0.05)


def test_template_metadata_hand_and_uncertainty(model):
    point = {"mass": 0.5, "h_p": 0.06, "slope": 1.0, "alpha": 2e-3, "orbits": 20.0}
    right = model.predict(**point, tau0=3.0)
    left = model.predict(**point, tau0=3.0, hand="L")
    assert right.name == "learned_m0.5_tau3_b0_h0.06_p1_a0.002_o20_R" and left.name.endswith("_L")
    np.testing.assert_allclose(left.delta, right.mirror().delta)
    assert (right.mass, right.tau0, right.beta, right.h_p, right.flaring) == (0.5, 3.0, 0.0, 0.06, 0.25)
    meta = template_metadata(right)
    assert template_kind(right) == "simulation" and metadata_variant(meta) == "learned_p1_a0.002_o20"
    assert right.provenance["learned"]["point"] == point and right.provenance["learned"]["inside_box"]
    unc = model.predict_uncertainty(**point, tau0=3.0)
    assert unc.dsigma_std.shape == unc.delta_std.shape == right.delta.shape
    assert np.all(unc.dsigma_std >= 0) and 0 < unc.relative_error < 1
    assert 0 < right.provenance["learned"]["dsigma_relative_error"] < 1
    assert unc.expected_recovery == pytest.approx(1 - unc.relative_error**2)
    # far outside the training runs the model knows less
    far = model.predict_uncertainty(**{**point, "orbits": 3000.0}, tau0=3.0, extrapolate=True)
    assert far.relative_error > unc.relative_error


@pytest.mark.parametrize(("field", "value", "message"), [
    ("mass", 5.0, r"mass = 5 outside \[0.1, 3\]"),
    ("h_p", 0.2, r"h_p = 0.2 outside \[0.04, 0.12\]"),
    ("alpha", 1.0, r"alpha = 1 outside"),
    ("orbits", 5.0, r"orbits = 5 outside \[20, 1000\]"),
])
def test_outside_the_trained_box_is_a_clear_error(model, field, value, message):
    point = {"mass": 1.0, "h_p": 0.07, "slope": 1.0, "alpha": 2e-3, "orbits": 20.0, field: value}
    with pytest.raises(InputError, match=message + r".*extrapolate=True"):
        model.predict(**point, tau0=0.3)
    t = model.predict(**point, tau0=0.3, extrapolate=True)
    assert not t.provenance["learned"]["inside_box"]
    with pytest.raises(InputError, match="must be positive"):
        model.predict(**{**point, "mass": -1.0}, tau0=0.3)


def test_save_and_load_give_the_same_templates(model, tmp_path):
    path = model.save(tmp_path / "learned.h5")
    back = LearnedTemplateModel.load(path)
    assert back.run_names == model.run_names and back.options == model.options
    np.testing.assert_allclose(np.array(back.box), np.array(model.box))
    point = {"mass": 2.0, "h_p": 0.08, "slope": 0.8, "alpha": 1e-3, "orbits": 20.0}
    a, b = model.predict(**point, tau0=0.3), back.predict(**point, tau0=0.3)
    np.testing.assert_allclose(b.delta, a.delta, atol=2e-5)
    ua, ub = model.predict_uncertainty(**point), back.predict_uncertainty(**point)
    assert ub.relative_error == pytest.approx(ua.relative_error, rel=1e-4)
    assert model.summary() in repr(back) and "\n" not in repr(back)
    (tmp_path / "bad.h5").write_bytes(b"not hdf5")
    with pytest.raises(DataFileError, match="bad.h5"):
        LearnedTemplateModel.load(tmp_path / "bad.h5")
    # a file of other inputs is refused, naming the file
    other = tmp_path / "other.h5"
    model.save(other)
    with h5py.File(other, "a") as f:
        assert f.attrs["kind"] == LEARNED_KIND
        f.attrs["parameters"] = '["ln_mass", "h_p"]'
    with pytest.raises(DataFileError, match=r"other\.h5.*refit"):
        LearnedTemplateModel.load(other)


def test_too_few_runs_is_a_clear_error(runs):
    with pytest.raises(InputError, match="at least 4 training runs"):
        LearnedTemplateModel.fit(runs[:2])


HELD_OUT = ["physics:h0.07_mu1_slope1.5", "physics:h0.06_mu0.5", "continuum:h0.08_mu1_slope1.35_alpha3.2e-04"]


@pytest.mark.slow
@pytest.mark.parametrize("name", HELD_OUT)
def test_held_out_run_recovers_its_own_delta_chi2(runs, name):
    """Leave one run out: refitted without it, the model's template at the run's parameters recovers
    ≥ 0.8 of the run's own Δχ² at the truth (fiducial planting, noise-free, τ0 0.3 and 3). A run on
    the box's face may lie just outside the others' box; it is predicted with ``extrapolate=True``, as
    ``tools/learned_model_loro.py`` predicts every run."""
    from .. import variant_fit as V

    run = run_named(runs, name)
    held = LearnedTemplateModel.fit([r for r in runs if r is not run])
    for tau0 in (0.3, 3.0):
        ref = reference(run, tau0)
        cross, power = V.truth_products(ref, [held.predict(**run.parameters, tau0=tau0, extrapolate=True)], tau0)
        recovery = (2 * cross[1] - power[1]) / power[0]
        assert recovery > 0.8, (tau0, recovery)
