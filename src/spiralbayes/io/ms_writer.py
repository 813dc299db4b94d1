"""Write :class:`~spiralbayes.visibilities.Visibilities` as a Measurement Set that CASA opens.

python-casacore only (``pip install "spiralbayes[ms]"``); CASA itself is not needed to write.
What CASA's tasks need beyond the columns that ``casacore.tables.default_ms`` creates was found
by trying tclean, listobs and msmetadata on written sets (CASA 6.7): a frequency frame other
than REST in ``SPECTRAL_WINDOW.MEAS_FREQ_REF`` (TOPO here), a row in ``OBSERVATION``
(telescope ``ALMA``), one ``FEED`` row per antenna with its receptors' polarisation types,
``ANTENNA`` rows for every antenna id used, and rows of one integration sharing one ``TIME``
(with one time stamp per row CASA's visibility iterator makes tclean ~200 times slower).

Two layouts
-----------
* **Known antennas and times** (``vis.layout``, set by :mod:`spiralbayes.simulate`): one
  ``ANTENNA`` row per antenna at its ITRF position, rows ``(ANTENNA1 < ANTENNA2)`` with the
  time of their integration, ``SCAN_NUMBER`` per configuration and the coverage's w. CASA
  stores ``UVW = uvw(ANTENNA1) - uvw(ANTENNA2)`` whereas the package's rows are
  ``uvw(antenna2) - uvw(antenna1)``: such rows are written as ``(-u, -v, -w)`` with
  ``conj(V)``, the same measurement (``V(-u, -v) = conj V(u, v)`` for a real sky). So
  :func:`~spiralbayes.io.read_ms` of the set returns ``(-u, -v, conj V)`` for those rows.
  Times: the source (at ``phase_centre``) transits the array's meridian on ``date``; a row at
  hour angle ``H`` [h] of scan ``k`` is at ``t_transit + k T_sid + H 3600 / 1.002737909`` s
  (``T_sid`` one sidereal day), mean sidereal time by the IAU 1982 expression (Aoki et al.
  1982). UT1 - UTC, precession, nutation and aberration are ignored: with the default
  ``date`` near J2000.0, CASA's ``fixvis`` recomputes the written u, v from ``ANTENNA``,
  ``TIME`` and ``FIELD`` to 7e-6 of the baseline and w to 1.2e-4 (CASA's w axis points at the
  aberrated direction, 20" away). CASA's UVW axes are J2000; for dates decades away the
  of-date frame is rotated by ~0.1 deg, which no imaging task notices.
* **Recorded antennas without positions** (``vis.antenna1``, ``antenna2``, ``time`` without a
  layout, e.g. read from a Measurement Set or a spiralbayes HDF5 file): each row keeps its
  antennas (``ANTENNA1 = antenna2``, ``ANTENNA2 = antenna1``, so that ``UVW`` as written is
  ``uvw(ANTENNA1) - uvw(ANTENNA2)``) and its time (MJD seconds as read, or seconds after the
  transit on ``date`` for times below 1e9 s); UVW and DATA are written as they are and the
  antennas are pseudo-antennas, as below.
* **Unknown** (data read from a uvtable, ...): consecutive blocks of ``rows_per_time`` rows
  share a time stamp (30 s apart) and are given the baselines of a pseudo-array in turn.
  UVW and DATA are written as they are. CASA images such a set exactly as the real one, but
  its UVW do not follow from its ``ANTENNA`` table (only imaging and tasks that read UVW are
  meaningful on it).

Weights: each hand (XX = YY = V) gets ``WEIGHT = w / 2`` and ``SIGMA = 1 / sqrt(w / 2)``, so
that Stokes I ``(XX + YY) / 2`` has weight ``w`` (see :mod:`spiralbayes.io.measurement_set`)
and CASA's natural-weighted ``sumwt`` is ``sum(w)``.
"""

from __future__ import annotations

import logging
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from ..exceptions import InputError
from ..layout import ObservationLayout
from ..units import C_LIGHT
from ..visibilities import Visibilities
from ._common import _json

