"""One way to tag, write and open spiralbayes' HDF5 files.

Every result file carries ``kind`` (what it holds, e.g. ``"spiralbayes.ScanResult"``) and
``format_version`` root attributes. :func:`write_file` writes through a temporary file that is
renamed into place (:func:`~spiralbayes._provenance.atomic_path`); :func:`open_file` checks the
path, the HDF5 signature and the kind, and turns each failure into one line that names the file —
also failures while reading inside the ``with`` block (a truncated file often opens but cannot
give its datasets back; a missing attribute or an unparsable JSON attribute means the same).
:func:`open_reference` opens, checks and reports alike the files spiralbayes reads but does not write
(reduced simulations), which carry no ``kind``.

Result classes are written and read by one routine, :func:`save_dataclass` / :func:`load_dataclass`,
which walks the dataclass's fields (layout version :data:`RESULT_LAYOUT_VERSION`):

* a NumPy array becomes a dataset with a Fletcher-32 checksum (strings as UTF-8 bytes, marked by
  the dataset attribute ``text = True``; a field's ``metadata["units"]`` becomes its ``units``);
* a nested dataclass becomes a group (attribute ``dataclass = "module:QualName"``), a list or a
  dict of dataclasses a group of such groups (``container = "list"`` or ``"dict"``);
* anything else (numbers, strings, None, dicts and lists of them) an attribute holding JSON
  (Python's dialect, so NaN and infinities come back as they were).

Files of an older layout are read by the reader the class names for that version (the
``format_version`` root attribute says which); any other version is refused with a message that
names it.
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib
import json
from pathlib import Path

from ._provenance import FORMAT_VERSION, atomic_path, json_default
from .exceptions import DataFileError, InputError, MissingFileError, SpiralbayesError

__all__ = ["RESULT_LAYOUT_VERSION", "checked_dataset", "load_dataclass", "open_file", "open_reference", "read_kind",
           "refuse_other_kind", "require_file", "save_dataclass", "write_file"]

RESULT_LAYOUT_VERSION = 2
"""``format_version`` of files written by :func:`save_dataclass` (1: the hand-written per-class layouts)."""


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
    kinds = (kind,) if isinstance(kind, str) else tuple(kind)
    with _checked_open(path, kinds, what, mode) as f:
        yield f


@contextlib.contextmanager
def open_reference(path, what: str):
    """Yield a read-only ``h5py.File`` that spiralbayes reads but did not write (no ``kind`` attribute
    is required: a reduced simulation file, ``tests/data/references/...``).

    The file is checked and its read failures are reported as :func:`open_file` does
    (:class:`~spiralbayes.exceptions.MissingFileError`, :class:`~spiralbayes.exceptions.DataFileError`
    naming the file).
    """
    with _checked_open(path, None, what, "r") as f:
        yield f


@contextlib.contextmanager
def _checked_open(path, kinds: tuple[str, ...] | None, what: str, mode: str):
    """:func:`open_file`'s checks; ``kinds`` None accepts a file of any kind (or none)."""
    import h5py

    path = require_file(path, what)
    try:
        f = h5py.File(path, mode)
    except OSError as exc:
        raise DataFileError(f"{path} is not a readable HDF5 {what} (truncated or corrupt? {_reason(exc)}); "
                            "re-create it, or delete it to start afresh") from None
    with f:
        found = read_kind(f)
        if kinds is not None and found not in kinds:
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


# -- the dataclass-driven layout ------------------------------------------------------------------
def save_dataclass(obj, path, kind: str) -> Path:
    """Write the dataclass ``obj`` to ``path`` (atomically) in the layout of the module docstring."""
    with write_file(path, kind) as f:
        f.attrs["format_version"] = RESULT_LAYOUT_VERSION
        _write_fields(f, obj)
    return Path(path)


