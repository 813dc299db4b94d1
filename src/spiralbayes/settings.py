"""Settings dataclasses: each option's default and description written once, for code and TOML alike.

A stage's options (sampling, limits, alternatives, the scan) are the fields of a frozen
dataclass. Each field carries its description (with units) in its metadata; the configuration
schema (:data:`spiralbayes.config.SCHEMA`) is generated from these fields, so a default changed
here changes ``--print-config``, the TOML defaults and the function's default together.

TOML has no ``None``: a field whose default is ``None`` (meaning "automatic") states the value
that spells it in the file (``toml=0``, ``toml=[]``); :func:`from_config` maps it back.

A public function takes ``settings=`` and the few arguments a notebook user changes; its old
keyword arguments still work as ``**overrides`` (:func:`with_overrides`)::

    sample_posterior(vis, disc, bank, settings=SamplingSettings(n_walkers=48), n_steps=2000)
"""

from __future__ import annotations

import dataclasses
import math
import numbers

__all__ = ["DEFAULT_DISTANCE_PC", "DEFAULT_MSTAR_MSUN", "MAX_DISTANCE_PC", "MIN_DISTANCE_PC", "config_options",
           "documented",
           "from_config", "is_finite_number", "is_integer", "option", "with_overrides"]

DEFAULT_DISTANCE_PC = 140.0
"""Distance [pc] assumed when none is given (the Taurus and Lupus star-forming regions are at ~140-160 pc)."""
DEFAULT_MSTAR_MSUN = 0.8
"""Stellar mass [M_sun] assumed when none is given (the paper's fiducial star; M_th = (H/r)^3 M_*)."""
MIN_DISTANCE_PC = 1.0
"""Smallest distance [pc] accepted from a user (no disc is nearer than ~50 pc; below 1 pc is a unit slip)."""
MAX_DISTANCE_PC = 1.0e4
"""Largest distance [pc] accepted from a user: no protoplanetary disc beyond the Galaxy's ~10 kpc is resolved
(a larger value is a unit slip, e.g. metres or au for pc)."""

_NO_TOML = object()


def option(default, doc: str, *, toml=_NO_TOML, config: bool = True):
    """A dataclass field with its description.

    Parameters
    ----------
    default : object
        The default (immutable: a tuple rather than a list).
    doc : str
        One line with the unit and what the value does; shown by ``--print-config``.
    toml : object, optional
        How the TOML file spells a ``None`` default (e.g. ``0`` for "automatic").
    config : bool
        Whether the option appears in the configuration file (False: code only, e.g. a pool).
    """
    metadata = {"doc": doc, "config": config}
    if toml is not _NO_TOML:
        metadata["toml"] = toml
    return dataclasses.field(default=default, metadata=metadata)


def _toml_default(f: dataclasses.Field):
    value = f.metadata.get("toml", f.default)
    return list(value) if isinstance(value, tuple) else value


def config_options(cls, names=None) -> dict[str, tuple[object, str]]:
    """``{key: (TOML default, description)}`` of the configuration fields of a settings class.

    Parameters
    ----------
    cls : type
        A settings dataclass whose fields were made with :func:`option`.
    names : iterable of str, optional
        Only these fields, in this order (default: every configuration field, in field order).
    """
    by_name = {f.name: f for f in dataclasses.fields(cls) if f.metadata.get("config")}
    keys = list(by_name) if names is None else list(names)
    return {key: (_toml_default(by_name[key]), by_name[key].metadata["doc"]) for key in keys}


def from_config(cls, section: dict, **extra):
    """A settings object from a configuration section (keys that are not fields are ignored).

    TOML spellings of ``None`` defaults (``toml=`` of :func:`option`) become ``None`` and lists
    become tuples; ``extra`` sets fields the section does not hold (e.g. a thread count).
    """
    values = {}
    for f in dataclasses.fields(cls):
        if f.name not in section:
            continue
        value = section[f.name]
        if "toml" in f.metadata and value == f.metadata["toml"]:
            value = None
        values[f.name] = tuple(value) if isinstance(value, list) else value
    return cls(**{**values, **extra})


def with_overrides(settings, cls, overrides: dict, where: str):
    """``settings`` (default ``cls()``) with the keyword arguments ``overrides`` applied.

    Raises
    ------
    TypeError
        ``settings`` is not a ``cls``, or an override names no field of it (the message lists them).
    """
    if settings is None:
        settings = cls()
    elif not isinstance(settings, cls):
        raise TypeError(f"{where}: settings must be a {cls.__name__}, got {type(settings).__name__}")
    if not overrides:
        return settings
    names = [f.name for f in dataclasses.fields(cls)]
    unknown = sorted(set(overrides) - set(names))
    if unknown:
        raise TypeError(f"{where}() got unknown keyword argument(s) {unknown}; the {cls.__name__} options are "
                        f"{names}")
    return dataclasses.replace(settings, **overrides)


def is_integer(value) -> bool:
    """Whether ``value`` is an integer (Python or NumPy; ``True``/``False`` are not), for ``__post_init__`` checks."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def is_finite_number(value) -> bool:
    """Whether ``value`` is a finite real number (Python or NumPy; ``True``/``False`` are not)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value)


def documented(cls):
    """Class decorator (outside ``@dataclass``): append an ``Attributes`` section listing every
    :func:`option` field with its description and default to the class docstring, so that
    ``help(cls)`` and the API pages show what ``--print-config`` shows."""
    lines = []
    for f in dataclasses.fields(cls):
        if "doc" not in f.metadata:
            continue
        default = f.metadata.get("toml", f.default) if f.default is None else f.default
        spelled = "automatic" if f.default is None else repr(default)
        lines += [f"    {f.name}", f"        {f.metadata['doc']} (default: {spelled})"]
    if lines:
        doc = (cls.__doc__ or "").rstrip()
        cls.__doc__ = doc + "\n\n    Attributes\n    ----------\n" + "\n".join(lines) + "\n"
    return cls