__all__ = [
    "ALMA_HEIGHT",
    "ALMA_LONGITUDE",
    "DEFAULT_PHASE_CENTRE",
    "enu_to_itrf",
    "gmst_deg",
    "itrf_to_enu",
    "row_times",
    "transit_time",
    "write_ms",
]

log = logging.getLogger(__name__)

ALMA_LONGITUDE = -67.7538
"""Longitude of the ALMA array centre [deg] (as :mod:`spiralbayes.simulate`)."""
ALMA_HEIGHT = 5050.0
"""Height of the ALMA array centre above the WGS84 ellipsoid [m] (the Chajnantor plateau)."""
DEFAULT_PHASE_CENTRE = (240.0, -25.0)
"""(RA, Dec) [deg] J2000 written when neither the caller nor the layout gives one."""
_PROVENANCE_KEYWORD = "SPIRALBAYES_PROVENANCE"
_SIDEREAL_RATE = 1.002737909
_SIDEREAL_DAY = 86400.0 / _SIDEREAL_RATE
_DAY = 86400.0
_MJD_UNIX = 40587.0
_WGS84_A, _WGS84_F = 6378137.0, 1.0 / 298.257223563
_TOPO, _CORR_XX_YY = 5, (9, 12)


def _tables():
    try:
        import casacore.tables as tables
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError('writing Measurement Sets needs python-casacore: pip install "spiralbayes[ms]"') from exc
    return tables


# ---------------------------------------------------------------------------------- geometry
def _enu_axes(lon_deg: float, lat_deg: float) -> np.ndarray:
    """Rows: unit vectors east, north, up in ITRF at (lon, lat)."""
    lon, lat = np.radians(lon_deg), np.radians(lat_deg)
    sl, cl, sp, cp = np.sin(lon), np.cos(lon), np.sin(lat), np.cos(lat)
    return np.array([[-sl, cl, 0.0], [-sp * cl, -sp * sl, cp], [cp * cl, cp * sl, sp]])


def _geodetic_to_itrf(lon_deg: float, lat_deg: float, height: float) -> np.ndarray:
    e2 = _WGS84_F * (2.0 - _WGS84_F)
    lon, lat = np.radians(lon_deg), np.radians(lat_deg)
    n = _WGS84_A / np.sqrt(1.0 - e2 * np.sin(lat) ** 2)
    return np.array([(n + height) * np.cos(lat) * np.cos(lon), (n + height) * np.cos(lat) * np.sin(lon),
                     (n * (1.0 - e2) + height) * np.sin(lat)])


def enu_to_itrf(enu, lat_deg: float, lon_deg: float = ALMA_LONGITUDE, height: float = ALMA_HEIGHT) -> np.ndarray:
    """ITRF (Earth-centred) positions [m] of local (east, north, up) offsets [m] about a site.

    The site is the WGS84 geodetic position ``(lon, lat, height)``; ``enu`` has shape (n, 3).
    """
    centre = _geodetic_to_itrf(lon_deg, lat_deg, height)
    return centre[None, :] + np.asarray(enu, dtype=float) @ _enu_axes(lon_deg, lat_deg)


def itrf_to_enu(itrf, lat_deg: float, lon_deg: float = ALMA_LONGITUDE, height: float = ALMA_HEIGHT) -> np.ndarray:
    """Inverse of :func:`enu_to_itrf`."""
    centre = _geodetic_to_itrf(lon_deg, lat_deg, height)
    return (np.asarray(itrf, dtype=float) - centre[None, :]) @ _enu_axes(lon_deg, lat_deg).T


def gmst_deg(mjd_ut1) -> np.ndarray:
    """Greenwich mean sidereal time [deg] at UT1 MJD (IAU 1982, linear and quadratic terms)."""
    d = np.asarray(mjd_ut1, dtype=float) - 51544.5
    t = d / 36525.0
    return (280.46061837 + 360.98564736629 * d + 0.000387933 * t**2) % 360.0


