"""uv coverage of the ALMA 12-m array by Earth-rotation synthesis (see :mod:`spiralbayes.simulate`)."""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from ..exceptions import InputError
from ..layout import ObservationLayout
from ..units import C_LIGHT

__all__ = [
    "ALMA_LATITUDE",
    "SIDEREAL_RATE",
    "UVCoverage",
    "available_configurations",
    "baseline_uvw",
    "elevation",
    "load_configuration",
    "uv_coverage",
]

log = logging.getLogger(__name__)

ALMA_LATITUDE = -23.0234
"""Latitude of the ALMA array centre [deg] (longitude -67.7538 deg)."""

SIDEREAL_RATE = 1.002737909
"""Sidereal seconds (of hour angle) per SI second."""

_CONFIG_DIR = ("data", "alma-configurations")
_CONFIG_RE = re.compile(r"^(?:alma\.)?cycle(\d+)\.(\d+)(?:\.layout\.txt)?$", re.IGNORECASE)
_SHORT_RE = re.compile(r"^C-?(\d+)$", re.IGNORECASE)


# ---------------------------------------------------------------------------------------------
# Antenna configurations
# ---------------------------------------------------------------------------------------------
def _config_root():
    root = resources.files("spiralbayes")
    for part in _CONFIG_DIR:  # one level at a time: Traversable.joinpath takes one name before Python 3.11
        root = root.joinpath(part)
    return root


def available_configurations() -> list[str]:
    """Names of the packaged configurations, e.g. ``["cycle10.1", ..., "cycle11.10"]``.

    ``"C-M"`` is short for ``"cycle11.M"`` (see :func:`.load_configuration`).
    """
    names = []
    for entry in _config_root().iterdir():
        match = _CONFIG_RE.match(entry.name)
        if match:
            names.append((int(match[1]), int(match[2])))
    return [f"cycle{c}.{m}" for c, m in sorted(names)]


def _canonical_name(name: str | Path, cycle: int) -> str:
    text = str(name).strip()
    short = _SHORT_RE.match(text)
    if short:
        return f"cycle{cycle}.{int(short[1])}"
    full = _CONFIG_RE.match(text)
    if full:
        return f"cycle{int(full[1])}.{int(full[2])}"
    return text


def load_configuration(name, cycle: int = 11) -> np.ndarray:
    """Antenna positions ``(n_ant, 3)`` [m], columns x east, y north, z up.

    Parameters
    ----------
    name : str, path or array
        ``"C-4"`` / ``"C4"`` (configuration 4 of ``cycle``), ``"cycle10.4"``,
        ``"alma.cycle10.4.layout.txt"``, the path of a text file with ``x y z`` columns, or an
        ``(n_ant, 3)`` array (returned as a float copy).
    cycle : int
        ALMA cycle used for the short ``"C-M"`` names (10 or 11).

    Raises
    ------
    ValueError
        For an unknown name, listing the valid ones.
    """
    if not isinstance(name, (str, Path)):
        pos = np.array(name, dtype=float)
        if pos.ndim != 2 or pos.shape[1] != 3 or pos.shape[0] < 2:
            raise InputError(f"antenna positions must have shape (n_ant >= 2, 3), got {pos.shape}")
        return pos
    canonical = _canonical_name(name, cycle)
    if _CONFIG_RE.match(canonical):
        entry = _config_root().joinpath(f"alma.{canonical}.layout.txt")
        if entry.is_file():
            return np.loadtxt(entry.open("r"), dtype=float, ndmin=2)
    path = Path(name)
    if path.suffix and path.is_file():
        pos = np.loadtxt(path, dtype=float, ndmin=2)
        if pos.shape[1] < 3:
            raise InputError(f"{path}: expected columns x y z [m], got {pos.shape[1]} column(s)")
        return pos[:, :3]
    valid = available_configurations()
    short = sorted({int(v.split(".")[1]) for v in valid if v.startswith(f"cycle{cycle}.")})
    raise InputError(
        f"unknown ALMA configuration {name!r}: use one of {', '.join(valid)}, "
        f"or 'C-M' for cycle {cycle} (M in {short}), or the path of an 'x y z' [m] antenna file"
    )


