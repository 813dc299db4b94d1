"""spiralbayes' own HDF5 visibility format (with metadata and provenance)."""

from __future__ import annotations

import logging
from dataclasses import replace
from pathlib import Path

import numpy as np

from .._hdf5 import checked_dataset
from .._provenance import FORMAT_VERSION, atomic_path
from ..exceptions import DataFileError, InputError
from ..visibilities import Visibilities
from ._common import _as_str, _existing_file, _guard_uv_units, _json, _loads_provenance, _source_record


__all__ = ["read_hdf5", "write_hdf5", "visibilities_from_hdf5_group", "visibilities_to_hdf5_group"]

log = logging.getLogger(__name__)

_H5_TYPE = "spiralbayes.Visibilities"
_H5_DATASETS = ("u", "v", "V", "weights")
_H5_ROW_DATASETS = ("antenna1", "antenna2", "time")  # optional: written only when the data carry them


def visibilities_to_hdf5_group(vis: Visibilities, group) -> None:
    """Store ``vis`` in an open ``h5py.Group`` (datasets u, v, V, weights; metadata as attributes).

    Datasets ``antenna1``, ``antenna2`` (int) and ``time`` [s] are added when ``vis`` has them.
    Attributes: ``spiralbayes_type``, ``format_version``, ``wavelength`` [m] (NaN when
    unknown), ``conjugated``, ``provenance`` (JSON), ``units``.
    """
    for name in _H5_DATASETS:
        checked_dataset(group, name, getattr(vis, name))  # checksummed: corruption fails to read
    for name in _H5_ROW_DATASETS:
        if getattr(vis, name) is not None:
            checked_dataset(group, name, getattr(vis, name))
    group.attrs["spiralbayes_type"] = _H5_TYPE
    group.attrs["format_version"] = FORMAT_VERSION
    group.attrs["wavelength"] = np.nan if vis.wavelength is None else vis.wavelength
    group.attrs["conjugated"] = bool(vis.conjugated)
    group.attrs["provenance"] = _json(vis.provenance)
    group.attrs["units"] = "u, v: lambda; V: Jy; weights: Jy^-2 (1/sigma^2 of Re and Im); wavelength: m"


def visibilities_from_hdf5_group(group, source: str = "") -> Visibilities:
    """Read a :class:`Visibilities` written by :func:`visibilities_to_hdf5_group`."""
    where = source or group.name
    missing = [name for name in _H5_DATASETS if name not in group]
    if missing:
        raise InputError(f"{where}: missing dataset(s) {missing}; a spiralbayes visibility file holds "
                         f"datasets {list(_H5_DATASETS)} (write one with save_visibilities)")
    version = int(group.attrs.get("format_version", FORMAT_VERSION))
    if version > FORMAT_VERSION:
        raise InputError(f"{where}: format_version {version} is newer than this spiralbayes understands "
                         f"({FORMAT_VERSION}); upgrade spiralbayes")
    wle = float(group.attrs.get("wavelength", np.nan))
    prov = _loads_provenance(_as_str(group.attrs.get("provenance", "{}")))
    rows = {name: group[name][()] for name in _H5_ROW_DATASETS if name in group}
    return Visibilities(
        u=group["u"][()], v=group["v"][()], V=group["V"][()], weights=group["weights"][()],
        wavelength=wle if np.isfinite(wle) else None, conjugated=bool(group.attrs.get("conjugated", False)),
        provenance=prov if isinstance(prov, dict) else {"written_provenance": prov}, **rows,
    )


def read_hdf5(path, *, group: str = "/") -> Visibilities:
    """Read visibilities from spiralbayes' HDF5 format (see :func:`write_hdf5`).

    Parameters
    ----------
    path : str or Path
    group : str
        HDF5 group holding the datasets (default the root).

    Returns
    -------
    Visibilities
        With the stored provenance, plus ``loaded_from`` (path, SHA-256 of the file).
    """
    import h5py

    path = _existing_file(path)
    try:
        fh = h5py.File(path, "r")
    except OSError as exc:
        raise DataFileError(f"{path}: not a readable HDF5 file (truncated or corrupt? {_one_line(exc)}); "
                            "re-create or re-download it") from None
    with fh:
        if group not in fh:
            raise InputError(f"{path}: no group {group!r} in the file (groups: {list(fh.keys())})")
        try:
            vis = visibilities_from_hdf5_group(fh[group], source=str(path))
        except (OSError, KeyError, TypeError) as exc:  # h5py on a truncated or half-written file
            raise DataFileError(f"{path}: incomplete or corrupt visibility file ({_one_line(exc)}); "
                                "re-create or re-download it") from None
        except ValueError as exc:
            msg = str(exc)
            raise InputError(msg if msg.startswith(str(path)) else f"{path}: {msg}") from None
    _guard_uv_units(vis.u, vis.v, path, vis.wavelength)
    loaded = _source_record(path, "read_hdf5", format="spiralbayes hdf5")
    return replace(vis, provenance={**vis.provenance, "loaded_from": loaded})


def write_hdf5(vis: Visibilities, path) -> Path:
    """Write ``vis`` to an HDF5 file (datasets u, v [lambda], V [Jy], weights [Jy^-2]).

    With antennas recorded, also ``antenna1``, ``antenna2`` and ``time`` [s].

    Root attributes: ``wavelength`` [m] (NaN if unknown), ``conjugated``, ``provenance``
    (JSON string), ``format_version`` (``spiralbayes._provenance.FORMAT_VERSION``).
    Written to a temporary file and renamed into place.
    """
    import h5py

    path = Path(path)
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as fh:
        visibilities_to_hdf5_group(vis, fh)
    log.info("wrote %d visibilities to %s", vis.n, path)
    return path


def _one_line(exc: Exception) -> str:
    text = " ".join(str(exc).split()) or exc.__class__.__name__
    return text if len(text) <= 200 else text[:197] + "..."
