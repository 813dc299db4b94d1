"""Atomic file writing, provenance records, content hashes and strict JSON, shared by every writer.

Files are written through :func:`atomic_path` (a temporary file beside the target, renamed into
place only on success, with the permissions the user's umask gives new files). JSON written by
spiralbayes is strict (RFC 8259): :func:`to_json` turns NaN and infinities into ``null``, which
every JSON reader accepts, instead of Python's bare ``NaN``.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import hashlib
import json
import math
import os
import platform
import tempfile
from pathlib import Path

import numpy as np

from ._version import __version__

__all__ = ["atomic_path", "check_output_name", "content_hash", "provenance_record", "data_hash", "json_default",
           "json_safe", "to_json", "FORMAT_VERSION"]

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
    try:
        # mkstemp makes the file private (0600); results on a shared machine should be readable
        # by whoever the user's umask allows, as with a plain open().
        os.fchmod(fd, 0o666 & ~_umask())
    finally:
        os.close(fd)
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def check_output_name(name, what: str) -> str:
    """``name`` if it is a plain file name stem that stays inside its output folder, else InputError.

    Refused: empty names, path separators (``/``, and ``\\`` for Windows users), ``..`` or a
    leading ``.`` (hidden files and parent folders), NUL and other control characters.

    Parameters
    ----------
    name : str
        The configurable name (e.g. ``[sample] run_name``).
    what : str
        The option, for the message.
    """
    from .exceptions import InputError

    text = str(name)
    bad = (not text.strip() or "/" in text or "\\" in text or text.startswith(".") or ".." in text
           or any(ord(c) < 32 for c in text))
    if bad:
        raise InputError(f"{what} = {text!r} must be a plain name (letters, digits, '_', '-'; no '/', '\\', '..' "
                         "or leading '.'): outputs stay inside the output folder")
    return text


def _umask() -> int:
    """The process's umask (read from /proc where possible: setting it to query it is not thread-safe)."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def data_hash(*arrays) -> str:
    """Short SHA-256 of the given arrays' bytes, to tie results to their input data."""
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:16]


def content_hash(*items) -> str:
    """Short SHA-256 of arrays (values, dtype and shape) and JSON-able objects, in order.

    Used for resume keys: two inputs that give different results must hash differently, so the
    array's dtype and shape are hashed with its bytes, and dicts with sorted keys.
    """
    h = hashlib.sha256()
    for item in items:
        if isinstance(item, np.ndarray) or np.isscalar(item) and isinstance(item, np.generic):
            a = np.ascontiguousarray(item)
            h.update(f"{a.dtype.str}{a.shape}".encode())
            h.update(a.tobytes())
        else:
            h.update(to_json(item, sort_keys=True).encode())
        h.update(b"|")
    return h.hexdigest()[:16]


def provenance_record(**extra) -> dict:
    """Package and dependency versions, time and host, plus ``extra`` items."""
    versions = {"spiralbayes": __version__, "numpy": np.__version__, "python": platform.python_version()}
    for mod in ("scipy", "ducc0", "frank", "emcee", "h5py"):
        with contextlib.suppress(Exception):  # an optional or broken install is left out of the record
            versions[mod] = __import__(mod).__version__
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


def json_safe(obj):
    """``obj`` with NumPy values made Python values and non-finite floats made ``None`` (recursively)."""
    if isinstance(obj, dict):
        return {str(k): json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return json_safe(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if obj is None or isinstance(obj, (str, int, bool)):
        return obj
    return json_safe(json_default(obj))


def to_json(obj, **kwargs) -> str:
    """Strict JSON text of ``obj`` (:func:`json_safe`: NaN and infinities become ``null``)."""
    return json.dumps(json_safe(obj), allow_nan=False, **kwargs)
