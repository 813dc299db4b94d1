"""CASA Measurement Sets through python-casacore (optional: ``pip install "spiralbayes[ms]"``).

:func:`read_ms` turns the main table's ``UVW`` [m], ``DATA``/``CORRECTED_DATA``,
``WEIGHT``/``WEIGHT_SPECTRUM`` and ``FLAG`` into a :class:`~spiralbayes.visibilities.Visibilities`
of Stokes I with u, v in wavelengths **per channel** (``CHAN_FREQ`` of each spectral window,
found through ``DATA_DESCRIPTION``). :func:`write_ms` (:mod:`.ms_writer`) writes an MS that
CASA's tasks accept (one spectral window, one channel, XX = YY = V).

Each visibility keeps the antennas and ``TIME`` [MJD seconds] of its row, so that antenna-based
gain errors can be diagnosed (:mod:`spiralbayes.calibration`). CASA's ``UVW`` is
``uvw(ANTENNA1) - uvw(ANTENNA2)`` whereas a :class:`~spiralbayes.visibilities.Visibilities` row's
baseline is ``position[antenna2] - position[antenna1]`` (:mod:`spiralbayes.layout`), so
``Visibilities.antenna1 = ANTENNA2`` and ``Visibilities.antenna2 = ANTENNA1``.

Measurement Set data are in the convention of frank and galario (``conjugated=False``):
``V = sum I exp(+2 pi i (u l + v m))`` with u, v = ``UVW[0:2] / lambda`` as stored.

Stokes I from the two parallel hands
------------------------------------
For linear feeds ``I = (XX + YY) / 2`` (circular: ``(RR + LL) / 2``). With independent noise
of variance ``sigma_p^2 = 1 / w_p`` on each of Re and Im of each hand,

    Var(I) = (sigma_XX^2 + sigma_YY^2) / 4   =>   w_I = 4 / (1/w_XX + 1/w_YY) = 4 w_XX w_YY / (w_XX + w_YY).

For equal weights ``w_I = 2 w = w_XX + w_YY``: the *sum* of the weights, as visread and the
DSHARP export script give. uvplot's ``export_uvtable`` averages them instead,
``0.5 (w_XX + w_YY)``, which is half the statistical weight: a factor 2 in chi^2, Delta chi^2
and Delta BIC (read such tables with ``weight_factor=2``, or re-estimate the weights). The
plain mean is used rather than the inverse-variance weighted mean (DSHARP's), because it is
Stokes I by definition even for polarised emission; the two agree when the weights are
equal. If one hand is flagged, Stokes I cannot be formed and the point is dropped (as CASA
does for ``stokes='I'``); pass ``average_polarisations=False`` to keep each hand as a
separate estimate of I instead.
"""

from __future__ import annotations

import logging
from pathlib import Path
from collections.abc import Iterable, Sequence

import numpy as np

from ..exceptions import InputError, MissingDependencyError, MissingFileError
from ..units import C_LIGHT
from ..visibilities import Visibilities
from ._common import _loads_provenance

__all__ = ["read_ms", "write_ms", "CORR_TYPES"]

log = logging.getLogger(__name__)

CORR_TYPES = {1: "I", 2: "Q", 3: "U", 4: "V", 5: "RR", 6: "RL", 7: "LR", 8: "LL",
              9: "XX", 10: "XY", 11: "YX", 12: "YY"}
"""casacore's Stokes enumeration (``POLARIZATION/CORR_TYPE``)."""

_PAIRS = ((9, 12), (5, 8))  # (XX, YY), (RR, LL)
_SINGLE = (1, 9, 12, 5, 8)  # usable alone as an estimate of I
_PROVENANCE_KEYWORD = "SPIRALBAYES_PROVENANCE"
_REQUIRED = ("UVW", "FLAG", "DATA_DESC_ID")
_ROW_COLUMNS = ("ANTENNA1", "ANTENNA2", "TIME")


def _tables():
    """Import ``casacore.tables`` lazily, with an install hint."""
    try:
        import casacore.tables as tables
    except ImportError:
        # from None: the user needs the install line, not casacore's import traceback
        raise MissingDependencyError(
            "reading or writing Measurement Sets needs python-casacore: "
            'pip install "spiralbayes[ms]" (or pip install python-casacore)'
        ) from None
    return tables


