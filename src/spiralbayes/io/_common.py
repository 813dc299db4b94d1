"""Helpers shared by the visibility readers and writers: provenance records, unit conversion."""

from __future__ import annotations

import hashlib
import json
import logging
from pathlib import Path
from typing import Any

import numpy as np

from .._hdf5 import require_file
from .._provenance import to_json
from ..exceptions import InputError
from ..visibilities import Visibilities
from .checks import check_uv_units

log = logging.getLogger("spiralbayes.io")

_UV_UNIT_ALIASES = {
    "lambda": "lambda", "λ": "lambda", "wavelengths": "lambda", "wle": "lambda",
    "klambda": "klambda", "kλ": "klambda", "kilolambda": "klambda",
    "m": "m", "metre": "m", "metres": "m", "meter": "m", "meters": "m",
}
_UV_UNIT_SCALE = {"lambda": 1.0, "klambda": 1e3}

def _file_sha256(path: Path) -> str:
    """SHA-256 of a file's bytes (read in chunks; the file is opened read-only)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _source_record(path: Path, reader: str, **extra) -> dict:
    """Provenance entry for data read from ``path``."""
    record = {"source": str(path), "reader": reader}
    if path.is_file():
        record["sha256"] = _file_sha256(path)
    record.update(extra)
    return record


def _existing_file(path) -> Path:
    path = require_file(path, "visibility file")
    if path.is_dir():
        raise InputError(f"{path} is a directory; expected a file (a Measurement Set is read with read_ms)")
    return path


def _build(path: Path, **kwargs) -> Visibilities:
    """Construct :class:`Visibilities`, prefixing any validation error with the file name."""
    try:
        return Visibilities(**kwargs)
    except ValueError as exc:
        raise InputError(f"{path}: {exc}") from None


def _normalise_uv_units(uv_units: str | None) -> str | None:
    if uv_units is None:
        return None
    key = str(uv_units).strip().lower()
    if key not in _UV_UNIT_ALIASES:
        raise InputError(f"uv_units={uv_units!r} is not understood: use 'lambda', 'klambda' or 'm'")
    return _UV_UNIT_ALIASES[key]


def _check_wavelength(wavelength, what: str) -> np.ndarray:
    wle = np.asarray(wavelength, dtype=float)
    if not (np.all(np.isfinite(wle)) and np.all(wle > 0)):
        raise InputError(f"{what}: wavelength must be positive and finite [m], got {wavelength!r}")
    return wle


def _uv_to_lambda(u, v, units: str, wavelength, path: Path) -> tuple[np.ndarray, np.ndarray, list]:
    """Convert u, v to wavelengths; return them and the list of conversions applied.

    ``wavelength`` [m] (scalar or one per row) is needed only when ``units == 'm'``.
    """
    if units == "m":
        if wavelength is None:
            raise InputError(
                f"{path}: u, v are in metres but no wavelength is known; pass wavelength=<metres> "
                "(e.g. 299792458 / frequency_Hz) or uv_units='lambda' if they are already in wavelengths"
            )
        wle = _check_wavelength(wavelength, str(path))
        note = "u, v converted from metres with " + (
            f"wavelength {float(wle):.8g} m" if wle.ndim == 0 else "one wavelength per row"
        )
        return np.asarray(u) / wle, np.asarray(v) / wle, [note]
    scale = _UV_UNIT_SCALE[units]
    if scale != 1.0:
        return np.asarray(u) * scale, np.asarray(v) * scale, [f"u, v converted from {units} (x{scale:g})"]
    return np.asarray(u, dtype=float), np.asarray(v, dtype=float), []


def _guard_uv_units(u, v, path: Path, wavelength=None, explicit: bool = False) -> None:
    """u, v believed to be wavelengths: refuse clear metres, warn when ambiguous unless the user
    said they are wavelengths (``explicit``) (:mod:`.checks`)."""
    check_uv_units(u, v, wavelength, str(path), warn_ambiguous=not explicit)


def _scale_weights(weights, weight_factor: float, conversions: list) -> np.ndarray:
    factor = float(weight_factor)
    if not (np.isfinite(factor) and factor > 0):
        raise InputError(f"weight_factor must be a positive number, got {weight_factor!r}")
    if factor != 1.0:
        conversions.append(f"weights multiplied by {factor:g} (weight_factor)")
        return np.asarray(weights, dtype=float) * factor
    return np.asarray(weights, dtype=float)


def _json(obj) -> str:
    """Strict JSON (NaN as null) of a provenance record, for file headers and attributes."""
    return to_json(obj, sort_keys=True)



def _loads_provenance(text: str) -> Any:
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text


def _as_str(x) -> str:
    return x.decode() if isinstance(x, bytes) else str(x)