def load_dataclass(cls, path, kind: str, what: str, legacy: dict | None = None):
    """Read an instance of ``cls`` written by :func:`save_dataclass`.

    Parameters
    ----------
    cls : type
        The dataclass.
    path : path
    kind : str
        The file's expected ``kind`` attribute.
    what : str
        What the file is, for messages ("scan result").
    legacy : dict, optional
        ``{format_version: reader}`` for older layouts; ``reader(f)`` gets the open file and
        returns the instance.

    Raises
    ------
    DataFileError
        Missing, corrupt, of another kind, or of a layout version this spiralbayes cannot read.
    """
    legacy = legacy or {}
    with open_file(path, kind, what) as f:
        version = int(f.attrs.get("format_version", -1))
        if version == RESULT_LAYOUT_VERSION:
            return _read_fields(f, cls)
        if version in legacy:
            return legacy[version](f)
        known = sorted({RESULT_LAYOUT_VERSION, *legacy})
        newer = " (newer than this spiralbayes: upgrade it)" if version > RESULT_LAYOUT_VERSION else ""
        raise DataFileError(f"{path} is a {what} of format_version {version}{newer}; this spiralbayes reads "
                            f"format_version {', '.join(map(str, known))}: re-create the file")


def _write_fields(group, obj) -> None:
    cls = type(obj)
    group.attrs["dataclass"] = f"{cls.__module__}:{cls.__qualname__}"
    for fld in dataclasses.fields(obj):
        _write_value(group, fld.name, getattr(obj, fld.name), fld.metadata)


def _write_value(group, name: str, value, metadata=None) -> None:
    import numpy as np

    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        _write_fields(group.create_group(name), value)
    elif isinstance(value, np.ndarray):
        text = value.dtype.kind in "UO"
        data = np.char.encode(value.astype(str), "utf-8") if text else value
        ds = checked_dataset(group, name, data)
        if text:
            ds.attrs["text"] = True
        if metadata and "units" in metadata:
            ds.attrs["units"] = metadata["units"]
    elif _holds_dataclasses(value):
        sub = group.create_group(name)
        items = list(value.items() if isinstance(value, dict) else enumerate(value))
        sub.attrs["container"] = "dict" if isinstance(value, dict) else "list"
        sub.attrs["order"] = json.dumps([str(k) for k, _ in items])
        for key, item in items:
            _write_fields(sub.create_group(str(key)), item)
    else:
        group.attrs[name] = json.dumps(value, default=json_default)


def _holds_dataclasses(value) -> bool:
    items = value.values() if isinstance(value, dict) else value if isinstance(value, (list, tuple)) else ()
    items = list(items)
    return bool(items) and all(dataclasses.is_dataclass(v) and not isinstance(v, type) for v in items)


def _read_fields(group, cls=None):
    cls = cls or _resolve(group.attrs["dataclass"])
    kwargs = {}
    for fld in dataclasses.fields(cls):
        if not fld.init:
            continue
        if fld.name in group:
            kwargs[fld.name] = _read_item(group[fld.name])
        elif fld.name in group.attrs:
            kwargs[fld.name] = json.loads(group.attrs[fld.name])
        elif fld.default is dataclasses.MISSING and fld.default_factory is dataclasses.MISSING:
            raise KeyError(f"{cls.__name__}.{fld.name} is missing")
    return cls(**kwargs)


def _read_item(item):
    import h5py
    import numpy as np

    if isinstance(item, h5py.Dataset):
        data = item[()]
        if item.attrs.get("text", False):
            data = np.char.decode(np.asarray(data), "utf-8")
        return data
    container = item.attrs.get("container")
    if container is None:
        return _read_fields(item)
    keys = json.loads(item.attrs["order"])
    if container == "dict":
        return {k: _read_fields(item[k]) for k in keys}
    return [_read_fields(item[k]) for k in keys]


def _resolve(name) -> type:
    """The dataclass named ``"module:QualName"``; only spiralbayes' own classes are accepted."""
    name = name.decode() if isinstance(name, bytes) else str(name)
    module, _, qualname = name.partition(":")
    if module.split(".")[0] != "spiralbayes":
        raise InputError(f"group of class {name!r}: only spiralbayes classes are read back")
    obj = importlib.import_module(module)
    for part in qualname.split("."):
        obj = getattr(obj, part)
    if not dataclasses.is_dataclass(obj):
        raise InputError(f"group of class {name!r}: not a dataclass")
    return obj