# ----------------------------------------------------------------------------------
# reading
# ----------------------------------------------------------------------------------
def read_ms(
    path,
    *,
    column: str | None = None,
    spw: int | Sequence[int] | None = None,
    field: int | str | Sequence[int | str] | None = None,
    average_polarisations: bool = True,
) -> Visibilities:
    """Read a CASA Measurement Set into Stokes I visibilities.

    Parameters
    ----------
    path : str or Path
        The MS directory. Opened read-only; nothing in it is changed.
    column : {'CORRECTED_DATA', 'DATA', ...}, optional
        Data column; default ``CORRECTED_DATA`` if present, else ``DATA``.
    spw : int or sequence of int, optional
        Spectral window id(s) to keep (default all).
    field : int, str or sequence, optional
        Field id(s) or name(s) (``FIELD/NAME``) to keep (default all).
    average_polarisations : bool
        Combine the parallel hands to Stokes I, ``(XX + YY) / 2`` with weight
        ``4 / (1/w_XX + 1/w_YY)`` (see the module docstring). If False, each parallel hand
        is returned as its own visibility (an estimate of I for unpolarised emission).

    Returns
    -------
    Visibilities
        u, v [lambda] converted per channel with ``C_LIGHT / CHAN_FREQ``; V [Jy]; weights
        [Jy^-2] from ``WEIGHT_SPECTRUM`` if it holds data, else ``WEIGHT`` (per row and
        correlation, applied to every channel, as visread and the DSHARP scripts do).
        Flagged data (``FLAG``, ``FLAG_ROW``) are dropped; ``wavelength`` is
        ``C_LIGHT / mean(CHAN_FREQ)`` of the windows read.

    Raises
    ------
    ValueError
        A needed column or subtable is missing (naming the MS and the column), an unknown
        spw/field is requested, or no unflagged data remain.
    MissingDependencyError
        If python-casacore is not installed (an ``ImportError``; the message gives the install line).

    Notes
    -----
    uvplot's ``export_uvtable`` averages the weights of the two hands (half the
    statistical weight derived above); DSHARP's ``ExportMS`` and visread sum them.
    """
    tables = _tables()
    path = Path(path)
    if not (path / "table.dat").exists():
        raise MissingFileError(f"{path} is not a Measurement Set (no table.dat in that directory)")
    with tables.table(str(path), readonly=True, ack=False) as ms:
        if ms.nrows() == 0:
            raise InputError(f"{path}: the Measurement Set has no rows (no visibilities)")
        column = _data_column(path, ms, column)
        weight_col = _weight_column(path, ms)
        spws, pols = _data_descriptions(tables, path)
        chan_freq = _chan_freqs(tables, path)
        corr_types = _corr_types(tables, path)
        fields = _field_ids(tables, path, field)
        parts, used_spw = [], set()
        for ddid, (spw_id, pol_id) in enumerate(zip(spws, pols)):
            if spw is not None and spw_id not in np.atleast_1d(spw):
                continue
            sub = _select_rows(ms, ddid, fields)
            if sub is None:
                continue
            with sub:
                parts.append(_read_rows(path, sub, column, weight_col, chan_freq[spw_id],
                                        corr_types[pol_id], average_polarisations))
            used_spw.add(int(spw_id))
        stored_prov = _stored_provenance(ms)
    _check_selection(path, spw, spws, used_spw)
    return _assemble(path, parts, column, weight_col, sorted(used_spw), chan_freq, average_polarisations,
                     stored_prov)


def _data_column(path: Path, ms, column: str | None) -> str:
    names = ms.colnames()
    missing = [c for c in _REQUIRED if c not in names]
    if missing:
        raise InputError(f"{path}: Measurement Set lacks column(s) {missing}; it needs UVW, FLAG, "
                         "DATA_DESC_ID, WEIGHT and DATA or CORRECTED_DATA (re-export it with CASA split)")
    if column is None:
        column = "CORRECTED_DATA" if "CORRECTED_DATA" in names else "DATA"
    column = column.upper()
    if column not in names or not ms.iscelldefined(column, 0):
        data_cols = [c for c in names if c.endswith("DATA") and c != "FLAG_CATEGORY"]
        raise InputError(f"{path}: Measurement Set has no (filled) column {column}; data columns present: "
                         f"{data_cols} — pass column=<one of them>")
    return column


def _weight_column(path: Path, ms) -> str:
    names = ms.colnames()
    if "WEIGHT_SPECTRUM" in names and ms.nrows() and ms.iscelldefined("WEIGHT_SPECTRUM", 0):
        return "WEIGHT_SPECTRUM"
    if "WEIGHT" not in names:
        raise InputError(f"{path}: Measurement Set lacks column WEIGHT (and WEIGHT_SPECTRUM); "
                         "statistical weights are needed — run CASA statwt or re-export the data")
    return "WEIGHT"


