"""Reading and writing visibility files: one function per format, and dispatch by extension.

Every reader returns a :class:`~spiralbayes.visibilities.Visibilities` (u, v [lambda], complex V
[Jy], weights [Jy^-2]); every writer accepts one. Formats (``shared/notes/ecosystem.md`` lists
where users' files come from and their pitfalls):

* uvtable ``.txt``/``.dat``/``.csv`` (optionally ``.gz``): :func:`.read_uvtable` /
  :func:`write_uvtable` — frank's layout; uvplot's metre variant is converted with the
  wavelength in its header.
* ``.npz``: :func:`.read_npz` / :func:`write_npz` — frank's keys, or DSHARP ``ExportMS`` keys.
* ``.h5``/``.hdf5``: :func:`.read_hdf5` / :func:`write_hdf5` — spiralbayes' own format, with
  metadata and provenance.
* Measurement Set directories (``.ms``): :func:`read_ms` / :func:`write_ms` — needs
  python-casacore (``pip install "spiralbayes[ms]"``).

:func:`load_visibilities` and :func:`save_visibilities` pick the format from the file
extension. Readers never modify the user's file; writers write to a temporary file beside
the target and rename it into place only on success.

u, v in metres are only ever converted with a wavelength that is given or stated in the file,
never guessed; u, v that are clearly metres but claimed to be wavelengths are refused, and
ambiguous ones warned about (:func:`~spiralbayes.io.checks.check_uv_units`).
:func:`load_visibilities` also checks that the weights look statistical
(:func:`~spiralbayes.io.checks.check_weights`) and warns with the fix when they do not.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from pathlib import Path

from .._hdf5 import require_file
from ..exceptions import InputError
from ..visibilities import Visibilities
from .checks import WeightCheck, check_uv_units, check_weights
from .data_checks import check_duplicate_rows, check_uv_coverage
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
    "WeightCheck",
    "check_uv_units",
    "check_weights",
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
    if (path.is_dir() or suffix in MS_SUFFIXES) and (suffix in MS_SUFFIXES or (path / "table.dat").exists()):
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


def load_visibilities(path, *, check_weights_on_load: bool = True, **kwargs) -> Visibilities:
    """Read visibilities from any supported file, chosen by extension.

    ``.txt/.dat/.csv`` (optionally ``.gz``) → :func:`.read_uvtable`; ``.npz`` →
    :func:`.read_npz`; ``.h5/.hdf5`` → :func:`.read_hdf5`; a directory ending in ``.ms``
    (or any casacore table directory) → :func:`spiralbayes.io.measurement_set.read_ms`.
    Keyword arguments go to that reader (an option the reader does not take raises
    :class:`~spiralbayes.exceptions.InputError` listing those it does). The file is never modified.

    The data are checked on load (:mod:`~spiralbayes.io.data_checks`): a uvtable whose last row
    was cut mid-number and all-zero or one-line uv coverage are refused; exactly repeated rows
    raise a :class:`~spiralbayes.exceptions.DataWarning`.

    With ``check_weights_on_load`` (default) the weights are compared with the scatter of the
    data and a :class:`~spiralbayes.exceptions.DataWarning` says how to fix them when they do
    not look statistical (:func:`.check_weights`).

    Parameters
    ----------
    path : str or Path
        The file (or Measurement Set directory); its extension chooses the reader.
    check_weights_on_load : bool
        Compare the weights with the scatter of the data and warn when they do not look statistical.
    **kwargs
        Options of the reader (e.g. ``wavelength=`` [m] for a uvtable in metres).

    Returns
    -------
    Visibilities
        u, v [λ], V [Jy], weights [Jy⁻²] and the file's provenance, in the package's convention.
    """
    path = require_file(path, "visibility file")
    fmt = _format_of(path)
    readers: dict[str, Callable[..., Visibilities]] = {"ms": read_ms, "uvtable": read_uvtable, "npz": read_npz,
                                                       "hdf5": read_hdf5}
    reader = readers[fmt]
    _check_options(reader, fmt, path, kwargs)
    vis = reader(path, **kwargs)
    check_uv_coverage(vis.u, vis.v, str(path))
    check_duplicate_rows(vis.u, vis.v, vis.V, vis.weights, str(path))
    if check_weights_on_load:
        check_weights(vis, str(path))
    return vis


_OPTION_HINTS = {
    ("ms", "wavelength"): "a Measurement Set states its frequencies (CHAN_FREQ), from which u, v are converted",
    ("ms", "uv_units"): "a Measurement Set stores UVW in metres and is converted with its CHAN_FREQ",
    ("ms", "conjugated"): "Measurement Sets are in the CASA/frank convention",
    ("hdf5", "wavelength"): "spiralbayes' HDF5 files store u, v in wavelengths and the wavelength itself",
    ("hdf5", "uv_units"): "spiralbayes' HDF5 files store u, v in wavelengths",
}


def _check_options(reader, fmt: str, path: Path, kwargs: dict) -> None:
    """Refuse options the chosen reader does not take, with the reason and the ones it does."""
    accepted = [name for name, p in inspect.signature(reader).parameters.items()
                if p.kind is inspect.Parameter.KEYWORD_ONLY]
    for key in kwargs:
        if key not in accepted:
            why = _OPTION_HINTS.get((fmt, key), f"{reader.__name__} does not take it")
            raise InputError(f"{path}: option {key}= does not apply to this {fmt} file ({why}); "
                             f"options of {reader.__name__}: {', '.join(accepted) or 'none'}")


def save_visibilities(vis: Visibilities, path, **kwargs) -> Path:
    """Write ``vis`` in the format given by the extension of ``path`` (see :func:`load_visibilities`).

    Existing files are replaced atomically. Keyword arguments go to the writer.

    Parameters
    ----------
    vis : Visibilities
        The data to write.
    path : str or Path
        The file: ``.txt/.dat/.csv`` (uvtable), ``.npz``, ``.h5/.hdf5`` or a ``.ms`` directory.
    **kwargs
        Options of the writer.

    Returns
    -------
    Path
        The path written.
    """
    path = Path(path)
    fmt = _format_of(path)
    if fmt == "ms":
        return write_ms(vis, path, **kwargs)
    writer = {"uvtable": write_uvtable, "npz": write_npz, "hdf5": write_hdf5}[fmt]
    return writer(vis, path, **kwargs)
