"""Shared by the tests marked ``casa``: skip cleanly without CASA, run CASA tasks in a scratch folder.

Install and run them with ``pip install -e ".[test,casa]" && python -m pytest -m casa``.
"""

import pytest

from spiralbayes._casa import casa_available, import_casa


def require_casa():
    """``(casatools, casatasks)``, or skip the test when CASA is not installed."""
    if not casa_available():
        pytest.skip('CASA is not installed (pip install -e ".[test,casa]")')
    return import_casa()


def read_casa_image(casatools, path):
    """A CASA image as ``array[iy north, ix west]`` (the package's orientation), with its header."""
    ia = casatools.image()
    ia.open(str(path))
    try:
        pixels = ia.getchunk()[:, :, 0, 0].T.astype(float)
        cs = ia.coordsys()
        info = {"refpix": cs.referencepixel()["numeric"][:2], "increment_rad": cs.increment()["numeric"][:2],
                "beam": ia.restoringbeam()}
        cs.done()
    finally:
        ia.close()
    return pixels, info
