"""One way to tag, write and open spiralbayes' HDF5 files.

Every result file carries ``kind`` (what it holds, e.g. ``"spiralbayes.ScanResult"``) and
``format_version`` root attributes. :func:`write_file` writes through a temporary file that is
renamed into place (:func:`~spiralbayes._provenance.atomic_path`); :func:`open_file` checks the
path, the HDF5 signature and the kind, and turns each failure into one line that names the file —
also failures while reading inside the ``with`` block (a truncated file often opens but cannot
give its datasets back; a missing attribute or an unparsable JSON attribute means the same).
"""

from __future__ import annotations

import contextlib
import json
from pathlib import Path

from ._provenance import FORMAT_VERSION, atomic_path
from .exceptions import DataFileError, InputError, MissingFileError, SpiralbayesError

__all__ = ["checked_dataset", "open_file", "read_kind", "refuse_other_kind", "require_file", "write_file"]


def require_file(path, what: str, hint: str = "") -> Path:
    """``path`` as a :class:`Path`; :class:`MissingFileError` naming ``what`` if it does not exist."""
    path = Path(path)
    if not path.exists():
        raise MissingFileError(f"{what} {path} does not exist" + (f": {hint}" if hint else ""))
    return path


def checked_dataset(group, name: str, data, **kwargs):
    """Create dataset ``name`` with a Fletcher-32 checksum, so that a corrupted file fails to read.

    HDF5 verifies the checksum of every chunk it reads and raises ``OSError`` on a mismatch, which
    :func:`open_file` reports as a corrupt file; without it flipped bytes in raw data would be read
    back as wrong numbers. Scalars and empty arrays (which cannot be chunked) are stored plainly.
    """
    import numpy as np

    data = np.asarray(data)
    if data.ndim == 0 or data.size == 0:
        return group.create_dataset(name, data=data, **kwargs)
    return group.create_dataset(name, data=data, fletcher32=True, **kwargs)


@contextlib.contextmanager
def write_file(path, kind: str):
    """Yield an open, writable ``h5py.File`` tagged ``kind``; it replaces ``path`` only on success."""
    import h5py

    refuse_other_kind(path, kind)
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs["kind"] = kind
        f.attrs["format_version"] = FORMAT_VERSION
        yield f


def refuse_other_kind(path, kind: str) -> None:
    """Raise :class:`~spiralbayes.exceptions.InputError` if ``path`` holds another kind of spiralbayes result.

    No command overwrites a result of another kind (a chain file written onto ``scan.h5`` lost the
    scan). Files that are not spiralbayes HDF5 results (no ``kind``) are not judged here.
    """
    import h5py

    path = Path(path)
    if not path.is_file():
        return
    try:
        with h5py.File(path, "r") as f:
            found = read_kind(f)
    except OSError:  # not HDF5, or damaged: the writer replaces it as before
        return
    if found and found != kind:
        raise InputError(f"{path} holds another kind of result ({found}), refusing to overwrite it with a "
                         f"{kind}: choose another output name or folder, or delete the file")


@contextlib.contextmanager
def open_file(path, kind: str | tuple[str, ...], what: str, mode: str = "r"):
    """Yield an open ``h5py.File`` after checking that it exists, is HDF5 and holds ``kind``.

    Raises
    ------
    MissingFileError
        No file at ``path``.
    DataFileError
        Not an HDF5 file (or truncated), written as another kind of result, or unreadable while
        the block reads it (``OSError``, a missing dataset or attribute, bad JSON, or a content
        check of the caller failing: all re-raised with the file's name and the fix).
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
        try:
            yield f
        except DataFileError:
            raise
        except SpiralbayesError as exc:  # the content failed the reader's checks
            raise DataFileError(f"{path}: {exc}") from None
        except (OSError, KeyError, json.JSONDecodeError, ValueError, TypeError) as exc:
            # h5py raises OSError/KeyError for truncated or half-written files, ValueError/TypeError
            # for datasets of the wrong shape or type
            raise DataFileError(f"{path} is an incomplete or corrupt {what} ({exc.__class__.__name__}: "
                                f"{_reason(exc)}); re-create it, or delete it to start afresh") from None


def read_kind(f) -> str:
    """The ``kind`` attribute of an open file (``""`` when absent)."""
    kind = f.attrs.get("kind", "")
    return kind.decode() if isinstance(kind, bytes) else str(kind)


def _reason(exc: Exception) -> str:
    """The exception's message on one line (at most 200 characters)."""
    text = " ".join(str(exc).split()).strip("'\"")
    text = text or exc.__class__.__name__
    return text if len(text) <= 200 else text[:197] + "..."

