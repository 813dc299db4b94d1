"""The Measurement Set writer: structure CASA needs, UVW sign and times, checked with python-casacore.

The CASA round trips (tclean, listobs, msmetadata, fixvis) are in ``test_ms_casa.py`` (marker ``casa``).
"""

from __future__ import annotations

import numpy as np
import pytest

tables = pytest.importorskip("casacore.tables")

from spiralbayes.io import read_ms, write_ms  # noqa: E402
from spiralbayes.io.ms_writer import (  # noqa: E402
    ALMA_LONGITUDE,
    enu_to_itrf,
    itrf_to_enu,
    transit_time,
)
from spiralbayes.simulate import baseline_uvw, observe, uv_coverage  # noqa: E402
from spiralbayes.units import ARCSEC  # noqa: E402
from spiralbayes.visibilities import Visibilities  # noqa: E402

LAT = -23.0234


@pytest.fixture(scope="module")
def observed():
    """Two configurations, a few integrations each, a point source 0.1" east plus noise."""
    cov = uv_coverage(["C-4", "C-7"], -25.0, [(-0.02, 0.02), (-0.03, 0.03)], 30.0, 0.87e-3)
    model = lambda u, v: 0.01 * np.exp(2j * np.pi * u * 0.1 * ARCSEC)  # noqa: E731
    return cov, observe(model, cov, sensitivity=35e-6, seed=1)


@pytest.fixture(scope="module")
def written(observed, tmp_path_factory):
    return write_ms(observed[1], tmp_path_factory.mktemp("ms") / "obs.ms")


def _col(path, name, sub=None):
    with tables.table(str(path) + (f"/{sub}" if sub else ""), ack=False) as t:
        return t.getcol(name)


def test_simulated_observations_carry_their_antennas(observed):
    cov, vis = observed
    lay = vis.layout
    assert lay is not None and lay.n == vis.n and lay.n_antennas == 86
    # each row's baseline is positions[antenna2] - positions[antenna1], projected at its hour angle
    uvw = baseline_uvw(lay.positions[lay.antenna2] - lay.positions[lay.antenna1], lay.hour_angle, -25.0)
    np.testing.assert_allclose(uvw[:, 0] / 0.87e-3, vis.u, rtol=1e-12, atol=1e-6)
    np.testing.assert_allclose(uvw[:, 2] / 0.87e-3, lay.w, rtol=1e-12, atol=1e-6)
    sub = vis.subset(np.arange(0, vis.n, 7))
    assert sub.layout.n == sub.n and np.array_equal(sub.layout.antenna1, lay.antenna1[::7])


def test_subtables_casa_needs(written, observed):
    vis = observed[1]
    assert _col(written, "MEAS_FREQ_REF", "SPECTRAL_WINDOW")[0] == 5  # TOPO, not REST
    assert list(_col(written, "TELESCOPE_NAME", "OBSERVATION")) == ["ALMA"]
    n_ant = vis.layout.n_antennas
    assert len(_col(written, "NAME", "ANTENNA")) == n_ant
    pol_types = _col(written, "POLARIZATION_TYPE", "FEED")  # string arrays come back as a dict
    assert list(pol_types["shape"]) == [n_ant, 2] and pol_types["array"] == ["X", "Y"] * n_ant
    a1, a2 = _col(written, "ANTENNA1"), _col(written, "ANTENNA2")
    assert np.all(a1 < a2) and a2.max() < n_ant
    assert set(_col(written, "STATE_ID")) == {-1} and set(_col(written, "PROCESSOR_ID")) == {-1}
    assert set(_col(written, "SCAN_NUMBER")) == {1, 2}
    w, s = _col(written, "WEIGHT").astype(float), _col(written, "SIGMA").astype(float)
    np.testing.assert_allclose(w * s**2, 1.0, rtol=1e-6)
    np.testing.assert_allclose(w.sum(axis=1), vis.weights, rtol=1e-6)  # Stokes I weight = sum of the hands


def test_one_time_stamp_per_integration(written, observed):
    cov = observed[0]
    times = _col(written, "TIME")
    n_integrations = np.unique(np.column_stack([cov.configuration, cov.hour_angle]), axis=0).shape[0]
    assert np.unique(times).size == n_integrations
    np.testing.assert_array_equal(np.unique(_col(written, "INTERVAL")), [30.0])
    t_range = _col(written, "TIME_RANGE", "OBSERVATION")[0]
    assert t_range[0] == pytest.approx(times.min() - 15.0) and t_range[1] == pytest.approx(times.max() + 15.0)


def test_uvw_follow_from_antennas_times_and_field(written):
    """Recompute UVW as CASA defines them, uvw(ANTENNA1) - uvw(ANTENNA2), with astropy's sidereal time."""
    from astropy import units as u
    from astropy.time import Time
    from astropy.utils import iers

    iers.conf.auto_download = False
    uvw, a1, a2, times = (_col(written, c) for c in ("UVW", "ANTENNA1", "ANTENNA2", "TIME"))
    ra, dec = np.degrees(_col(written, "PHASE_DIR", "FIELD")[0, 0])
    enu = itrf_to_enu(_col(written, "POSITION", "ANTENNA"), LAT)
    lst = Time(times / 86400.0, format="mjd", scale="utc").sidereal_time("mean", longitude=ALMA_LONGITUDE * u.deg)
    hour_angle = ((lst.deg - ra + 180.0) % 360.0 - 180.0) / 15.0
    expected = baseline_uvw(enu[a1] - enu[a2], hour_angle, dec, LAT)
    err = np.linalg.norm(uvw - expected, axis=1) / np.linalg.norm(expected, axis=1)
    assert err.max() < 1e-4  # UT1 - UTC = 0.36 s at J2000.0 is 2.6e-5 rad of Earth rotation
    # the site conversion itself is exact: ENU -> ITRF -> ENU
    pos = np.random.default_rng(0).normal(scale=1e3, size=(5, 3))
    np.testing.assert_allclose(itrf_to_enu(enu_to_itrf(pos, LAT), LAT), pos, atol=1e-8)
    assert np.linalg.norm(enu_to_itrf(np.zeros((1, 3)), LAT)) == pytest.approx(6.375e6, rel=1e-3)


