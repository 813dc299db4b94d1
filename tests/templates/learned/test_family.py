"""One disc of the learned model as a template family: the planet mass continuous, for the posterior."""

from __future__ import annotations

import numpy as np
import pytest

from spiralbayes.exceptions import InputError
from spiralbayes.templates.learned import learned_bank, learned_family

DISC = {"h_p": 0.07, "slope": 1.0, "alpha": 2e-3, "orbits": 20.0}


def _rel(a, b) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2) / np.mean(b**2)))


def test_family_nodes_are_the_models_predictions_and_between_them_its_interpolation(model):
    """The nodes are model.predict at the family's masses; between nodes the Lagrange-4 template stays
    within 1 % (RMS) of the model's own prediction there, over the whole mass range and both hands."""
    family = learned_family(model, **DISC, tau0=3.0, mass_range=(0.1, 3.0), n_masses=25)
    assert family.variant == "learned_p1_a0.002_o20" and family.beta == 0.0
    for j in (0, 12, 24):
        node = family.node(j)
        exact = model.predict(float(family.masses[j]), tau0=3.0, **DISC)
        np.testing.assert_array_equal(node.delta, exact.delta)
    worst = 0.0
    for mass in np.geomspace(0.11, 2.9, 9):
        for hand in ("R", "L"):
            fam = family if hand == "R" else learned_family(model, **DISC, tau0=3.0, hand="L", n_masses=25)
            worst = max(worst, _rel(fam.at(mass).delta, model.predict(mass, tau0=3.0, hand=hand, **DISC).delta))
    assert worst < 0.01, worst


def test_family_range_is_checked_against_the_training_box(model):
    with pytest.raises(InputError, match="mass = 5 outside"):
        learned_family(model, **DISC, tau0=3.0, mass_range=(0.1, 5.0))
    with pytest.raises(InputError, match="n_masses"):
        learned_family(model, **DISC, tau0=3.0, n_masses=1)


def test_posterior_families_of_a_learned_bank_come_from_its_model_file(model, runs, tmp_path):
    """family_of: a learned template naming its model file gets its disc's family (each disc, τ0 and hand
    one group); one that names no file, or a file whose model does not predict it, is refused."""
    from spiralbayes.inference.posterior.mass import MassPrior, family_of, group_families

    path = model.save(tmp_path / "model.h5")
    bank = learned_bank(model, masses=(0.3, 1.0), h_ps=0.07, slopes=(0.8, 1.2), alphas=2e-3, orbits=20.0, tau0s=3.0,
                        cache_dir=tmp_path)
    with pytest.raises(InputError, match="does not name"):
        family_of(bank[0])
    for t in bank:
        t.provenance["learned"]["model_file"] = str(path)
    groups = group_families(list(bank), MassPrior(mass_range=(0.1, 3.0)))
    assert len(groups) == 2 * 2  # two slopes x two hands
    for family, members in groups:
        point = members[0].provenance["learned"]["point"]
        assert family.variant == f"learned_p{point['slope']:g}_a0.002_o20" and family.hand == members[0].hand
        assert {m.hand for m in members} == {family.hand} and len(members) == 2
        at = family.at(1.0)
        direct = model.predict(1.0, tau0=3.0, hand=family.hand, **{**DISC, "slope": point["slope"]})
        assert _rel(at.delta, direct.delta) < 0.01

    other = type(model).fit(runs, restarts=0, n_components=4)
    other.save(tmp_path / "other.h5")
    t = bank[0]
    t.provenance["learned"]["model_file"] = str(tmp_path / "other.h5")
    with pytest.raises(InputError, match="does not predict it"):
        family_of(t)

