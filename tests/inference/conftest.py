import pytest


@pytest.fixture(scope="package")
def small_bank():
    """Two masses at tau0 = 3, beta = 10, both hands, on a coarse grid (fast to scan)."""
    from spiralbayes.templates import make_template

    out = []
    for mass in (0.3, 3.0):
        right = make_template(mass, 3.0, 10.0, "R", n_x=160, n_phi=360)
        out += [right, right.mirror()]
    return out
