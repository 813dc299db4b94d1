"""Atomic file writing and provenance records shared by every writer."""

from __future__ import annotations

import contextlib
import datetime as _dt
import hashlib
import os
import platform
import tempfile
from pathlib import Path

import numpy as np

from ._version import __version__

__all__ = ["atomic_path", "provenance_record", "data_hash", "json_default", "FORMAT_VERSION"]

FORMAT_VERSION = 1
"""Version of spiralbayes' HDF5 layouts; bumped when a layout changes."""


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path beside ``path``; rename it onto ``path`` only on success.

    A crash or exception leaves any existing ``path`` untouched and removes the temporary file.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def data_hash(*arrays) -> str:
    """Short SHA-256 of the given arrays' bytes, to tie results to their input data."""
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:16]


def provenance_record(**extra) -> dict:
    """Package and dependency versions, time and host, plus ``extra`` items."""
    versions = {"spiralbayes": __version__, "numpy": np.__version__, "python": platform.python_version()}
    for mod in ("scipy", "ducc0", "frank", "emcee", "h5py"):
        try:
            versions[mod] = __import__(mod).__version__
        except Exception:  # pragma: no cover - optional or broken install
            pass
    return {
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "versions": versions,
        "format_version": FORMAT_VERSION,
        **extra,
    }


def json_default(obj):
    """``json.dumps(..., default=json_default)``: NumPy scalars and arrays as Python values."""
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    return str(obj)