def test_transit_time_is_when_the_hour_angle_is_zero():
    from astropy import units as u
    from astropy.time import Time
    from astropy.utils import iers

    iers.conf.auto_download = False
    t = transit_time(240.0, "2000-01-01")
    lst = Time(t / 86400.0, format="mjd", scale="utc").sidereal_time("mean", longitude=ALMA_LONGITUDE * u.deg).deg
    assert abs((lst - 240.0 + 180.0) % 360.0 - 180.0) < 0.01  # 2.4 s of time (UT1 - UTC, rounding)
    assert 0.0 <= t / 86400.0 - 51544.0 < 1.0


def test_read_back_is_the_same_measurement(written, observed):
    """Rows are stored as (-u, -v, conj V): Hermitian-equivalent to what was written."""
    vis = observed[1]
    back = read_ms(written)
    np.testing.assert_allclose(back.u, -vis.u, rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(back.v, -vis.v, rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(back.V, np.conj(vis.V), rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(back.weights, vis.weights, rtol=1e-6)
    # the point source still sits 0.1" east in the stored convention: V = F exp(+2 pi i u l)
    model = 0.01 * np.exp(2j * np.pi * back.u * 0.1 * ARCSEC)
    assert np.sqrt(np.mean(np.abs(back.V - model) ** 2)) < 3 * vis.sigma[0]


def test_generic_layout_without_antennas(tmp_path):
    rng = np.random.default_rng(3)
    n = 2500
    vis = Visibilities(rng.uniform(-1e6, 1e6, n), rng.uniform(-1e6, 1e6, n), rng.normal(size=n) + 0j,
                       rng.uniform(1, 2, n), wavelength=1.3e-3)
    path = write_ms(vis, tmp_path / "g.ms", rows_per_time=1000)
    assert np.unique(_col(path, "TIME")).size == 3
    a1, a2 = _col(path, "ANTENNA1"), _col(path, "ANTENNA2")
    n_ant = len(_col(path, "NAME", "ANTENNA"))
    assert n_ant == 46 and np.all(a1 < a2) and a2.max() < n_ant  # 46 * 45 / 2 = 1035 >= 1000 baselines
    assert len(_col(path, "ANTENNA_ID", "FEED")) == n_ant
    back = read_ms(path)
    np.testing.assert_allclose(back.u, vis.u, rtol=1e-12)  # no flip without a layout
    np.testing.assert_allclose(back.V, vis.V, rtol=1e-6, atol=1e-7)


def test_antennas_and_times_read_back_in_the_package_convention(written, observed):
    """read_ms gives antenna1 = ANTENNA2, antenna2 = ANTENNA1: the baseline stays position[a2] - position[a1]."""
    vis = observed[1]
    back = read_ms(written)
    lay = vis.layout
    pos = lay.positions
    uvw = baseline_uvw(pos[back.antenna2] - pos[back.antenna1], lay.hour_angle, -25.0) / 0.87e-3
    np.testing.assert_allclose(uvw[:, 0], back.u, rtol=1e-9, atol=1e-3)
    np.testing.assert_allclose(uvw[:, 1], back.v, rtol=1e-9, atol=1e-3)
    # TIME [MJD s] differs from the simulation's time [s from the start] by one offset
    offset = back.time - vis.time
    assert np.ptp(offset) < 1e-3 and offset[0] > 4e9


def test_gain_errors_written_obey_casas_measurement_equation(tmp_path):
    """A point source at the phase centre corrupted in the package reads back as g_ANT1 conj(g_ANT2)."""
    from spiralbayes.simulate import GainErrors

    cov = uv_coverage("C-4", -25.0, (-0.02, 0.02), 30.0, 0.87e-3)
    gains = GainErrors(20.0, 0.05, coherence_s=60.0, seed=3)
    vis = observe(np.ones(cov.n), cov, sigma=1.0, add_noise=False, gains=gains)
    path = write_ms(vis, tmp_path / "g.ms")
    ant1, ant2 = _col(path, "ANTENNA1"), _col(path, "ANTENNA2")
    data = _col(path, "DATA")[:, 0, 0]
    g_a1, g_a2 = gains.gains(ant1, ant2, vis.time)  # same rows, same times
    np.testing.assert_allclose(data, g_a1 * np.conj(g_a2), rtol=1e-6, atol=1e-6)


def test_recorded_antennas_and_times_survive_a_second_write(written, tmp_path):
    """An MS read back (antennas and times, no positions) is written again with the same rows."""
    first = read_ms(written)
    again = read_ms(write_ms(first, tmp_path / "again.ms"))
    for name in ("antenna1", "antenna2"):
        np.testing.assert_array_equal(getattr(again, name), getattr(first, name))
    np.testing.assert_allclose(again.u, first.u, rtol=1e-14, atol=1e-9)  # metres and back: rounding only
    np.testing.assert_allclose(again.v, first.v, rtol=1e-14, atol=1e-9)
    np.testing.assert_allclose(again.time, first.time, rtol=0, atol=1e-6)
    np.testing.assert_allclose(again.V, first.V, rtol=1e-6, atol=1e-8)
    # one time stamp per integration, as CASA needs
    assert np.unique(_col(tmp_path / "again.ms", "TIME")).size == np.unique(first.time).size
