import pytest

from spiralbayes.simulate import uv_coverage

LAM = 0.87e-3


@pytest.fixture(scope="package")
def short_cov():
    """C-4 + C-7, a few minutes each: fast, but with the fiducial's baseline range."""
    return uv_coverage(["C-4", "C-7"], -25.0, [(-0.05, 0.05), (-0.1, 0.1)], 30.0, LAM)