def _config_label(name, cycle: int) -> str:
    if isinstance(name, (str, Path)):
        return _canonical_name(str(name), cycle)
    return "custom"


# ---------------------------------------------------------------------------------------------
# uv coverage
# ---------------------------------------------------------------------------------------------
@dataclass
class UVCoverage:
    """Baselines of a (multi-configuration) observation.

    Attributes
    ----------
    u, v, w : ndarray
        Baseline coordinates [lambda], one per antenna pair and integration.
    hour_angle : ndarray
        Hour angle [h] at the mid-point of each integration.
    configuration : ndarray of int
        Index into ``configurations`` of each row.
    configurations : list of str
        Configuration names (``"cycle11.4"``, ...).
    wavelength : float
        [m].
    declination : float
        [deg].
    integration_time : float
        [s].
    hour_angles : list of (float, float)
        Requested hour-angle range [h] per configuration.
    n_dropped : int
        Integrations (times antenna pairs) dropped below ``min_elevation``.
    antenna1, antenna2 : ndarray of int, optional
        Antennas of each row, indices into ``antenna_positions``: the row's baseline is
        ``antenna_positions[antenna2] - antenna_positions[antenna1]``.
    antenna_positions : ndarray (n_ant, 3), optional
        Positions [m] (x east, y north, z up) of the antennas of every configuration, stacked
        (one entry per antenna and configuration, named in ``antenna_names``).
    """

    u: np.ndarray
    v: np.ndarray
    w: np.ndarray
    hour_angle: np.ndarray
    configuration: np.ndarray
    configurations: list
    wavelength: float
    declination: float
    integration_time: float
    hour_angles: list
    min_elevation: float
    n_dropped: int = 0
    antenna1: np.ndarray | None = None
    antenna2: np.ndarray | None = None
    antenna_positions: np.ndarray | None = None
    antenna_names: tuple = ()

    @property
    def n(self) -> int:
        """Number of visibilities."""
        return self.u.size

    @property
    def uv_distance(self) -> np.ndarray:
        return np.hypot(self.u, self.v)

    def layout(self) -> ObservationLayout | None:
        """Antennas and hour angles of every row (None if the antennas are not known)."""
        if self.antenna1 is None or self.antenna2 is None or self.antenna_positions is None:
            return None
        return ObservationLayout(self.antenna1, self.antenna2, self.hour_angle, self.configuration, self.w,
                                 self.antenna_positions, self.antenna_names, self.integration_time,
                                 self.declination, ALMA_LATITUDE)

    def times(self) -> np.ndarray:
        """Time of every row [s] from the middle of the first integration.

        Configuration ``k`` is observed ``k`` sidereal days after configuration 0 (as
        :func:`spiralbayes.io.write_ms` writes them), so equal hour angles of different
        configurations are different times.
        """
        t = (self.configuration * 24.0 + self.hour_angle) * 3600.0 / SIDEREAL_RATE
        return t - t.min()

    def describe(self) -> dict:
        """Plain-type summary for provenance records."""
        return {
            "configurations": list(self.configurations),
            "hour_angles_h": [list(map(float, h)) for h in self.hour_angles],
            "declination_deg": self.declination,
            "latitude_deg": ALMA_LATITUDE,
            "integration_time_s": self.integration_time,
            "wavelength_m": self.wavelength,
            "min_elevation_deg": self.min_elevation,
            "n_visibilities": int(self.n),
            "n_dropped_below_min_elevation": int(self.n_dropped),
        }


def elevation(hour_angle, declination, latitude: float = ALMA_LATITUDE) -> np.ndarray:
    """Source elevation [deg] at hour angle [h] and declination [deg]."""
    h = np.radians(np.asarray(hour_angle, dtype=float) * 15.0)
    d, lat = np.radians(declination), np.radians(latitude)
    return np.degrees(np.arcsin(np.sin(lat) * np.sin(d) + np.cos(lat) * np.cos(d) * np.cos(h)))


