"""frank-style ASCII uvtables (``.txt``, ``.dat``, ``.csv``, optionally ``.gz``).

Columns u [lambda], v [lambda], Re V [Jy], Im V [Jy], weight [Jy^-2]; uvplot's variant with u, v
in metres and the wavelength in a header line is converted with that wavelength.
"""

from __future__ import annotations

import gzip
import logging
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._provenance import atomic_path
from .data_checks import check_last_row
from ..exceptions import InputError
from ..visibilities import Visibilities
from ._common import (
    _UV_UNIT_ALIASES,
    _build,
    _check_wavelength,
    _existing_file,
    _json,
    _loads_provenance,
    _normalise_uv_units,
    _scale_weights,
    _source_record,
    _uv_to_lambda,
    _guard_uv_units,
)

__all__ = ["read_uvtable", "write_uvtable"]

log = logging.getLogger(__name__)

_WLE_RE = re.compile(r"(?:wavelength|wle)\s*(?:\[\s*m\s*\])?\s*[=:]\s*([-+]?[0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)",
                     re.IGNORECASE)
_U_UNIT_RE = re.compile(r"(?<![A-Za-z(])u\s*\[\s*([^\]\s]+)\s*\]")
_CONJ_RE = re.compile(r"conjugated\s*[=:]\s*(true|false)", re.IGNORECASE)
_COLUMNS_RE = re.compile(r"columns\s*:?(.*)", re.IGNORECASE)
_UVTABLE_LAYOUT = "u [lambda], v [lambda], Re V [Jy], Im V [Jy], weight [Jy^-2]"


@dataclass
class _UVTableHeader:
    wavelength: float | None = None
    uv_units: str | None = None
    conjugated: bool | None = None
    columns: list[str] = field(default_factory=list)
    provenance: Any = None
    first_data_line: str = ""


def _open_text(path: Path):
    return gzip.open(path, "rt") if path.suffix.lower() == ".gz" else open(path, encoding="utf-8",
                                                                             errors="replace")


def _parse_uvtable_header(path: Path) -> _UVTableHeader:
    """Read the leading ``#`` comment lines: wavelength, u/v units, conjugation, column names."""
    header = _UVTableHeader()
    with _open_text(path) as fh:
        for line in fh:
            text = line.strip()
            if not text:
                continue
            if not text.startswith("#"):
                header.first_data_line = text
                break
            _parse_header_line(text.lstrip("#").strip(), header)
    return header


def _parse_header_line(text: str, header: _UVTableHeader) -> None:
    if text.lower().startswith("provenance:"):
        header.provenance = _loads_provenance(text.split(":", 1)[1].strip())  # from write_uvtable
        return
    if header.wavelength is None and (m := _WLE_RE.search(text)):
        header.wavelength = float(m.group(1))
    if header.uv_units is None and (m := _U_UNIT_RE.search(text)):
        unit = m.group(1).lower()
        header.uv_units = _UV_UNIT_ALIASES.get(unit)
        if header.uv_units is None:
            log.warning("unrecognised u unit %r in header line %r (ignored)", unit, text)
    if header.conjugated is None and (m := _CONJ_RE.search(text)):
        header.conjugated = m.group(1).lower() == "true"
    if not header.columns and (m := _COLUMNS_RE.match(text)):
        header.columns = [c for c in re.split(r"[\s,]+", m.group(1).strip()) if c]


def _column_layout(path: Path, ncols: int, names: list[str]) -> dict[str, int]:
    """Indices of u, v, Re, Im, weight (and per-row wavelength) in a table of ``ncols`` columns."""
    base = [re.sub(r"\[.*?\]|\(.*?\)", "", n).strip().lower() for n in names] if len(names) == ncols else []
    if ncols == 5:
        return {"u": 0, "v": 1, "re": 2, "im": 3, "weight": 4}
    if ncols == 6 and base and base[2] == "w":
        return {"u": 0, "v": 1, "re": 3, "im": 4, "weight": 5}
    if ncols == 6 and base and base[5] in ("lambda", "wle", "wavelength"):
        return {"u": 0, "v": 1, "re": 2, "im": 3, "weight": 4, "wavelength": 5}
    declared = f" (header declares columns {names})" if names else ""
    raise InputError(
        f"{path}: found {ncols} columns{declared}, expected 5: {_UVTABLE_LAYOUT}; "
        "6 columns are accepted only when a '# Columns:' header names a third column 'w' "
        "or a sixth column 'lambda[m]'. Rewrite the file with the 5 columns in that order"
    )


def _load_table(path: Path, first_line: str) -> np.ndarray:
    if not first_line:
        raise InputError(f"{path}: no data rows found (only comments or blank lines); expected "
                         f"rows of {_UVTABLE_LAYOUT}")
    delimiter = "," if "," in first_line else None
    try:
        table = np.loadtxt(path, comments="#", delimiter=delimiter, ndmin=2, dtype=float)
    except ValueError as exc:
        raise InputError(
            f"{path}: could not parse the table ({exc}); expected every row to hold the 5 numbers "
            f"{_UVTABLE_LAYOUT}, separated by whitespace or commas"
        ) from None
    return table