def _subtable(tables, path: Path, name: str, columns: Iterable[str]):
    sub_path = path / name
    if not (sub_path / "table.dat").exists():
        raise InputError(f"{path}: Measurement Set lacks the {name} subtable")
    tab = tables.table(str(sub_path), readonly=True, ack=False)
    missing = [c for c in columns if c not in tab.colnames()]
    if missing:
        tab.close()
        raise InputError(f"{path}: subtable {name} lacks column(s) {missing}")
    return tab


def _data_descriptions(tables, path: Path) -> tuple[np.ndarray, np.ndarray]:
    with _subtable(tables, path, "DATA_DESCRIPTION", ("SPECTRAL_WINDOW_ID", "POLARIZATION_ID")) as dd:
        return dd.getcol("SPECTRAL_WINDOW_ID"), dd.getcol("POLARIZATION_ID")


def _chan_freqs(tables, path: Path) -> list[np.ndarray]:
    """``CHAN_FREQ`` [Hz] of each spectral window (windows may differ in channel count)."""
    with _subtable(tables, path, "SPECTRAL_WINDOW", ("CHAN_FREQ",)) as spw:
        freqs = [np.asarray(spw.getcell("CHAN_FREQ", i), dtype=float) for i in range(spw.nrows())]
    for i, f in enumerate(freqs):
        if not (np.all(np.isfinite(f)) and np.all(f > 0)):
            raise InputError(f"{path}: SPECTRAL_WINDOW row {i} has invalid CHAN_FREQ {f} (must be > 0 Hz)")
    return freqs


def _corr_types(tables, path: Path) -> list[np.ndarray]:
    with _subtable(tables, path, "POLARIZATION", ("CORR_TYPE",)) as pol:
        return [np.asarray(pol.getcell("CORR_TYPE", i), dtype=int) for i in range(pol.nrows())]


def _field_ids(tables, path: Path, field) -> list[int] | None:
    if field is None:
        return None
    wanted = [field] if isinstance(field, (int, np.integer, str)) else list(field)
    with _subtable(tables, path, "FIELD", ("NAME",)) as tab:
        names = list(tab.getcol("NAME"))
    ids = []
    for item in wanted:
        if isinstance(item, str):
            if item not in names:
                raise InputError(f"{path}: no field named {item!r}; fields: {names}")
            ids.append(names.index(item))
        elif 0 <= int(item) < len(names):
            ids.append(int(item))
        else:
            raise InputError(f"{path}: no field id {item}; ids 0..{len(names) - 1} ({names})")
    return ids


def _select_rows(ms, ddid: int, fields: list[int] | None):
    query = f"DATA_DESC_ID == {ddid}"
    if fields is not None:
        query += " && FIELD_ID IN [" + ",".join(str(i) for i in fields) + "]"
    if "FLAG_ROW" in ms.colnames():
        query += " && NOT FLAG_ROW"
    sub = ms.query(query)
    if sub.nrows() == 0:
        sub.close()
        return None
    return sub


def _read_rows(path: Path, sub, column: str, weight_col: str, freq: np.ndarray, corr: np.ndarray,
               average: bool) -> dict:
    """u, v [lambda], V, weights of the unflagged Stokes I points of one data description."""
    uvw = sub.getcol("UVW")  # (nrow, 3) [m]
    data = sub.getcol(column).astype(complex)  # (nrow, nchan, ncorr); average in double precision
    flag = sub.getcol("FLAG")
    weight = sub.getcol(weight_col).astype(float)
    if weight.ndim == 2:  # WEIGHT: (nrow, ncorr) -> every channel
        weight = np.broadcast_to(weight[:, None, :], data.shape)
    if data.shape[1] != freq.size:
        raise InputError(f"{path}: {column} has {data.shape[1]} channels but CHAN_FREQ has {freq.size}")
    V, w, ok = _combine_polarisations(path, data, weight, flag, corr, average)
    u = uvw[:, 0, None, None] * freq[None, :, None] / C_LIGHT
    v = uvw[:, 1, None, None] * freq[None, :, None] / C_LIGHT
    u, v = (np.broadcast_to(x, V.shape) for x in (u, v))
    rows = {}
    if all(c in sub.colnames() for c in _ROW_COLUMNS):
        # the package's antenna1 is CASA's ANTENNA2 (opposite baseline sign, see the module docstring)
        for name, col in zip(("antenna2", "antenna1", "time"), _ROW_COLUMNS):
            rows[name] = np.broadcast_to(sub.getcol(col)[:, None, None], V.shape)[ok]
    return {"u": u[ok], "v": v[ok], "V": V[ok], "weights": w[ok], "n_flagged": int((~ok).sum()), **rows}


