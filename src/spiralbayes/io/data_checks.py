"""Load-time checks of what the numbers in a visibility file can mean.

Each check refuses data no search can use (:class:`~spiralbayes.exceptions.InputError`) or warns
(:class:`~spiralbayes.exceptions.DataWarning`) with the fix in the message:

* :func:`check_duplicate_rows` — rows that repeat another exactly (u, v, V and weight) count the
  same measurement twice: χ² and every Δχ² scale with the number of copies (an export written
  twice doubled Δχ² 3.3 → 5.9). Warned, with the count and the fix.
* :func:`check_uv_coverage` — every baseline of zero length (u = v = 0) or all baselines on one
  line through the origin (rank-1 uv coverage): no azimuthal structure, and no geometry, can be
  constrained. Refused.
* :func:`check_last_row` — a uvtable whose last row was cut mid-number (another field count, a
  lost exponent or integer digits, with or without a final newline) reads a wrong weight or V
  silently (29614.8 read as 2.96, 3.4e-3 as 3.4). Refused, naming the line.
* :func:`check_search_data` — what :func:`~spiralbayes.inference.scan.scan` needs on top:
  at least :data:`MIN_SEARCH_VISIBILITIES` visibilities and a positive distance.
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..exceptions import DataWarning, InputError

__all__ = ["MIN_SEARCH_VISIBILITIES", "check_duplicate_rows", "check_last_row", "check_search_data",
           "check_uv_coverage"]

MIN_SEARCH_VISIBILITIES = 20
"""Fewest visibilities a scan accepts. A floor, not a recommendation: a template bank times the
(r_p, phi_p) grid is thousands of models, and with fewer than ~20 visibilities (40 numbers) the
best of them fits noise; the handedness test and the BIC threshold assume N >> 1."""

DEGENERATE_RATIO = 1e-8
"""uv coverage whose second principal axis is below this fraction of the first is one line."""


def check_duplicate_rows(u, v, V, weights, source: str = "data") -> int:
    """Warn when rows repeat exactly; return how many rows are copies of an earlier one."""
    rows = np.column_stack([np.asarray(u, float), np.asarray(v, float), np.real(V), np.imag(V),
                            np.asarray(weights, float)])
    if rows.shape[0] < 2:
        return 0
    keys = np.ascontiguousarray(rows).view(np.dtype((np.void, rows.dtype.itemsize * rows.shape[1]))).ravel()
    copies = int(keys.size - np.unique(keys).size)
    if copies:
        warnings.warn(f"{source}: {copies} of {keys.size} rows repeat another row exactly (u, v, V and weight): "
                      "each copy counts the same measurement again, so chi^2 and every Delta chi^2 grow with the "
                      "copies; remove them (e.g. vis.subset(np.unique(rows, axis=0, return_index=True)[1])) or "
                      "re-export the data once", DataWarning, stacklevel=3)
    return copies


def check_uv_coverage(u, v, source: str = "data") -> None:
    """Refuse all-zero baselines and uv coverage on one line through the origin."""
    u, v = np.asarray(u, float), np.asarray(v, float)
    q = np.hypot(u, v)
    if u.size == 0 or not np.any(q > 0):
        raise InputError(f"{source}: every baseline has u = v = 0 (autocorrelations or a broken export): no "
                         "structure can be measured; check the u, v columns of the file")
    moments = np.array([[np.sum(u * u), np.sum(u * v)], [np.sum(u * v), np.sum(v * v)]])
    low, high = np.linalg.eigvalsh(moments)
    if high <= 0 or low / high < DEGENERATE_RATIO:
        raise InputError(f"{source}: all {u.size} baselines lie on one line through the origin of the uv plane "
                         "(degenerate coverage): azimuthal structure and the disc geometry cannot be measured; "
                         "check the u, v columns (e.g. v exported as a copy of u, or one baseline)")


def check_last_row(path, source: str | None = None) -> None:
    """Refuse a text table whose last row looks cut, naming its line.

    The last data row is compared, column by column, with the (up to 20) rows before it. It is
    refused when it has another number of fields; when a number ends inside its exponent
    (``1.2e-``); when it lacks the exponent, or has a shorter one, where every row before has one
    (``3.4`` cut from ``3.4e-3``: a value 10³ off); when it lacks the decimal point every row
    before has and at least 2 digits fewer (integer digits lost: ``2961`` cut from ``29614.83``); when a
    column of integers has 2 digits fewer than every row before, or any fewer where every row
    before holds the same integer; when it keeps 1 or 2 significant
    digits where every row before has at least 6; and, in a file without a final newline, when any column has fewer
    digits than in every row before. A cut after the decimal point that keeps 3 or more
    significant digits changes the value by less than 1 % and is not detected.
    """
    path = Path(path)
    if path.suffix.lower() == ".gz" or not path.is_file():
        return
    size = path.stat().st_size
    with open(path, "rb") as fh:
        fh.seek(max(0, size - TAIL_BYTES))
        tail = fh.read().decode("utf-8", "replace")
    newline = tail.endswith("\n")
    lines = tail.splitlines()[1 if size > TAIL_BYTES else 0:]  # the first line of a tail may be partial
    index = [i for i, line in enumerate(lines) if line.strip() and not line.lstrip().startswith("#")]
    if len(index) < 2:
        return
    rows = [lines[i] for i in index]
    reason = _cut_reason(rows[-1], rows[-21:-1], newline)
    if reason:
        line = _count_lines(path, newline) - (len(lines) - 1 - index[-1])
        raise InputError(f"{source or path}, line {line}: {reason}: it looks cut mid-number (truncated copy?); "
                         f"re-export or re-copy it, or delete line {line}")


TAIL_BYTES = 8192
"""How much of the end of a table :func:`check_last_row` reads."""

_TOKEN = re.compile(r"[\s,]+")
_INCOMPLETE_EXPONENT = re.compile(r"[eEdD][-+]?$")


@dataclass(frozen=True)
class _Number:
    """The written form of one number of a row."""

    text: str
    digits: int  # mantissa digits
    significant: int  # mantissa digits after leading zeros
    point: bool
    decimals: int  # digits after the point
    exponent: int | None  # digits of the exponent; None without one

    @classmethod
    def parse(cls, token: str) -> _Number:
        parts = re.split(r"[eEdD]", token, maxsplit=1)
        mantissa = "".join(c for c in parts[0] if c.isdigit())
        exponent = None if len(parts) == 1 else sum(c.isdigit() for c in parts[1])
        decimals = sum(c.isdigit() for c in parts[0].partition(".")[2])
        return cls(token, len(mantissa), len(mantissa.lstrip("0")), "." in parts[0], decimals, exponent)


def _numbers(line: str) -> list[_Number]:
    return [_Number.parse(token) for token in _TOKEN.split(line.strip()) if token]


def _cut_reason(last: str, before: list[str], newline: bool) -> str | None:
    """Why ``last`` looks cut compared with the rows ``before`` it, or None."""
    row, rows = _numbers(last), [_numbers(line) for line in before]
    counts = {len(r) for r in rows}
    if len(counts) == 1 and len(row) not in counts:
        return f"the last row has {len(row)} numbers where the rows before have {counts.pop()}"
    rows = [r for r in rows if len(r) == len(row)]
    if not rows:
        return None
    short = []
    for col, number in enumerate(row, start=1):
        column = [r[col - 1] for r in rows]
        fewest = min(c.digits for c in column)
        if _INCOMPLETE_EXPONENT.search(number.text):
            return f"the last row's column {col} ({number.text!r}) ends inside its exponent"
        exponents = [c.exponent for c in column if c.exponent is not None]
        if number.significant > 0 and len(exponents) == len(column):
            if number.exponent is None:
                return f"the last row's column {col} ({number.text!r}) has no exponent where every row before has one"
            if number.exponent < min(exponents):
                return f"the last row's column {col} ({number.text!r}) has a shorter exponent than every row before"
        # a plain zero may be a flagged row; %g drops the point of a whole number (one digit fewer)
        plain = not number.point and number.exponent is None and number.significant > 0
        integers = not any(c.point or c.exponent is not None for c in column)
        if plain and number.digits < fewest and (number.digits <= fewest - 2 and (all(c.point for c in column)
                                                                                 or integers)
                                                  or integers and len({c.text for c in column}) == 1):
            return f"the last row's column {col} ({number.text!r}) has fewer integer digits than every row before"
        fixed = {c.decimals for c in column} == {number.decimals}  # %f: every zero has the column's decimals
        if number.point and number.significant == 0 and number.digits < fewest and not fixed:  # '0.': not %g
            return f"the last row's column {col} ({number.text!r}) reads as 0 with fewer digits than every row before"
        if 1 <= number.significant <= 2 and min(c.significant for c in column) >= 6:  # 0 may be a flagged row
            return (f"the last row's column {col} ({number.text!r}) keeps {number.significant} significant digit(s) "
                    "where every row before has at least 6")
        if not newline and number.digits < fewest:
            short.append(col)
    if short:
        return (f"the last row's column(s) {', '.join(map(str, short))} have fewer digits than in every row before "
                "and the file does not end with a newline")
    return None


def _count_lines(path: Path, newline: bool) -> int:
    count = 0
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            count += block.count(b"\n")
    return count + (0 if newline else 1)


def check_search_data(vis, *, distance: float | None = None, minimum: int = MIN_SEARCH_VISIBILITIES) -> None:
    """Refuse data too few or too degenerate for a search, and a non-positive distance.

    Parameters
    ----------
    vis : Visibilities
    distance : float, optional
        Source distance [pc]; must be positive and finite when given.
    minimum : int
        Fewest visibilities accepted (:data:`MIN_SEARCH_VISIBILITIES`).
    """
    if distance is not None and not (isinstance(distance, (int, float, np.floating)) and not isinstance(distance, bool)
                                     and np.isfinite(distance) and distance > 0):
        raise InputError(f"distance = {distance!r} must be a positive, finite distance in pc (e.g. 140)")
    n = int(getattr(vis, "n", len(getattr(vis, "u", []))))
    if n < minimum:
        raise InputError(f"only {n} visibilities: a search needs at least {minimum} (MIN_SEARCH_VISIBILITIES; "
                         "thousands of template x position models would fit noise) — use the full, unbinned data")
    check_uv_coverage(vis.u, vis.v, "the visibilities")