def read_uvtable(
    path,
    *,
    uv_units: str | None = None,
    wavelength: float | None = None,
    conjugated: bool | None = None,
    weight_factor: float = 1.0,
) -> Visibilities:
    """Read a frank-style ASCII uvtable.

    Columns: u, v, Re V [Jy], Im V [Jy], weight [Jy^-2], separated by whitespace or commas;
    lines starting with ``#`` are comments. Two 6-column variants are understood when a
    ``# Columns:`` header names them: uvplot's older export (u, v, **w**, Re, Im, weight)
    and a per-row wavelength column (u, v, Re, Im, weight, ``lambda[m]``).

    Parameters
    ----------
    path : str or Path
        The file (``.gz`` compressed files are read too).
    uv_units : {'lambda', 'klambda', 'm'}, optional
        Units of the u, v columns. Default: what the header declares (e.g. uvplot's
        ``# Columns: u[m] v[m] ...``), else wavelengths (frank's layout). An explicit value
        overrides the header (with a logged warning when they disagree).
    wavelength : float, optional
        Observing wavelength [m]. Needed when u, v are in metres; defaults to the header's
        ``# wavelength[m] = ...`` line (uvplot writes the mean wavelength there). u, v in
        metres without any wavelength raise :class:`ValueError` — they are never guessed.
    conjugated : bool, optional
        Whether V is the complex conjugate of the frank/galario convention. Default: the
        header's ``# conjugated = ...`` line (written by :func:`write_uvtable`), else False.
    weight_factor : float
        Multiply the weights by this (e.g. 2 for uvplot exports, whose polarisation average
        halves the weights relative to visread and the DSHARP scripts). Recorded in provenance.

    Returns
    -------
    Visibilities

    Raises
    ------
    ValueError
        Wrong number of columns, unparsable rows, no rows, metres without a wavelength, or
        invalid values (NaN/inf, negative weights); the message names the file.
    FileNotFoundError
        If ``path`` does not exist.
    """
    path = _existing_file(path)
    check_last_row(path)
    header = _parse_uvtable_header(path)
    table = _load_table(path, header.first_data_line)
    cols = _column_layout(path, table.shape[1], header.columns)
    units = _resolve_units(path, _normalise_uv_units(uv_units), header.uv_units)
    wle = _resolve_wavelength(path, wavelength, header.wavelength)
    row_wle = table[:, cols["wavelength"]] if "wavelength" in cols else None
    u, v, conversions = _uv_to_lambda(
        table[:, cols["u"]], table[:, cols["v"]], units, row_wle if row_wle is not None else wle, path
    )
    if wle is None and row_wle is not None:
        wle = float(np.mean(row_wle))
    if units != "m":
        _guard_uv_units(u, v, path, wle, explicit=uv_units is not None)
    weights = _scale_weights(table[:, cols["weight"]], weight_factor, conversions)
    conj = bool(header.conjugated) if conjugated is None else bool(conjugated)
    prov = _source_record(path, "read_uvtable", format="uvtable", uv_units=units,
                          conversions=conversions, n_rows=int(table.shape[0]))
    if header.provenance is not None:
        prov["written_provenance"] = header.provenance
    return _build(path, u=u, v=v, V=table[:, cols["re"]] + 1j * table[:, cols["im"]], weights=weights,
                  wavelength=wle, conjugated=conj, provenance=prov)


def _resolve_units(path: Path, given: str | None, declared: str | None) -> str:
    if given is not None:
        if declared is not None and declared != given:
            log.warning("%s: header declares u, v in %s but uv_units=%r was given; using %r",
                        path, declared, given, given)
        return given
    return declared or "lambda"


def _resolve_wavelength(path: Path, given, declared) -> float | None:
    if given is None:
        return declared
    given = float(_check_wavelength(given, str(path)))
    if declared is not None and abs(declared - given) > 1e-6 * given:
        log.warning("%s: header wavelength %.8g m differs from wavelength=%.8g m; using the latter",
                    path, declared, given)
    return given


def write_uvtable(vis: Visibilities, path, *, delimiter: str | None = None) -> Path:
    """Write ``vis`` as a frank-style uvtable (u [lambda], v [lambda], Re, Im [Jy], weight [Jy^-2]).

    Numbers are written with 17 significant digits, so reading the file back reproduces
    the arrays exactly. The header records the wavelength (uvplot's ``wavelength[m] =``
    form), the conjugation flag and the provenance (one JSON line). Written atomically.

    Parameters
    ----------
    vis : Visibilities
    path : str or Path
        Target file; ``.csv`` files are comma separated unless ``delimiter`` is given.
    delimiter : str, optional
        Column separator; default a tab (a comma for ``.csv``).

    Returns
    -------
    Path
        The file written.
    """
    path = Path(path)
    if delimiter is None:
        delimiter = "," if path.suffix.lower() == ".csv" else "\t"
    lines = ["spiralbayes uvtable (frank layout)"]
    if vis.wavelength is not None:
        lines.append(f"wavelength[m] = {vis.wavelength!r}")
    lines += [f"conjugated = {vis.conjugated}", "provenance: " + _json(vis.provenance),
              "Columns:\tu[lambda]\tv[lambda]\tRe(V)[Jy]\tIm(V)[Jy]\tweight[Jy^-2]"]
    table = np.column_stack([vis.u, vis.v, vis.V.real, vis.V.imag, vis.weights])
    with atomic_path(path) as tmp:
        opener = gzip.open if path.suffix.lower() == ".gz" else open
        with opener(tmp, "wb") as fh:
            np.savetxt(fh, table, fmt="%.17g", delimiter=delimiter, header="\n".join(lines))
    log.info("wrote %d visibilities to %s", vis.n, path)
    return path
