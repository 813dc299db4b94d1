"""Reading and writing visibility files: one function per format, and dispatch by extension.

Every reader returns a :class:`~spiralbayes.visibilities.Visibilities` (u, v [lambda], complex V
[Jy], weights [Jy^-2]); every writer accepts one. Formats (``shared/notes/ecosystem.md`` lists
where users' files come from and their pitfalls):

* uvtable ``.txt``/``.dat``/``.csv`` (optionally ``.gz``): :func:`read_uvtable` /
  :func:`write_uvtable` — frank's layout; uvplot's metre variant is converted with the
  wavelength in its header.
* ``.npz``: :func:`read_npz` / :func:`write_npz` — frank's keys, or DSHARP ``ExportMS`` keys.
* ``.h5``/``.hdf5``: :func:`read_hdf5` / :func:`write_hdf5` — spiralbayes' own format, with
  metadata and provenance.
* Measurement Set directories (``.ms``): :func:`read_ms` / :func:`write_ms` — needs
  python-casacore (``pip install "spiralbayes[ms]"``).

:func:`load_visibilities` and :func:`save_visibilities` pick the format from the file
extension. Readers never modify the user's file; writers write to a temporary file beside
the target and rename it into place only on success.

u, v in metres are only ever converted with a wavelength that is given or stated in the file,
never guessed.
"""

from __future__ import annotations

from pathlib import Path

from .._hdf5 import require_file
from ..exceptions import InputError
from ..visibilities import Visibilities
from .hdf5 import (
    read_hdf5,
    visibilities_from_hdf5_group,
    visibilities_to_hdf5_group,
    write_hdf5,
)
from .measurement_set import read_ms, write_ms
from .npz import read_npz, write_npz
from .uvtable import read_uvtable, write_uvtable

__all__ = [
    "load_visibilities",
    "read_hdf5",
    "read_ms",
    "read_npz",
    "read_uvtable",
    "save_visibilities",
    "visibilities_from_hdf5_group",
    "visibilities_to_hdf5_group",
    "write_hdf5",
    "write_ms",
    "write_npz",
    "write_uvtable",
]

UVTABLE_SUFFIXES = (".txt", ".dat", ".csv")
NPZ_SUFFIXES = (".npz",)
HDF5_SUFFIXES = (".h5", ".hdf5")
MS_SUFFIXES = (".ms",)


def _format_of(path: Path) -> str:
    suffixes = [s.lower() for s in path.suffixes]
    suffix = suffixes[-2] if suffixes and suffixes[-1] == ".gz" and len(suffixes) > 1 else path.suffix.lower()
    if path.is_dir() or suffix in MS_SUFFIXES:
        if suffix in MS_SUFFIXES or (path / "table.dat").exists():
            return "ms"
    if suffix in UVTABLE_SUFFIXES:
        return "uvtable"
    if suffix in NPZ_SUFFIXES:
        return "npz"
    if suffix in HDF5_SUFFIXES:
        return "hdf5"
    supported = UVTABLE_SUFFIXES + NPZ_SUFFIXES + HDF5_SUFFIXES + MS_SUFFIXES
    raise InputError(f"{path}: unknown visibility format {suffix!r}; supported: {', '.join(supported)} "
                     "(or call read_uvtable/read_npz/read_hdf5/read_ms directly)")


def load_visibilities(path, **kwargs) -> Visibilities:
    """Read visibilities from any supported file, chosen by extension.

    ``.txt/.dat/.csv`` (optionally ``.gz``) → :func:`read_uvtable`; ``.npz`` →
    :func:`read_npz`; ``.h5/.hdf5`` → :func:`read_hdf5`; a directory ending in ``.ms``
    (or any casacore table directory) → :func:`spiralbayes.measurement_set.read_ms`.
    Keyword arguments go to that reader. The file is never modified.
    """
    path = require_file(path, "visibility file")
    fmt = _format_of(path)
    if fmt == "ms":
        return read_ms(path, **kwargs)
    reader = {"uvtable": read_uvtable, "npz": read_npz, "hdf5": read_hdf5}[fmt]
    return reader(path, **kwargs)


def save_visibilities(vis: Visibilities, path, **kwargs) -> Path:
    """Write ``vis`` in the format given by the extension of ``path`` (see :func:`load_visibilities`).

    Existing files are replaced atomically. Keyword arguments go to the writer.
    """
    path = Path(path)
    fmt = _format_of(path)
    if fmt == "ms":
        return write_ms(vis, path, **kwargs)
    writer = {"uvtable": write_uvtable, "npz": write_npz, "hdf5": write_hdf5}[fmt]
    return writer(vis, path, **kwargs)