def transit_time(ra_deg: float, date: str, lon_deg: float = ALMA_LONGITUDE) -> float:
    """MJD seconds (UTC taken as UT1) of the first meridian transit of ``ra_deg`` on ``date`` (YYYY-MM-DD)."""
    try:
        day = float(np.datetime64(date, "D").astype(np.int64)) + _MJD_UNIX
    except ValueError:
        raise InputError(f"date must be YYYY-MM-DD, got {date!r}") from None
    hour_angle0 = (gmst_deg(day) + lon_deg - ra_deg) % 360.0  # at 0h UT
    return float((day + ((360.0 - hour_angle0) % 360.0) / (360.0 * _SIDEREAL_RATE)) * _DAY)


def row_times(layout: ObservationLayout, ra_deg: float, date: str) -> np.ndarray:
    """TIME [MJD seconds] of every row of ``layout`` (see the module docstring)."""
    t0 = transit_time(ra_deg, date)
    return t0 + layout.scan * _SIDEREAL_DAY + layout.hour_angle * 3600.0 / _SIDEREAL_RATE


# ------------------------------------------------------------------------------------ rows
def _known_rows(vis: Visibilities, phase_centre, date: str) -> dict:
    lay = vis.layout
    assert lay is not None  # write_ms calls this only for data with a layout
    flip = lay.antenna1 < lay.antenna2  # package rows are uvw(a2) - uvw(a1); CASA's uvw(ANT1) - uvw(ANT2)
    sign = np.where(flip, -1.0, 1.0)
    ra, dec = phase_centre if phase_centre is not None else (DEFAULT_PHASE_CENTRE[0], lay.declination)
    if not np.isclose(dec, lay.declination, atol=1e-9):
        raise InputError(f"phase_centre Dec {dec} deg differs from the declination {lay.declination} deg the "
                         "layout's u, v were computed for: pass phase_centre=(ra, layout.declination)")
    return {
        "uvw": np.column_stack([vis.u, vis.v, lay.w]) * sign[:, None] * vis.wavelength,
        "data": np.where(flip, np.conj(vis.V), vis.V),
        "antenna1": np.minimum(lay.antenna1, lay.antenna2),
        "antenna2": np.maximum(lay.antenna1, lay.antenna2),
        "time": row_times(lay, ra, date),
        "scan": lay.scan + 1,
        "interval": lay.integration_time,
        "itrf": enu_to_itrf(lay.positions, lay.latitude),
        "names": list(lay.names),
        "dish": lay.dish_diameter,
        "direction": (ra, dec),
        "layout": "known antennas and times",
    }


def _recorded_rows(vis: Visibilities, phase_centre, date: str, rows_per_time: int) -> dict:
    rows = _generic_rows(vis, phase_centre, date, rows_per_time)
    assert vis.antenna1 is not None and vis.antenna2 is not None  # write_ms checks vis.has_antennas
    n_ant = int(max(vis.antenna1.max(), vis.antenna2.max())) + 1
    angle = 2 * np.pi * np.arange(n_ant) / n_ant
    enu = np.column_stack([100.0 * np.cos(angle), 100.0 * np.sin(angle), np.zeros(n_ant)])
    rows.update(antenna1=vis.antenna2, antenna2=vis.antenna1, itrf=enu_to_itrf(enu, -23.0234),
                names=[f"P{k:02d}" for k in range(n_ant)],
                layout="recorded antennas and times, pseudo-antenna positions (UVW not from ANTENNA)")
    if vis.time is not None:
        # MJD seconds of real data are ~5e9; smaller times count from the transit on ``date``
        t0 = 0.0 if vis.time.min() > 1e9 else transit_time(rows["direction"][0], date)
        steps = np.diff(np.unique(vis.time))
        rows.update(time=t0 + vis.time, interval=float(np.median(steps)) if steps.size else 30.0)
    return rows