def baseline_uvw(enu, hour_angle, declination, latitude: float = ALMA_LATITUDE) -> np.ndarray:
    """Projected baselines ``(..., 3)`` [m] of ENU baseline vectors ``(..., 3)`` [m].

    ``hour_angle`` [h] broadcasts against the leading axes of ``enu`` (TMS eqs. 4.1, 4.15).
    """
    enu = np.asarray(enu, dtype=float)
    lat, d = np.radians(latitude), np.radians(declination)
    h = np.radians(np.asarray(hour_angle, dtype=float) * 15.0)
    x, y, z = enu[..., 0], enu[..., 1], enu[..., 2]
    X = -y * np.sin(lat) + z * np.cos(lat)
    Y = x
    Z = y * np.cos(lat) + z * np.sin(lat)
    sh, ch, sd, cd = np.sin(h), np.cos(h), np.sin(d), np.cos(d)
    u = sh * X + ch * Y
    v = -sd * ch * X + sd * sh * Y + cd * Z
    w = cd * ch * X - cd * sh * Y + sd * Z
    return np.stack([u, v, w], axis=-1)


def _wavelength(wavelength, frequency) -> float:
    if (wavelength is None) == (frequency is None):
        raise InputError("give exactly one of wavelength [m] and frequency [Hz]")
    lam = float(wavelength) if wavelength is not None else C_LIGHT / float(frequency)
    if not (np.isfinite(lam) and lam > 0):
        raise InputError(f"wavelength must be a positive number of metres, got {lam!r}")
    if lam > 0.1:
        raise InputError(
            f"wavelength {lam} m is not an ALMA wavelength: give it in metres (e.g. 8.7e-4)"
        )
    return lam


