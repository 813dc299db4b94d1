"""Load-time checks of what the numbers in a visibility file can mean.

Each check refuses data no search can use (:class:`~spiralbayes.exceptions.InputError`) or warns
(:class:`~spiralbayes.exceptions.DataWarning`) with the fix in the message:

* :func:`check_duplicate_rows` — rows that repeat another exactly (u, v, V and weight) count the
  same measurement twice: χ² and every Δχ² scale with the number of copies (an export written
  twice doubled Δχ² 3.3 → 5.9). Warned, with the count and the fix.
* :func:`check_uv_coverage` — every baseline of zero length (u = v = 0) or all baselines on one
  line through the origin (rank-1 uv coverage): no azimuthal structure, and no geometry, can be
  constrained. Refused.
* :func:`check_last_row` — a uvtable cut mid-number (no final newline and a last row whose
  numbers have fewer digits than the rows before) reads a wrong weight or V silently
  (29614.8 read as 2.96). Refused.
* :func:`check_search_data` — what :func:`~spiralbayes.inference.scan.scan` needs on top:
  at least :data:`MIN_SEARCH_VISIBILITIES` visibilities and a positive distance.
"""

from __future__ import annotations

import re
import warnings
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
    """Refuse a text table whose last row was cut mid-number (no final newline, shorter numbers)."""
    path = Path(path)
    if path.suffix.lower() == ".gz" or not path.is_file():
        return
    size = path.stat().st_size
    with open(path, "rb") as fh:
        fh.seek(max(0, size - 8192))
        tail = fh.read().decode("utf-8", "replace")
    if not tail or tail.endswith("\n"):
        return
    lines = [line for line in tail.splitlines()[1:] if line.strip() and not line.lstrip().startswith("#")]
    if len(lines) < 2:
        return
    last, before = _digits(lines[-1]), [_digits(line) for line in lines[-21:-1]]
    before = [d for d in before if len(d) == len(last)]
    if not before:
        raise InputError(f"{source or path}: the last row has another number of columns than the rows before and "
                         "the file does not end with a newline: it looks cut (truncated copy?); re-export or re-copy "
                         "it, or delete the last row")
    shortest = np.min(np.array(before), axis=0)
    cut = [i for i, (d, m) in enumerate(zip(last, shortest)) if d < m]
    if cut:
        raise InputError(f"{source or path}: the last row's column(s) {', '.join(str(i + 1) for i in cut)} have fewer "
                         "digits than in every row before and the file does not end with a newline: it looks cut "
                         "mid-number (truncated copy?); re-export or re-copy it, or delete the last row")


_TOKEN = re.compile(r"[\s,]+")


def _digits(line: str) -> list[int]:
    """Mantissa digits of each number of a row (the exponent is not counted)."""
    out = []
    for token in _TOKEN.split(line.strip()):
        if token:
            mantissa = re.split(r"[eEdD]", token, maxsplit=1)[0]
            out.append(sum(c.isdigit() for c in mantissa))
    return out


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
