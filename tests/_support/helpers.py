"""Constants shared by the test modules (the fixtures built from them live in conftest.py)."""

from pathlib import Path

import numpy as np

from spiralbayes import DiscGeometry

GEOMETRY = DiscGeometry(30.0, 60.0)
DISTANCE = 140.0
R_P_TRUE = 50.0 / DISTANCE  # 50 au at 140 pc
SCAN_RP = np.linspace(0.02, 0.5, 25)  # the paper's 25 radii
DATA = Path(__file__).parents[1] / "data"
"""Small real data files (AS 209 sample; see data/README.md)."""
