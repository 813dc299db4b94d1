"""Template families: which templates a mass limit treats as one morphology at several masses."""

import dataclasses

import numpy as np
import pytest

from spiralbayes.exceptions import InputError
from spiralbayes.inference.limits.families import SIMULATION_VARIANT, template_families
from spiralbayes.templates.template import SpiralTemplate, template_metadata


def _template(mass, hand="R", name=None, generator=True, beta=0.0, variant=None):
    phi = 2 * np.pi * (np.arange(8) + 0.5) / 8
    provenance = {"generator": "spiralbayes.templates.generator"} if generator else {"reader": "fargo3d"}
    if variant is not None:
        provenance["variant"] = variant
    return SpiralTemplate(np.array([0.5, 1.0, 2.0]), phi, np.zeros((3, 8)), mass=mass, tau0=3.0, beta=beta,
                          h_p=0.07, hand=hand, name=name or f"{'gen' if generator else 'map'}_{mass:g}_{hand}",
                          provenance=provenance)


def _bank():
    return [_template(m, h) for m in (0.3, 1.0, 3.0) for h in "RL"]


def test_simulated_maps_form_their_own_family_beside_the_generator():
    maps = [_template(1.0, h, generator=False) for h in "RL"] + [_template(2.0, "R", generator=False)]
    families = template_families([template_metadata(t) for t in _bank() + maps])
    assert [f.key.get("variant") for f in families] == [None, SIMULATION_VARIANT]
    generator, simulation = families
    # the generator family keeps its three masses and its templates; a 2 M_th map does not enter it
    assert generator.masses == [0.3, 1.0, 3.0]
    assert generator.members == {"R": [0, 2, 4], "L": [1, 3, 5]}
    assert simulation.masses == [1.0, 2.0]
    assert simulation.members == {"R": [6, 8], "L": [7, None]}
    assert "variant=simulation" in simulation.label


def test_maps_with_an_unknown_cooling_time_stay_out_of_the_limits():
    maps = [_template(1.0, h, generator=False, beta=float("nan")) for h in "RL"]
    families = template_families([template_metadata(t) for t in _bank() + maps])
    assert len(families) == 1 and families[0].key.get("variant") is None


def test_two_maps_for_one_mass_and_hand_are_an_error_that_names_both_and_the_fix():
    maps = [_template(1.0, "R", name="run_nu1e-4", generator=False),
            _template(1.0, "R", name="run_nu1e-5", generator=False)]
    with pytest.raises(InputError, match=r"'run_nu1e-4' and 'run_nu1e-5'.*1 M_th, hand R.*variant"):
        template_families([template_metadata(t) for t in _bank() + maps])


def test_variant_names_keep_two_simulation_sets_apart():
    maps = [_template(1.0, "R", name=f"run_{v}", generator=False, variant=v) for v in ("nu1e-4", "nu1e-5")]
    families = template_families([template_metadata(t) for t in _bank() + maps])
    assert sorted(str(f.key.get("variant")) for f in families) == ["None", "nu1e-4", "nu1e-5"]


def test_a_generator_template_repeated_under_another_name_is_an_error():
    twin = dataclasses.replace(_bank()[2], name="gen_1_R_copy")
    with pytest.raises(InputError, match="gen_1_R_copy"):
        template_families([template_metadata(t) for t in _bank() + [twin]])