def uv_coverage(configurations, declination: float, hour_angles=(-0.5, 0.5),
                integration_time: float = 30.0, wavelength: float | None = None, *,
                frequency: float | None = None, min_elevation: float = 15.0,
                cycle: int = 11) -> UVCoverage:
    """Earth-rotation synthesis coverage of one or more ALMA configurations.

    Parameters
    ----------
    configurations : str or sequence
        One configuration or several (e.g. ``["C-4", "C-7"]``), each as accepted by
        :func:`.load_configuration`. Several configurations are concatenated, each observed over
        its own hour-angle range.
    declination : float
        Source declination [deg].
    hour_angles : (start, end) or sequence of (start, end)
        Hour-angle range [h], one for all configurations or one per configuration. The range
        is cut into ``floor(range / integration)`` integrations sampled at their mid-points.
    integration_time : float
        Length of one integration (after any time averaging) [s].
    wavelength, frequency : float
        Observing wavelength [m] or frequency [Hz] (exactly one).
    min_elevation : float
        Integrations with the source lower than this [deg] are dropped.
    cycle : int
        ALMA cycle for ``"C-M"`` names.

    Returns
    -------
    UVCoverage
        u, v, w [λ] of every baseline and integration, with the antennas, hour angles and configuration of
        each row.

    Raises
    ------
    ValueError
        Unknown configuration; a source that never rises above ``min_elevation`` at ALMA;
        hour-angle ranges that are empty, reversed, shorter than one integration, or with the
        source below ``min_elevation`` throughout.
    """
    lam = _wavelength(wavelength, frequency)
    if isinstance(configurations, (str, Path)) or (
        isinstance(configurations, np.ndarray) and configurations.ndim == 2
    ):
        configurations = [configurations]
    configurations = list(configurations)
    if not configurations:
        raise InputError("no configuration given: pass e.g. 'C-4' or ['C-4', 'C-7']")
    if not -90.0 <= declination <= 90.0:
        raise InputError(f"declination must be in [-90, 90] deg, got {declination}")
    if not integration_time > 0:
        raise InputError(f"integration_time must be positive [s], got {integration_time}")
    ha = np.asarray(hour_angles, dtype=float)
    if ha.shape == (2,):
        ranges = [tuple(ha)] * len(configurations)
    elif ha.shape == (len(configurations), 2):
        ranges = [tuple(row) for row in ha]
    else:
        raise InputError(
            f"hour_angles must be (start, end) [h] or one (start, end) per configuration "
            f"({len(configurations)}), got shape {ha.shape}"
        )
    max_el = 90.0 - abs(declination - ALMA_LATITUDE)
    if max_el < min_elevation:
        raise InputError(
            f"a source at declination {declination:+.2f} deg never rises above min_elevation = "
            f"{min_elevation} deg at ALMA (latitude {ALMA_LATITUDE} deg; highest elevation "
            f"{max_el:.1f} deg at transit): no data"
        )

    step_h = integration_time * SIDEREAL_RATE / 3600.0
    us, vs, ws, hs, idx, labels = [], [], [], [], [], []
    ant1, ant2, names = [], [], []
    positions: list[np.ndarray] = []
    n_dropped = 0
    for k, (config, (h0, h1)) in enumerate(zip(configurations, ranges)):
        label = _config_label(config, cycle)
        pos = load_configuration(config, cycle)
        if not (np.isfinite(h0) and np.isfinite(h1)) or h1 <= h0 or h1 - h0 > 24.0:
            raise InputError(
                f"hour-angle range ({h0}, {h1}) h for {label} gives no data: need start < end "
                "and a range of at most 24 h"
            )
        n_int = int(np.floor((h1 - h0) / step_h + 1e-9))
        if n_int < 1:
            raise InputError(
                f"hour-angle range ({h0}, {h1}) h for {label} is shorter than one integration "
                f"({integration_time} s = {step_h:.4g} h of hour angle): no data"
            )
        hour = h0 + (np.arange(n_int) + 0.5) * step_h
        up = elevation(hour, declination) >= min_elevation
        if not up.any():
            el = elevation(hour, declination)
            raise InputError(
                f"the source (declination {declination:+.2f} deg) is below min_elevation = "
                f"{min_elevation} deg throughout hour angles ({h0}, {h1}) h for {label} "
                f"(elevation {el.min():.1f} to {el.max():.1f} deg): no data; choose hour angles "
                "nearer transit (0 h)"
            )
        i, j = np.triu_indices(pos.shape[0], k=1)
        enu = pos[j] - pos[i]
        n_dropped += int((~up).sum()) * enu.shape[0]
        uvw = baseline_uvw(enu[None, :, :], hour[up][:, None], declination) / lam
        us.append(uvw[..., 0].ravel())
        vs.append(uvw[..., 1].ravel())
        ws.append(uvw[..., 2].ravel())
        hs.append(np.repeat(hour[up], enu.shape[0]))
        idx.append(np.full(uvw[..., 0].size, k, dtype=int))
        labels.append(label)
        first = sum(p.shape[0] for p in positions)
        ant1.append(np.tile(i, int(up.sum())) + first)
        ant2.append(np.tile(j, int(up.sum())) + first)
        positions.append(pos)
        prefix = _short_label(label, k) if label not in labels[:-1] else f"K{k}A"
        names += [f"{prefix}{n:02d}" for n in range(pos.shape[0])]
    if n_dropped:
        log.info("dropped %d visibilities with the source below %.1f deg", n_dropped, min_elevation)
    return UVCoverage(
        u=np.concatenate(us), v=np.concatenate(vs), w=np.concatenate(ws),
        hour_angle=np.concatenate(hs), configuration=np.concatenate(idx), configurations=labels,
        wavelength=lam, declination=float(declination), integration_time=float(integration_time),
        hour_angles=ranges, min_elevation=float(min_elevation), n_dropped=n_dropped,
        antenna1=np.concatenate(ant1), antenna2=np.concatenate(ant2), antenna_positions=np.vstack(positions),
        antenna_names=tuple(names),
    )


def _short_label(label: str, k: int) -> str:
    """Antenna-name prefix of a configuration: ``"C4A"`` for ``cycle11.4``, ``"K0A"`` for custom ones."""
    match = _CONFIG_RE.match(label)
    return f"C{int(match[2])}A" if match else f"K{k}A"