def _generic_rows(vis: Visibilities, phase_centre, date: str, rows_per_time: int) -> dict:
    if rows_per_time < 1:
        raise InputError(f"rows_per_time must be >= 1, got {rows_per_time}")
    n_ant = int(np.ceil(0.5 * (1.0 + np.sqrt(1.0 + 8.0 * rows_per_time))))
    i, j = np.triu_indices(n_ant, k=1)
    idx = np.arange(vis.n)
    block = idx // rows_per_time
    ra, dec = phase_centre if phase_centre is not None else DEFAULT_PHASE_CENTRE
    angle = 2 * np.pi * np.arange(n_ant) / n_ant  # pseudo-antennas on a 100-m circle
    enu = np.column_stack([100.0 * np.cos(angle), 100.0 * np.sin(angle), np.zeros(n_ant)])
    interval = 30.0
    return {
        "uvw": np.column_stack([vis.u, vis.v, np.zeros(vis.n)]) * vis.wavelength,
        "data": vis.V,
        "antenna1": i[(idx % rows_per_time) % i.size],
        "antenna2": j[(idx % rows_per_time) % i.size],
        "time": transit_time(ra, date) + (block - 0.5 * block.max()) * interval,
        "scan": np.ones(vis.n, dtype=int),
        "interval": interval,
        "itrf": enu_to_itrf(enu, -23.0234),
        "names": [f"P{k:02d}" for k in range(n_ant)],
        "dish": 12.0,
        "direction": (ra, dec),
        "layout": f"generic: {rows_per_time} rows per time stamp, pseudo-antennas (UVW not from ANTENNA)",
    }


# ---------------------------------------------------------------------------------- writing
def write_ms(vis: Visibilities, path, *, field_name: str = "spiralbayes", phase_centre=None,
             date: str = "2000-01-01", rows_per_time: int = 903, channel_width: float = 1e6) -> Path:
    """Write ``vis`` as a Measurement Set that CASA's tasks (tclean, listobs, ...) accept.

    One spectral window of one channel at ``C_LIGHT / vis.wavelength`` (TOPO frame), XX = YY
    = V, ``WEIGHT = w / 2`` and ``SIGMA = WEIGHT^-1/2`` per hand; ``DATA`` is single-precision
    complex and ``WEIGHT`` float32, as in CASA (relative precision ~1e-7). Conjugated data are
    written in the MS convention. The provenance is stored as the table keyword
    ``SPIRALBAYES_PROVENANCE``. The MS is built in a temporary directory beside ``path`` and
    moved into place; an existing MS at ``path`` is replaced. See the module docstring for the
    antenna/time layouts and the UVW sign.

    Parameters
    ----------
    vis : Visibilities
        Must have a known ``wavelength``. With ``vis.layout`` the real antennas and times are
        written; with recorded antennas only, those antennas and times; otherwise a generic layout.
    path : str or Path
        Target directory (conventionally ending in ``.ms``).
    field_name : str
        Name written to the FIELD table.
    phase_centre : (float, float), optional
        (RA, Dec) J2000 [deg] of the field. Default: RA 240 deg and the layout's declination
        (Dec -25 deg without a layout).
    date : str
        Day of the (first) transit, ``YYYY-MM-DD``.
    rows_per_time : int
        Rows per time stamp of the generic layout (903: the baselines of 43 antennas).
    channel_width : float
        Width of the channel [Hz] (CHAN_WIDTH, EFFECTIVE_BW, RESOLUTION, TOTAL_BANDWIDTH).

    Returns
    -------
    Path
    """
    tables = _tables()
    if vis.wavelength is None:
        raise InputError("write_ms needs the observing wavelength to convert u, v to metres: "
                         "set it with dataclasses.replace(vis, wavelength=<metres>)")
    std = vis.standardised()
    assert std.wavelength is not None  # standardised() keeps the wavelength checked above
    if std.layout is not None:
        rows = _known_rows(std, phase_centre, date)
    elif std.has_antennas:
        rows = _recorded_rows(std, phase_centre, date, int(rows_per_time))
    else:
        rows = _generic_rows(std, phase_centre, date, int(rows_per_time))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent))
    try:
        _write_main(tables, std, rows, tmp / "ms")
        _write_subtables(tables, tmp / "ms", rows, C_LIGHT / std.wavelength, channel_width, field_name)
        _replace_dir(tmp / "ms", path)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    log.info("wrote %d visibilities to Measurement Set %s (%s)", vis.n, path, rows["layout"])
    return path


