"""Which antennas measured each visibility, and when: the optional :class:`ObservationLayout`.

Fitting needs only u, v, V and the weights, but a Measurement Set that CASA accepts as a real
observation also records, per row, the two antennas and the time of the integration, and per
antenna its position. Simulated observations know all of it (:mod:`spiralbayes.simulate`
fills it in); data read from other formats usually do not, and then
:func:`spiralbayes.io.write_ms` falls back to a generic layout.

Sign convention (the package's, that of :func:`spiralbayes.simulate.uv_coverage`): the
baseline of a row is ``positions[antenna2] - positions[antenna1]``, i.e. ``(u, v, w)`` =
``uvw(antenna2) - uvw(antenna1)``. CASA stores the opposite difference,
``UVW = uvw(ANTENNA1) - uvw(ANTENNA2)``; the MS writer converts (see
:mod:`spiralbayes.io.ms_writer`).

Units: positions [m] in the local tangent plane of the array centre (x east, y north, z up);
hour angles [h] at the middle of each integration; w [lambda]; integration time [s];
declination and latitude [deg].
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .exceptions import InputError

__all__ = ["ObservationLayout"]


@dataclass(frozen=True)
class ObservationLayout:
    """Antennas, hour angles and w of every visibility of an Earth-rotation observation.

    Attributes
    ----------
    antenna1, antenna2 : ndarray of int, shape (N,)
        Row indices into ``positions``; the row's baseline is ``positions[antenna2] -
        positions[antenna1]``.
    hour_angle : ndarray, shape (N,)
        Hour angle of the source [h] at the middle of the row's integration.
    scan : ndarray of int, shape (N,)
        Block of the observation (a configuration); scan ``k`` is observed ``k`` sidereal days
        after scan 0, so that equal hour angles in different scans are different times.
    w : ndarray, shape (N,)
        Third baseline coordinate [lambda] (same sign convention as u, v).
    positions : ndarray, shape (n_ant, 3)
        Antenna positions [m], x east, y north, z up, about the array centre.
    names : tuple of str
        One name per antenna.
    integration_time : float
        Length of one integration [s].
    declination : float
        Source declination [deg] the hour angles refer to.
    latitude : float
        Latitude of the array centre [deg] used to compute u, v, w.
    dish_diameter : float
        [m].
    """

    antenna1: np.ndarray
    antenna2: np.ndarray
    hour_angle: np.ndarray
    scan: np.ndarray
    w: np.ndarray
    positions: np.ndarray
    names: tuple = field(default=())
    integration_time: float = 30.0
    declination: float = 0.0
    latitude: float = -23.0234
    dish_diameter: float = 12.0

    def __post_init__(self):
        ints = {k: np.asarray(getattr(self, k), dtype=np.int64).ravel() for k in ("antenna1", "antenna2", "scan")}
        floats = {k: np.asarray(getattr(self, k), dtype=float).ravel() for k in ("hour_angle", "w")}
        for k, v in {**ints, **floats}.items():
            object.__setattr__(self, k, v)
        pos = np.asarray(self.positions, dtype=float)
        if pos.ndim != 2 or pos.shape[1] != 3:
            raise InputError(f"ObservationLayout.positions must have shape (n_ant, 3) [m], got {pos.shape}")
        object.__setattr__(self, "positions", pos)
        names = tuple(str(n) for n in self.names) or tuple(f"A{k:02d}" for k in range(pos.shape[0]))
        if len(names) != pos.shape[0]:
            raise InputError(f"ObservationLayout.names has {len(names)} entries for {pos.shape[0]} antennas")
        object.__setattr__(self, "names", names)
        sizes = {k: getattr(self, k).size for k in ("antenna1", "antenna2", "hour_angle", "scan", "w")}
        if len(set(sizes.values())) != 1:
            raise InputError(f"ObservationLayout per-row arrays differ in length: {sizes}")
        for k in ("antenna1", "antenna2"):
            a = getattr(self, k)
            if a.size and (a.min() < 0 or a.max() >= pos.shape[0]):
                raise InputError(f"ObservationLayout.{k} must index the {pos.shape[0]} antennas, "
                                 f"got values {a.min()}..{a.max()}")
        if np.any(self.antenna1 == self.antenna2):
            raise InputError("ObservationLayout has rows with antenna1 == antenna2 (autocorrelations)")
        if not self.integration_time > 0:
            raise InputError(f"ObservationLayout.integration_time must be positive [s], got {self.integration_time}")

    @property
    def n(self) -> int:
        """Number of rows."""
        return self.antenna1.size

    @property
    def n_antennas(self) -> int:
        return self.positions.shape[0]

    def subset(self, index) -> ObservationLayout:
        """The layout of the selected rows (boolean mask or indices); antennas are kept."""
        from dataclasses import replace

        return replace(self, antenna1=self.antenna1[index], antenna2=self.antenna2[index],
                       hour_angle=self.hour_angle[index], scan=self.scan[index], w=self.w[index])

    def describe(self) -> dict:
        """Plain-type summary for provenance records."""
        return {"n_antennas": self.n_antennas, "n_rows": self.n, "n_scans": int(np.unique(self.scan).size),
                "integration_time_s": self.integration_time, "declination_deg": self.declination,
                "latitude_deg": self.latitude}
