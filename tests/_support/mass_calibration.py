"""The template-mismatch systematic of the planet mass, from planted reference spirals.

A row is one planted reference (``tools/mass_references.py`` writes them): its true mass and the
posterior of the family template's mass (median, 16/84 % and 2.5/97.5 % points, mixed over the
families; the systematic left out), and the source it comes from (a code or a run set). The model:
``ln(truth / median)`` is Gaussian with the posterior's own width and the systematic ``σ_sys`` added
in quadrature; :func:`systematic_ml` is ``σ_sys``'s maximum-likelihood value and :func:`held_out`
checks each source's cases against the value the other sources give.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

Z95 = 1.959964
"""The standard normal's two-sided 95 % point."""


def load_rows(paths) -> list[dict]:
    """The rows of one or more JSON-lines files."""
    return [json.loads(line) for p in paths for line in Path(p).read_text().splitlines() if line.strip()]


def log_offsets(row: dict) -> tuple[float, float, float]:
    """``ln(truth / median)`` and the posterior's 1σ (68 %) and 2σ (95 %, divided by 1.96) widths in
    ``ln M_p`` on the truth's side."""
    r = float(np.log(row["truth"] / row["median"]))
    if r > 0:
        return r, float(np.log(row["hi"] / row["median"])), float(np.log(row["hi95"] / row["median"]) / Z95)
    return r, float(np.log(row["median"] / row["lo"])), float(np.log(row["median"] / row["lo95"]) / Z95)


def systematic_ml(rows: list[dict]) -> float:
    """Maximum-likelihood ``σ_sys`` [in ln M_p] of ``rows`` (0 when their own widths explain them)."""
    from scipy.optimize import minimize_scalar

    r, s, _ = np.array([log_offsets(row) for row in rows]).T

    def nll(sys):
        v = s ** 2 + sys ** 2
        return 0.5 * np.sum(r ** 2 / v + np.log(v))

    return float(minimize_scalar(nll, bounds=(0.0, 3.0), method="bounded", options={"xatol": 1e-5}).x)


def held_out(rows: list[dict], systematic: float | None = None) -> list[dict]:
    """Each row with ``z = ln(truth / median) / hypot(σ_95, σ_sys)``, ``σ_sys`` from the *other*
    sources' rows (or ``systematic`` for all), and whether the truth is inside the widened 95 % interval."""
    out = []
    for source in sorted({row["source"] for row in rows}):
        sys = systematic if systematic is not None else systematic_ml([x for x in rows if x["source"] != source])
        for row in (x for x in rows if x["source"] == source):
            r, _, s95 = log_offsets(row)
            z = r / np.hypot(s95, sys)
            out.append({**row, "ln_offset": r, "sigma95": s95, "systematic": sys, "z": float(z),
                        "inside95": bool(abs(z) <= Z95)})
    return out
