"""Synthetic observations: uv geometry, noise level, model transforms, planted perturbations, presets."""

import json

import numpy as np
import pytest

from spiralbayes.geometry import DiscGeometry
from spiralbayes.simulate import (
    PRESETS,
    DiscModel,
    image_noise,
    preset_table,
    simulate_observation,
)
from spiralbayes.visibilities import Visibilities


class BlobTemplate:
    """A stand-in for a spiral template: a Gaussian bump at the planet in the disc plane."""

    name = "blob"

    def __init__(self, amplitude=5.0, width=0.01):
        self.amplitude, self.width = amplitude, width

    def evaluate(self, r, phi, r_p, phi_p):
        dx = r * np.cos(phi) - r_p * np.cos(phi_p)
        dy = r * np.sin(phi) - r_p * np.sin(phi_p)
        return self.amplitude * np.exp(-0.5 * (dx**2 + dy**2) / self.width**2)


# --- presets ----------------------------------------------------------------------------------------
def test_presets_sizes_close_to_paper():
    rows = preset_table(measure=False)
    assert [r["name"] for r in rows] == ["fiducial", "high_sensitivity", "low_sensitivity",
                                         "high_resolution", "taurus"]
    for row in rows:
        assert abs(row["6lnN"] - row["paper_6lnN"]) < 1.0, row
        # 60-s integrations: the coverage holds the stated time on source
        assert row["time_on_source_min"] == pytest.approx(row["paper_time_on_source_min"], abs=1e-6), row
        # the radiometer equation (effective T_sys) agrees with the requested noise for that time
        assert row["radiometer_noise"] == pytest.approx(row["sensitivity"], rel=0.05), row


def test_presets_state_the_papers_times_on_source():
    """Table 1: 40 min fiducial, 8 h high sensitivity (a time forecast scales with these)."""
    times = {name: p.total_time_on_source for name, p in PRESETS.items()}
    assert times["fiducial"] == 40.0 and times["high_sensitivity"] == 480.0
    assert times["low_sensitivity"] == 20.0 and times["high_resolution"] == 40.0
    assert all(p.integration_time == 60.0 for p in PRESETS.values())
    # the image noise scales as t^-1/2 between the three C-4 + C-7 sets, as Table 1's does
    fid, high = PRESETS["fiducial"], PRESETS["high_sensitivity"]
    assert fid.sensitivity * np.sqrt(fid.total_time_on_source / high.total_time_on_source) == \
        pytest.approx(high.sensitivity, rel=0.02)


def test_simulate_observation_preset_end_to_end():
    vis = simulate_observation("taurus", DiscModel(flux=0.1), DiscGeometry(35, 120), BlobTemplate(),
                               r_p=0.4, phi_p=1.0, seed=2)
    assert isinstance(vis, Visibilities) and vis.n == PRESETS["taurus"].coverage().n
    assert vis.wavelength == pytest.approx(1.33e-3)
    prov = vis.provenance
    assert prov["preset"]["name"] == "taurus" and prov["seed"] == 2
    assert prov["model"]["perturbation"] == "blob" and prov["model"]["r_p_arcsec"] == 0.4
    json.dumps(prov)  # plain types: every writer can store it
    assert image_noise(vis.weights) == pytest.approx(50e-6)
    again = simulate_observation("taurus", DiscModel(flux=0.1), DiscGeometry(35, 120), BlobTemplate(),
                                 r_p=0.4, phi_p=1.0, seed=2)
    np.testing.assert_array_equal(vis.V, again.V)


# --- errors -----------------------------------------------------------------------------------------
def test_unknown_preset():
    with pytest.raises(ValueError, match="unknown preset 'fidu'.*fiducial.*taurus"):
        simulate_observation("fidu")
