"""What every result class offers: the :class:`Result` protocol and the :class:`ResultMixin` that implements it.

A result (a scan, a verdict, limits, completeness, a forecast, a posterior, ...) is a dataclass that

* ``summary()`` says in words what it found (a ``str``, a few sentences or a small table);
* ``to_dict()`` gives its content as JSON-safe values (``json.dumps`` accepts it; NaN becomes
  ``None``), plus derived quantities a reader would want;
* ``save(path)`` writes it to HDF5 atomically and ``load(path)`` reads it back, both through the one
  dataclass-driven layout of ``spiralbayes._hdf5``;
* prints on one line (``repr``);
* where it ranks candidates (scan instances, alternative models, templates), exposes the winner
  as the read-only property ``best``: an object with attributes, not a dict
  (:class:`~spiralbayes.inference.scan.ScanPeak`, :class:`~spiralbayes.inference.detection.AlternativeFit`,
  :class:`~spiralbayes.inference.posterior.TemplateRun`).

The protocol follows ``typing.Protocol`` (structural: a class need not inherit from it);
:class:`ResultMixin` is the shared implementation the package's result classes use.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from ._hdf5 import load_dataclass, save_dataclass
from ._provenance import json_safe

__all__ = ["Result", "ResultMixin", "fields_dict"]


@runtime_checkable
class Result(Protocol):
    """The interface of every spiralbayes result class (see the module docstring)."""

    def summary(self) -> str: ...

    def to_dict(self) -> dict: ...

    def save(self, path) -> Path: ...

    @classmethod
    def load(cls, path) -> Result: ...


def fields_dict(obj) -> dict:
    """A dataclass's fields as JSON-safe values (nested dataclasses as dicts, NaN as None)."""
    return json_safe({f.name: _plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)})


def _plain(value):
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return fields_dict(value)
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


class ResultMixin:
    """``save``/``load``/``to_dict``/``repr`` of a result dataclass, driven by its fields.

    A subclass sets ``KIND`` (the file's ``kind`` attribute) and ``WHAT`` (words for messages),
    optionally ``LEGACY_READERS`` (``{format_version: reader(open h5py file)}`` for files written
    before the dataclass layout), and writes its own ``summary``. Decorate it with
    ``@dataclass(repr=False)`` to keep the one-line ``__repr__``.
    """

    KIND: str = ""
    WHAT: str = "result"
    LEGACY_READERS: dict = {}
    # set by the subclass's @dataclass; declared so that the checker accepts dataclasses.fields(self)
    __dataclass_fields__: ClassVar[dict[str, dataclasses.Field[Any]]]

    def save(self, path) -> Path:
        """Write to HDF5, atomically (``spiralbayes._hdf5.save_dataclass``)."""
        return save_dataclass(self, path, self.KIND)

    @classmethod
    def load(cls, path):
        """Read a file written by :meth:`save` (or by an older spiralbayes, see ``LEGACY_READERS``).

        Raises :class:`~spiralbayes.exceptions.DataFileError` naming the file when it is missing,
        truncated, corrupt, of another kind or of an unknown layout version.
        """
        return load_dataclass(cls, path, cls.KIND, cls.WHAT, cls.LEGACY_READERS)

    def to_dict(self) -> dict:
        """The fields as JSON-safe values."""
        return fields_dict(self)

    def summary(self) -> str:  # pragma: no cover - every result class writes its own
        raise NotImplementedError

    def __repr__(self) -> str:
        parts = []
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, np.ndarray):
                text = f"array{value.shape}"
            elif isinstance(value, (list, dict)):
                text = f"<{len(value)} items>"
            elif isinstance(value, float):
                text = f"{value:.6g}"
            elif isinstance(value, (int, bool, str)) or value is None:
                text = repr(value)
            else:
                text = type(value).__name__
            parts.append(f"{f.name}={text}")
        return f"{type(self).__name__}({', '.join(parts)})".replace("\n", " ")