def _replace_dir(src: Path, dst: Path) -> None:
    """Move directory ``src`` onto ``dst``, replacing an existing ``dst`` only once ``src`` is complete."""
    if dst.exists():
        backup = dst.with_name(f".{dst.name}.old-{os.getpid()}")
        os.replace(dst, backup)
        os.replace(src, dst)
        shutil.rmtree(backup, ignore_errors=True)
    else:
        os.replace(src, dst)


def _write_main(tables, vis: Visibilities, rows: dict, path: Path) -> None:
    n = vis.n
    desc = tables.maketabdesc([tables.makearrcoldesc("DATA", 0j, ndim=2, shape=[1, 2], valuetype="complex")])
    half = np.repeat(0.5 * vis.weights[:, None], 2, axis=1)
    with tables.default_ms(str(path), desc) as ms:
        ms.addrows(n)
        ms.putcol("UVW", rows["uvw"])
        ms.putcol("DATA", np.repeat(rows["data"][:, None, None], 2, axis=2).astype(np.complex64))
        ms.putcol("WEIGHT", half.astype(np.float32))
        ms.putcol("SIGMA", (1.0 / np.sqrt(half)).astype(np.float32))
        ms.putcol("FLAG", np.zeros((n, 1, 2), dtype=bool))
        ms.putcol("ANTENNA1", rows["antenna1"].astype(np.int32))
        ms.putcol("ANTENNA2", rows["antenna2"].astype(np.int32))
        ms.putcol("TIME", rows["time"])
        ms.putcol("TIME_CENTROID", rows["time"])
        ms.putcol("INTERVAL", np.full(n, rows["interval"]))
        ms.putcol("EXPOSURE", np.full(n, rows["interval"]))
        ms.putcol("SCAN_NUMBER", np.asarray(rows["scan"], dtype=np.int32))
        # no STATE or PROCESSOR rows are written; -1 says so (0 would point at a missing row)
        ms.putcol("STATE_ID", np.full(n, -1, dtype=np.int32))
        ms.putcol("PROCESSOR_ID", np.full(n, -1, dtype=np.int32))
        ms.putkeyword(_PROVENANCE_KEYWORD, _json(vis.provenance))
        ms.putkeyword("SPIRALBAYES_LAYOUT", rows["layout"])


def _write_subtables(tables, path: Path, rows: dict, freq: float, width: float, field_name: str) -> None:
    _spectral_window(tables, path, freq, width)
    _polarisation(tables, path)
    with tables.table(str(path / "DATA_DESCRIPTION"), readonly=False, ack=False) as dd:
        dd.addrows(1)
        dd.putcell("SPECTRAL_WINDOW_ID", 0, 0)
        dd.putcell("POLARIZATION_ID", 0, 0)
    _field(tables, path, field_name, rows["direction"])
    _observation(tables, path, rows)
    _antennas(tables, path, rows)
    _feeds(tables, path, len(rows["names"]))


def _spectral_window(tables, path: Path, freq: float, width: float) -> None:
    with tables.table(str(path / "SPECTRAL_WINDOW"), readonly=False, ack=False) as spw:
        spw.addrows(1)
        spw.putcell("NUM_CHAN", 0, 1)
        spw.putcell("CHAN_FREQ", 0, np.array([freq]))
        for col in ("CHAN_WIDTH", "EFFECTIVE_BW", "RESOLUTION"):
            spw.putcell(col, 0, np.array([width]))
        spw.putcell("REF_FREQUENCY", 0, freq)
        spw.putcell("TOTAL_BANDWIDTH", 0, width)
        spw.putcell("MEAS_FREQ_REF", 0, _TOPO)  # REST (0) makes tclean fail: "No MeasFrame specified"
        spw.putcell("NET_SIDEBAND", 0, 1)
        spw.putcell("NAME", 0, "spiralbayes")


