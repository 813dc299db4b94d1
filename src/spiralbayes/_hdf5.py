"""One way to tag, write and open spiralbayes' HDF5 files.

Every result file carries ``kind`` (what it holds, e.g. ``"spiralbayes.ScanResult"``) and
``format_version`` root attributes. :func:`write_file` writes through a temporary file that is
renamed into place (:func:`~spiralbayes._provenance.atomic_path`); :func:`open_file` checks the
path, the HDF5 signature and the kind, and turns each failure into one line that names the file.
"""

from __future__ import annotations

import contextlib
from pathlib import Path

from ._provenance import FORMAT_VERSION, atomic_path
from .exceptions import DataFileError, MissingFileError

__all__ = ["open_file", "read_kind", "require_file", "write_file"]


def require_file(path, what: str, hint: str = "") -> Path:
    """``path`` as a :class:`Path`; :class:`MissingFileError` naming ``what`` if it does not exist."""
    path = Path(path)
    if not path.exists():
        raise MissingFileError(f"{what} {path} does not exist" + (f": {hint}" if hint else ""))
    return path


@contextlib.contextmanager
def write_file(path, kind: str):
    """Yield an open, writable ``h5py.File`` tagged ``kind``; it replaces ``path`` only on success."""
    import h5py

    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs["kind"] = kind
        f.attrs["format_version"] = FORMAT_VERSION
        yield f


@contextlib.contextmanager
def open_file(path, kind: str | tuple[str, ...], what: str, mode: str = "r"):
    """Yield an open ``h5py.File`` after checking that it exists, is HDF5 and holds ``kind``.

    Raises
    ------
    MissingFileError
        No file at ``path``.
    DataFileError
        Not an HDF5 file (or truncated), or written as another kind of result.
    """
    import h5py

    path = require_file(path, what)
    kinds = (kind,) if isinstance(kind, str) else tuple(kind)
    try:
        f = h5py.File(path, mode)
    except OSError as exc:
        raise DataFileError(f"{path} is not a readable HDF5 {what} (truncated or corrupt? {_reason(exc)}); "
                            "re-create it, or delete it to start afresh") from None
    with f:
        found = read_kind(f)
        if found not in kinds:
            raise DataFileError(f"{path} is not a spiralbayes {what} (kind = {found!r}, expected {kinds[0]!r})")
        yield f


def read_kind(f) -> str:
    """The ``kind`` attribute of an open file (``""`` when absent)."""
    kind = f.attrs.get("kind", "")
    return kind.decode() if isinstance(kind, bytes) else str(kind)


def _reason(exc: OSError) -> str:
    text = str(exc).split("(", 1)[0].strip()
    return text or exc.__class__.__name__