def _combine_polarisations(path: Path, data, weight, flag, corr, average: bool):
    """Return V, w, ok with a trailing axis of 1 (Stokes I) or one per parallel hand."""
    corr = list(corr)
    for a, b in _PAIRS:
        if a in corr and b in corr:
            i, j = corr.index(a), corr.index(b)
            if not average:
                sel = [i, j]
                return data[..., sel], weight[..., sel], ~flag[..., sel]
            wi, wj = weight[..., i], weight[..., j]
            denom = wi + wj
            w = np.divide(4.0 * wi * wj, denom, out=np.zeros_like(denom), where=denom > 0)
            V = 0.5 * (data[..., i] + data[..., j])
            ok = ~(flag[..., i] | flag[..., j])
            return V[..., None], w[..., None], ok[..., None]
    for c in _SINGLE:
        if c in corr:
            k = corr.index(c)
            if c != 1:
                log.info("%s: only the %s correlation: used as Stokes I (assumes unpolarised emission)",
                         path, CORR_TYPES[c])
            return data[..., [k]], weight[..., [k]], ~flag[..., [k]]
    names = [CORR_TYPES.get(c, str(c)) for c in corr]
    raise InputError(f"{path}: correlations {names} hold no parallel hand (XX/YY, RR/LL or I) to form Stokes I")


def _stored_provenance(ms) -> dict | None:
    if _PROVENANCE_KEYWORD in ms.keywordnames():
        prov = _loads_provenance(str(ms.getkeyword(_PROVENANCE_KEYWORD)))
        return prov if isinstance(prov, dict) else {"text": prov}
    return None


def _check_selection(path: Path, spw, spws, used: set) -> None:
    if spw is not None:
        unknown = sorted(set(int(s) for s in np.atleast_1d(spw)) - set(int(s) for s in spws))
        if unknown:
            raise InputError(f"{path}: no spectral window(s) {unknown}; windows with data: {sorted(set(spws))}")


def _assemble(path: Path, parts: list, column: str, weight_col: str, used_spw: list, chan_freq,
              average: bool, stored_prov: dict | None) -> Visibilities:
    n_flagged = sum(p["n_flagged"] for p in parts)
    arrays = {k: np.concatenate([p[k] for p in parts]) if parts else np.zeros(0) for k in ("u", "v", "V", "weights")}
    if parts and all("time" in p for p in parts):
        arrays.update({k: np.concatenate([p[k] for p in parts]) for k in ("antenna1", "antenna2", "time")})
    if arrays["u"].size == 0:
        raise InputError(f"{path}: no unflagged data in the selection ({n_flagged} flagged points); "
                         "check spw/field or the flags")
    freqs = np.concatenate([chan_freq[s] for s in used_spw])
    if n_flagged:
        log.info("%s: dropped %d flagged points", path, n_flagged)
    prov = {
        "source": str(path), "reader": "read_ms", "format": "Measurement Set", "column": column,
        "weights_from": weight_col, "spw": used_spw,
        "chan_freq_Hz": {str(s): chan_freq[s].tolist() for s in used_spw},
        "polarisations": "Stokes I = (XX+YY)/2, w = 4/(1/wXX+1/wYY)" if average else "parallel hands separately",
        "n_flagged_dropped": n_flagged,
        "conversions": ["u, v converted from metres per channel with C_LIGHT / CHAN_FREQ"],
    }
    if stored_prov is not None:
        prov["written_provenance"] = stored_prov
    try:
        return Visibilities(arrays["u"], arrays["v"], arrays["V"], arrays["weights"],
                            wavelength=C_LIGHT / float(np.mean(freqs)), conjugated=False, provenance=prov,
                            antenna1=arrays.get("antenna1"), antenna2=arrays.get("antenna2"), time=arrays.get("time"))
    except ValueError as exc:
        raise InputError(f"{path}: {exc}") from None


# ----------------------------------------------------------------------------------
# writing: see ms_writer (a Measurement Set that CASA's tasks accept)
# ----------------------------------------------------------------------------------
from .ms_writer import write_ms  # noqa: E402
