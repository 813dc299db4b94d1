"""CASA opens what write_ms writes: tclean, msmetadata/listobs and fixvis on a written set (marker ``casa``).

Run with ``python -m pytest -m casa`` after ``pip install -e ".[test,casa]"``; skipped without CASA.
"""

from __future__ import annotations

import numpy as np
import pytest

from spiralbayes.fourier import dirty_image
from spiralbayes.io import write_ms
from spiralbayes.simulate import observe, uv_coverage
from spiralbayes.units import ARCSEC
from tests._support.casa_support import read_casa_image, require_casa

pytestmark = pytest.mark.casa

EAST = 0.1  # arcsec
FLUX = 0.01  # Jy


@pytest.fixture(scope="module")
def casa():
    return require_casa()


@pytest.fixture(scope="module")
def point_east(tmp_path_factory):
    """A 10 mJy point source 0.1" east with noise, C-4 + C-7, 2 + 4 min: its Measurement Set."""
    cov = uv_coverage(["C-4", "C-7"], -25.0, [(-0.02, 0.02), (-0.035, 0.035)], 30.0, 0.87e-3)
    vis = observe(lambda u, v: FLUX * np.exp(2j * np.pi * u * EAST * ARCSEC), cov, sensitivity=100e-6, seed=4)
    folder = tmp_path_factory.mktemp("casa_ms")
    return vis, write_ms(vis, folder / "point.ms"), folder


def test_tclean_images_the_written_set(casa, point_east, monkeypatch):
    """Dirty image = the package's dirty image; the source lands 0.1" east; sumwt = sum of the weights."""
    casatools, casatasks = casa
    vis, ms, folder = point_east
    monkeypatch.chdir(folder)  # tclean leaves scratch lattices in the working directory
    n, cell = 256, 0.01
    casatasks.tclean(vis=str(ms), imagename=str(folder / "dirty"), imsize=n, cell=f"{cell}arcsec",
                     specmode="mfs", gridder="standard", weighting="natural", niter=0, stokes="I")
    casa_dirty, info = read_casa_image(casatools, folder / "dirty.image")
    assert list(info["refpix"]) == [n // 2, n // 2]
    assert info["increment_rad"][0] == pytest.approx(-cell * ARCSEC)  # RA increases to the left
    ours = dirty_image(vis.u, vis.v, vis.V, vis.weights, (n, n), cell)
    peak = ours.max()
    assert peak == pytest.approx(FLUX, rel=0.05)
    iy, ix = np.unravel_index(np.argmax(casa_dirty), casa_dirty.shape)
    assert (iy, ix) == (n // 2, n // 2 - round(EAST / cell))  # 10 pixels east = left of centre
    inner = slice(n // 4, 3 * n // 4)  # gridding errors grow towards the edge of CASA's image
    assert np.max(np.abs(casa_dirty[inner, inner] - ours[inner, inner])) < 2e-3 * peak
    sumwt, _ = read_casa_image(casatools, folder / "dirty.sumwt")
    assert float(sumwt.ravel()[0]) == pytest.approx(vis.weights.sum(), rel=1e-5)


def test_casa_metadata_tools_accept_the_set(casa, point_east):
    """msmetadata and listobs check that every id in the main table has its subtable row."""
    casatools, casatasks = casa
    vis, ms, _ = point_east
    msmd = casatools.msmetadata()
    msmd.open(str(ms))
    try:
        assert msmd.nantennas() == vis.layout.n_antennas
        assert msmd.observatorynames()[0] == "ALMA"
        n_times = np.unique(np.column_stack([vis.layout.scan, vis.layout.hour_angle]), axis=0).shape[0]
        assert len(msmd.timesforfield(0)) == n_times
        assert msmd.nbaselines() == 2 * 903
    finally:
        msmd.close()
    summary = casatasks.listobs(vis=str(ms), listfile="")
    assert summary["nfields"] == 1 and summary["numrecords"] == vis.n


def test_casa_recomputes_the_stored_uvw(casa, point_east):
    """fixvis recomputes UVW from ANTENNA, TIME and FIELD: it must reproduce what was written."""
    import casacore.tables as tables

    _, casatasks = casa
    vis, ms, folder = point_east
    out = folder / "fixvis.ms"
    casatasks.fixvis(vis=str(ms), outputvis=str(out), reuse=False)
    with tables.table(str(ms), ack=False) as t:
        stored = t.getcol("UVW")
    with tables.table(str(out), ack=False) as t:
        recomputed = t.getcol("UVW")
    length = np.linalg.norm(stored, axis=1)
    # u, v: to 7e-6 here (UT1 - UTC, precession at 2000-01-01); w: CASA points its w axis at the
    # aberrated direction (annual aberration 20.5" = 1e-4 rad), which the package ignores
    assert np.max(np.abs(recomputed[:, :2] - stored[:, :2]) / length[:, None]) < 5e-5
    assert np.max(np.abs(recomputed[:, 2] - stored[:, 2]) / length) < 3e-4