def _polarisation(tables, path: Path) -> None:
    with tables.table(str(path / "POLARIZATION"), readonly=False, ack=False) as pol:
        pol.addrows(1)
        pol.putcell("NUM_CORR", 0, 2)
        pol.putcell("CORR_TYPE", 0, np.array(_CORR_XX_YY, dtype=np.int32))
        pol.putcell("CORR_PRODUCT", 0, np.array([[0, 0], [1, 1]], dtype=np.int32))


def _field(tables, path: Path, name: str, direction) -> None:
    ra, dec = np.radians(direction[0]), np.radians(direction[1])
    with tables.table(str(path / "FIELD"), readonly=False, ack=False) as fld:
        fld.addrows(1)
        fld.putcell("NAME", 0, name)
        fld.putcell("CODE", 0, "OBJ")
        for col in ("PHASE_DIR", "DELAY_DIR", "REFERENCE_DIR"):
            fld.putcell(col, 0, np.array([[ra, dec]]))
        fld.putcell("NUM_POLY", 0, 0)
        fld.putcell("TIME", 0, 0.0)
        fld.putcell("SOURCE_ID", 0, -1)


def _observation(tables, path: Path, rows: dict) -> None:
    half = 0.5 * rows["interval"]
    with tables.table(str(path / "OBSERVATION"), readonly=False, ack=False) as obs:
        obs.addrows(1)
        obs.putcell("TELESCOPE_NAME", 0, "ALMA")  # known to CASA's Observatories table
        obs.putcell("TIME_RANGE", 0, np.array([rows["time"].min() - half, rows["time"].max() + half]))
        obs.putcell("OBSERVER", 0, "spiralbayes")
        obs.putcell("PROJECT", 0, "spiralbayes")
        obs.putcell("RELEASE_DATE", 0, 0.0)
        obs.putcell("SCHEDULE_TYPE", 0, "")
        obs.putcell("FLAG_ROW", 0, False)


def _antennas(tables, path: Path, rows: dict) -> None:
    n = len(rows["names"])
    with tables.table(str(path / "ANTENNA"), readonly=False, ack=False) as ant:
        ant.addrows(n)
        ant.putcol("NAME", rows["names"])
        ant.putcol("STATION", [f"S{k:03d}" for k in range(n)])
        ant.putcol("TYPE", ["GROUND-BASED"] * n)
        ant.putcol("MOUNT", ["ALT-AZ"] * n)
        ant.putcol("POSITION", rows["itrf"])
        ant.putcol("OFFSET", np.zeros((n, 3)))
        ant.putcol("DISH_DIAMETER", np.full(n, float(rows["dish"])))
        ant.putcol("FLAG_ROW", np.zeros(n, dtype=bool))


def _feeds(tables, path: Path, n: int) -> None:
    """One feed per antenna with linear X/Y receptors (tclean reads POLARIZATION_TYPE)."""
    with tables.table(str(path / "FEED"), readonly=False, ack=False) as feed:
        feed.addrows(n)
        feed.putcol("ANTENNA_ID", np.arange(n, dtype=np.int32))
        feed.putcol("FEED_ID", np.zeros(n, dtype=np.int32))
        feed.putcol("SPECTRAL_WINDOW_ID", np.full(n, -1, dtype=np.int32))
        feed.putcol("TIME", np.zeros(n))
        feed.putcol("INTERVAL", np.full(n, 1e30))
        feed.putcol("NUM_RECEPTORS", np.full(n, 2, dtype=np.int32))
        feed.putcol("BEAM_ID", np.full(n, -1, dtype=np.int32))
        feed.putcol("BEAM_OFFSET", np.zeros((n, 2, 2)))
        feed.putcol("POLARIZATION_TYPE", np.array([["X", "Y"]] * n))
        feed.putcol("POL_RESPONSE", np.tile(np.eye(2, dtype=np.complex64), (n, 1, 1)))
        feed.putcol("POSITION", np.zeros((n, 3)))
        feed.putcol("RECEPTOR_ANGLE", np.zeros((n, 2)))
