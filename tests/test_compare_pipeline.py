"""`spiralbayes compare` on the demo's observation (marker ``casa``; a few minutes).

The paper's qualitative result for a 1 M_th, tau0 = 3, beta = 10 planet in the fiducial set-up:
the visibility scan detects it. With the package's templates the CLEAN residual image shows the
spiral too (its peak lies on the planet), and the azimuthally averaged CLEAN profile has no gap,
because the model disc's spiral has zero azimuthal mean (no gap was put in).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from spiralbayes.io import save_visibilities
from spiralbayes.simulate import DiscModel, simulate_observation
from tests._support.casa_support import require_casa
from tests._support.helpers import DISTANCE, GEOMETRY, R_P_TRUE

pytestmark = pytest.mark.casa


def test_compare_command_on_the_demo_observation(planet_templates, tmp_path, monkeypatch):
    require_casa()
    from spiralbayes.cli import main

    disc = DiscModel(distance=DISTANCE, r_ref=50.0, tau_ref=3.0)
    vis = simulate_observation("fiducial", disc, GEOMETRY, planet_templates[0], r_p=R_P_TRUE, phi_p=0.0, seed=1)
    save_visibilities(vis, tmp_path / "demo.h5")
    (tmp_path / "compare.toml").write_text(
        '[data]\npath = "demo.h5"\n[geometry]\ninc = 30.0\nPA = 60.0\ndistance = 140.0\n'
        "[templates]\nmass = [1.0]\ntau0 = [3.0]\nbeta = [10.0]\n"
        "[grid]\nn_r_p = 13\nn_phi_p = 46\n[output]\ndir = \"out\"\n")
    monkeypatch.chdir(tmp_path)
    assert main(["-q", "compare", "compare.toml"]) == 0
    out = tmp_path / "out"
    record = json.loads((out / "compare_verdicts.json").read_text())
    verdicts = {row["method"].split(" (")[0]: row["verdict"] for row in record["table"]}
    assert verdicts["visibility scan"] == "detected"
    assert verdicts["CLEAN residuals"] == "detected"
    assert verdicts["gap depth"] == "none"
    peak = record["residual_detection"]
    assert peak["peak_r"] == pytest.approx(R_P_TRUE, abs=0.08)  # the residual peak sits on the planet
    assert abs((peak["peak_phi_deg"] + 180.0) % 360.0 - 180.0) < 30.0
    assert (out / "compare.png").stat().st_size > 10_000 and (out / "compare_verdicts.txt").exists()
    assert (out / "casa" / "data.image").exists()
    assert np.isfinite(record["timings"]["clean_s"])
