"""Interferometric visibilities: the container, its readers and writers, binning and weights.

Every reader returns a :class:`Visibilities` (u, v [lambda], complex V [Jy], weights
[Jy^-2]); every writer accepts one. Formats (``shared/notes/ecosystem.md`` lists where users'
files come from and their pitfalls):

* uvtable ``.txt``/``.dat``/``.csv`` (optionally ``.gz``): :func:`read_uvtable` /
  :func:`write_uvtable` — frank's layout; uvplot's metre variant is converted with the
  wavelength in its header.
* ``.npz``: :func:`read_npz` / :func:`write_npz` — frank's keys, or DSHARP ``ExportMS`` keys.
* ``.h5``/``.hdf5``: :func:`read_hdf5` / :func:`write_hdf5` — spiralbayes' own format, with
  metadata and provenance.
* Measurement Set directories (``.ms``): :func:`spiralbayes.measurement_set.read_ms` /
  :func:`~spiralbayes.measurement_set.write_ms` — needs python-casacore.

Also here: :func:`bin_deprojected` (a "uvplot" of deprojected, binned visibilities) and
:func:`estimate_weights` (one weight rescaling factor from the scatter of the data, an
explicit option).

:func:`load_visibilities` and :func:`save_visibilities` pick the format from the file
extension. Readers never modify the user's file; writers write to a temporary file beside
the target and rename it into place only on success.

Conventions: ``V(u, v) = sum I(l, m) exp(+2 pi i (u l + v m))`` (CASA, frank, galario), u, v
being the Measurement Set's ``UVW[0:2] / lambda`` as stored. Data in the complex-conjugate
convention (e.g. exported by visread) carry ``conjugated=True``; call
:meth:`Visibilities.standardised` before modelling. u, v in metres are only ever converted
with a wavelength that is given or stated in the file, never guessed.
"""

from __future__ import annotations

import gzip
import hashlib
import json
import logging
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from ._provenance import FORMAT_VERSION, atomic_path, json_default

if TYPE_CHECKING:  # pragma: no cover
    from .geometry import DiscGeometry

__all__ = [
    "C_LIGHT",
    "Visibilities",
    "BinnedVisibilities",
    "WeightRescaling",
    "read_uvtable",
    "write_uvtable",
    "read_npz",
    "write_npz",
    "read_hdf5",
    "write_hdf5",
    "visibilities_to_hdf5_group",
    "visibilities_from_hdf5_group",
    "load_visibilities",
    "save_visibilities",
    "bin_deprojected",
    "estimate_weight_factor",
    "estimate_weights",
]

log = logging.getLogger(__name__)

C_LIGHT = 299_792_458.0
"""Speed of light [m/s] (exact, SI)."""

UVTABLE_SUFFIXES = (".txt", ".dat", ".csv")
NPZ_SUFFIXES = (".npz",)
HDF5_SUFFIXES = (".h5", ".hdf5")
MS_SUFFIXES = (".ms",)

_UV_UNIT_ALIASES = {
    "lambda": "lambda", "λ": "lambda", "wavelengths": "lambda", "wle": "lambda",
    "klambda": "klambda", "kλ": "klambda", "kilolambda": "klambda",
    "m": "m", "metre": "m", "metres": "m", "meter": "m", "meters": "m",
}
_UV_UNIT_SCALE = {"lambda": 1.0, "klambda": 1e3}
_LOOKS_LIKE_METRES = 3e3
"""Longest baseline [lambda] below which u, v in 'lambda' are suspiciously short (metres?)."""


@dataclass
class Visibilities:
    """Visibilities of one source, in the convention of frank, galario and CASA.

    Parameters
    ----------
    u, v : ndarray, shape (N,)
        Baseline coordinates [lambda] (the Measurement Set's UVW[0:2] divided by the
        wavelength, as stored).
    V : ndarray of complex, shape (N,)
        Visibilities [Jy].
    weights : ndarray, shape (N,)
        Statistical weights ``1 / sigma^2`` [Jy^-2], sigma the noise of each of Re and Im.
        Zero weights (flagged data) are dropped at construction, with a logged count.
    wavelength : float, optional
        Observing wavelength [m], when known.
    conjugated : bool
        True if ``V`` is the complex conjugate of the frank/galario convention (e.g. data
        exported by visread). Use :meth:`standardised` before modelling.
    provenance : dict
        Where the data came from (file, reader, conversions applied).
    """

    u: np.ndarray
    v: np.ndarray
    V: np.ndarray
    weights: np.ndarray
    wavelength: float | None = None
    conjugated: bool = False
    provenance: dict = field(default_factory=dict)

    def __post_init__(self):
        self.u = _real_array(self.u, "u")
        self.v = _real_array(self.v, "v")
        self.V = np.asarray(self.V, dtype=complex).ravel()
        self.weights = _real_array(self.weights, "weights")
        self._check_lengths()
        self._check_values()
        self._drop_zero_weights()
        if self.wavelength is not None:
            self.wavelength = float(self.wavelength)
            if not (np.isfinite(self.wavelength) and self.wavelength > 0):
                raise ValueError(f"wavelength must be a positive number of metres, got {self.wavelength!r}")
        self.provenance = dict(self.provenance)

    def _check_lengths(self):
        lengths = {"u": self.u.size, "v": self.v.size, "V": self.V.size, "weights": self.weights.size}
        if len(set(lengths.values())) != 1:
            raise ValueError(f"u, v, V and weights must have the same length, got {lengths}")
        if self.u.size == 0:
            raise ValueError("no visibilities: u, v, V and weights are empty")

    def _check_values(self):
        for name, arr in (("u", self.u), ("v", self.v), ("V", self.V), ("weights", self.weights)):
            bad = ~np.isfinite(arr)
            if bad.any():
                raise ValueError(
                    f"{name} has {bad.sum()} NaN/inf values (first at index {np.argmax(bad)}); "
                    "remove or flag those rows before loading"
                )
        if (self.weights < 0).any():
            n = int((self.weights < 0).sum())
            raise ValueError(
                f"weights has {n} negative values (first at index {np.argmax(self.weights < 0)}); "
                "weights are 1/sigma^2 [Jy^-2] and must be >= 0"
            )

    def _drop_zero_weights(self):
        keep = self.weights > 0
        n_drop = int((~keep).sum())
        if n_drop == self.u.size:
            raise ValueError("every visibility has zero weight (all flagged): nothing to fit")
        if n_drop:
            log.info("dropped %d visibilities with zero weight (flagged data)", n_drop)
            self.u, self.v, self.V, self.weights = (a[keep] for a in (self.u, self.v, self.V, self.weights))
            self.provenance = {**self.provenance, "dropped_zero_weight": n_drop}

    # ------------------------------------------------------------------------------
    def __len__(self) -> int:
        return self.u.size

    @property
    def n(self) -> int:
        """Number of visibility points N (the N of the BIC)."""
        return self.u.size

    @property
    def uv_distance(self) -> np.ndarray:
        """Baseline length [lambda]."""
        return np.hypot(self.u, self.v)

    @property
    def sigma(self) -> np.ndarray:
        """Noise of each of Re V and Im V [Jy]."""
        return 1.0 / np.sqrt(self.weights)

    def standardised(self) -> "Visibilities":
        """The same data in the frank/galario convention (un-conjugated if needed)."""
        if not self.conjugated:
            return self
        prov = {**self.provenance, "conjugated_on_load": True}
        return replace(self, V=np.conj(self.V), conjugated=False, provenance=prov)

    def subset(self, index) -> "Visibilities":
        """A copy with only the selected rows (boolean mask or indices)."""
        return replace(self, u=self.u[index], v=self.v[index], V=self.V[index], weights=self.weights[index])

    def with_weights(self, weights, note: str) -> "Visibilities":
        """A copy with new weights; ``note`` is recorded in the provenance."""
        prov = {**self.provenance, "weights": note}
        return replace(self, weights=np.asarray(weights, dtype=float), provenance=prov)

    def with_V(self, V, note: str | None = None) -> "Visibilities":
        """A copy with new visibility values (e.g. model or residuals)."""
        prov = self.provenance if note is None else {**self.provenance, "V": note}
        return replace(self, V=np.asarray(V, dtype=complex), provenance=prov)

    @property
    def frequency(self) -> float | None:
        """Observing frequency [Hz] (``C_LIGHT / wavelength``), when the wavelength is known."""
        return None if self.wavelength is None else C_LIGHT / self.wavelength

    def __repr__(self) -> str:
        q = self.uv_distance
        wle = "unknown" if self.wavelength is None else f"{self.wavelength:.6g} m"
        return (
            f"Visibilities(n={self.n}, baselines {q.min():.4g}-{q.max():.4g} lambda, "
            f"wavelength {wle}, conjugated={self.conjugated}, "
            f"source={self.provenance.get('source', 'in memory')!r})"
        )


def _real_array(x, name: str) -> np.ndarray:
    arr = np.asarray(x)
    if np.iscomplexobj(arr):
        raise ValueError(f"{name} must be real, got complex values")
    try:
        return arr.astype(float).ravel()
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be numeric: {exc}") from None


# ----------------------------------------------------------------------------------
# shared helpers for readers
# ----------------------------------------------------------------------------------
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
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"visibility file {path} does not exist")
    if path.is_dir():
        raise ValueError(f"{path} is a directory; expected a file (a Measurement Set is read with read_ms)")
    return path


def _build(path: Path, **kwargs) -> Visibilities:
    """Construct :class:`Visibilities`, prefixing any validation error with the file name."""
    try:
        return Visibilities(**kwargs)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def _normalise_uv_units(uv_units: str | None) -> str | None:
    if uv_units is None:
        return None
    key = str(uv_units).strip().lower()
    if key not in _UV_UNIT_ALIASES:
        raise ValueError(f"uv_units={uv_units!r} is not understood: use 'lambda', 'klambda' or 'm'")
    return _UV_UNIT_ALIASES[key]


def _check_wavelength(wavelength, what: str) -> np.ndarray:
    wle = np.asarray(wavelength, dtype=float)
    if not (np.all(np.isfinite(wle)) and np.all(wle > 0)):
        raise ValueError(f"{what}: wavelength must be positive and finite [m], got {wavelength!r}")
    return wle


def _uv_to_lambda(u, v, units: str, wavelength, path: Path) -> tuple[np.ndarray, np.ndarray, list]:
    """Convert u, v to wavelengths; return them and the list of conversions applied.

    ``wavelength`` [m] (scalar or one per row) is needed only when ``units == 'm'``.
    """
    if units == "m":
        if wavelength is None:
            raise ValueError(
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


def _warn_if_metres(u, v, path: Path) -> None:
    qmax = float(np.max(np.hypot(u, v))) if np.size(u) else 0.0
    if 0 < qmax < _LOOKS_LIKE_METRES:
        log.warning(
            "%s: longest baseline is only %.4g lambda; if u, v are in metres pass uv_units='m' "
            "and the wavelength (they are not converted automatically)", path, qmax,
        )


def _scale_weights(weights, weight_factor: float, conversions: list) -> np.ndarray:
    factor = float(weight_factor)
    if not (np.isfinite(factor) and factor > 0):
        raise ValueError(f"weight_factor must be a positive number, got {weight_factor!r}")
    if factor != 1.0:
        conversions.append(f"weights multiplied by {factor:g} (weight_factor)")
        return np.asarray(weights, dtype=float) * factor
    return np.asarray(weights, dtype=float)


# ----------------------------------------------------------------------------------
# uvtable (.txt / .dat / .csv)
# ----------------------------------------------------------------------------------
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
    return gzip.open(path, "rt") if path.suffix.lower() == ".gz" else open(path, "r", encoding="utf-8",
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
    raise ValueError(
        f"{path}: found {ncols} columns{declared}, expected 5: {_UVTABLE_LAYOUT}; "
        "6 columns are accepted only when a '# Columns:' header names a third column 'w' "
        "or a sixth column 'lambda[m]'. Rewrite the file with the 5 columns in that order"
    )


def _load_table(path: Path, first_line: str) -> np.ndarray:
    if not first_line:
        raise ValueError(f"{path}: no data rows found (only comments or blank lines); expected "
                         f"rows of {_UVTABLE_LAYOUT}")
    delimiter = "," if "," in first_line else None
    try:
        table = np.loadtxt(path, comments="#", delimiter=delimiter, ndmin=2, dtype=float)
    except ValueError as exc:
        raise ValueError(
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
    header = _parse_uvtable_header(path)
    table = _load_table(path, header.first_data_line)
    cols = _column_layout(path, table.shape[1], header.columns)
    units = _resolve_units(path, _normalise_uv_units(uv_units), header.uv_units)
    wle = _resolve_wavelength(path, wavelength, header.wavelength)
    row_wle = table[:, cols["wavelength"]] if "wavelength" in cols else None
    u, v, conversions = _uv_to_lambda(
        table[:, cols["u"]], table[:, cols["v"]], units, row_wle if row_wle is not None else wle, path
    )
    if units != "m":
        _warn_if_metres(u, v, path)
    if wle is None and row_wle is not None:
        wle = float(np.mean(row_wle))
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
        target = gzip.open(tmp, "wb") if path.suffix.lower() == ".gz" else open(tmp, "wb")
        with target as fh:
            np.savetxt(fh, table, fmt="%.17g", delimiter=delimiter, header="\n".join(lines))
    log.info("wrote %d visibilities to %s", vis.n, path)
    return path


def _json(obj) -> str:
    return json.dumps(obj, default=json_default, sort_keys=True)


# ----------------------------------------------------------------------------------
# .npz (frank keys or DSHARP ExportMS keys)
# ----------------------------------------------------------------------------------
_FRANK_KEYS = ("u", "v", "V", "weights")
_DSHARP_KEYS = ("u", "v", "Vis", "Wgt")
_FREQ_KEYS = ("freq", "freqs", "nu")


def read_npz(
    path,
    *,
    layout: str | None = None,
    uv_units: str | None = None,
    wavelength: float | None = None,
    conjugated: bool | None = None,
    weight_factor: float = 1.0,
) -> Visibilities:
    """Read visibilities from a NumPy ``.npz`` archive.

    Two layouts are understood:

    * ``'frank'``: keys ``u``, ``v`` [lambda], complex ``V`` [Jy], ``weights`` [Jy^-2]
      (what frank reads and :func:`write_npz` writes; optional ``wavelength``,
      ``conjugated`` and ``provenance`` keys are honoured).
    * ``'dsharp'``: the DSHARP ``ExportMS.py`` keys ``u``, ``v``, complex ``Vis`` [Jy],
      ``Wgt`` [Jy^-2] and, in the per-channel variant, ``freq`` [Hz]. In that variant
      ``u, v`` are in **metres**, one per row, and ``Vis``/``Wgt`` have shape
      ``(n_chan, n_rows)``: each channel is converted with its own wavelength
      ``C_LIGHT / freq`` (unambiguous, done automatically). Without a frequency key the
      units are ambiguous (the original DSHARP script wrote wavelengths, later variants
      metres), so ``uv_units`` must be given.

    Parameters
    ----------
    path : str or Path
    layout : {'frank', 'dsharp'}, optional
        Default: detected from the keys (an error if neither set is complete).
    uv_units : {'lambda', 'klambda', 'm'}, optional
        Units of ``u``, ``v``. Default: wavelengths for the frank layout; see above for dsharp.
    wavelength : float, optional
        Wavelength [m] for u, v in metres (overrides any frequency in the file).
    conjugated : bool, optional
        Whether V is conjugated relative to frank/galario; default the file's
        ``conjugated`` key, else False.
    weight_factor : float
        Multiply the weights by this (recorded in provenance).

    Returns
    -------
    Visibilities

    Raises
    ------
    ValueError
        Missing keys, ambiguous units, inconsistent shapes or invalid values (naming the file).
    """
    path = _existing_file(path)
    try:
        archive = np.load(path, allow_pickle=False)
    except ValueError as exc:
        raise ValueError(f"{path}: cannot read as .npz without unpickling objects ({exc}); "
                         "store plain numeric arrays") from None
    with archive as data:
        keys = set(data.files)
        layout = _npz_layout(path, keys, layout)
        arrays = {k: data[k] for k in data.files}
    if layout == "frank":
        kwargs = _npz_frank(path, arrays, _normalise_uv_units(uv_units), wavelength)
    else:
        kwargs = _npz_dsharp(path, arrays, _normalise_uv_units(uv_units), wavelength)
    conversions = kwargs.pop("conversions")
    kwargs["weights"] = _scale_weights(kwargs["weights"], weight_factor, conversions)
    if conjugated is None:
        conjugated = bool(arrays["conjugated"]) if "conjugated" in arrays else False
    prov = _source_record(path, "read_npz", format=f"npz ({layout} layout)", conversions=conversions)
    if "provenance" in arrays:
        prov["written_provenance"] = _loads_provenance(str(arrays["provenance"]))
    return _build(path, conjugated=bool(conjugated), provenance=prov, **kwargs)


def _npz_layout(path: Path, keys: set, layout: str | None) -> str:
    complete = {"frank": set(_FRANK_KEYS) <= keys, "dsharp": set(_DSHARP_KEYS) <= keys}
    if layout is None:
        found = [name for name, ok in complete.items() if ok]
        if len(found) == 1:
            return found[0]
        if not found:
            raise ValueError(
                f"{path}: keys {sorted(keys)} match no known layout; expected frank's "
                f"{list(_FRANK_KEYS)} or DSHARP ExportMS's {list(_DSHARP_KEYS)} (+ 'freq')"
            )
        raise ValueError(f"{path}: holds both frank and DSHARP keys; pass layout='frank' or 'dsharp'")
    if layout not in complete:
        raise ValueError(f"layout={layout!r} is not known: use 'frank' or 'dsharp'")
    if not complete[layout]:
        needed = _FRANK_KEYS if layout == "frank" else _DSHARP_KEYS
        missing = [k for k in needed if k not in keys]
        raise ValueError(f"{path}: layout {layout!r} needs keys {list(needed)}; missing {missing}")
    return layout


def _npz_frank(path: Path, a: dict, units: str | None, wavelength) -> dict:
    units = units or "lambda"
    wle = wavelength
    if wle is None and "wavelength" in a and np.isfinite(a["wavelength"]).all():
        wle = float(a["wavelength"])
    u, v, conversions = _uv_to_lambda(a["u"], a["v"], units, wle, path)
    if units != "m":
        _warn_if_metres(u, v, path)
    return dict(u=u, v=v, V=a["V"], weights=a["weights"], wavelength=wle, conversions=conversions)


def _npz_dsharp(path: Path, a: dict, units: str | None, wavelength) -> dict:
    vis, wgt = np.asarray(a["Vis"]), np.asarray(a["Wgt"], dtype=float)
    u, v = np.ravel(a["u"]), np.ravel(a["v"])
    freq_key = next((k for k in _FREQ_KEYS if k in a), None)
    freq = None if freq_key is None else np.ravel(np.asarray(a[freq_key], dtype=float))
    if wgt.shape != vis.shape:
        try:
            wgt = np.broadcast_to(wgt, vis.shape)
        except ValueError:
            raise ValueError(f"{path}: Wgt shape {wgt.shape} does not match Vis shape {vis.shape}") from None
    if vis.ndim == 2:
        return _dsharp_per_channel(path, u, v, vis, wgt, freq, units, wavelength)
    if units is None:
        if freq is None or freq.size != 1:
            raise ValueError(
                f"{path}: DSHARP-style keys without one frequency per channel: the units of u, v "
                "are ambiguous (the DSHARP script wrote wavelengths, later variants metres); pass "
                "uv_units='lambda', or uv_units='m' with wavelength=<metres>"
            )
        units = "m"
    wle = _dsharp_wavelength(path, freq, u.size, wavelength)
    u, v, conversions = _uv_to_lambda(u, v, units, wle, path)
    mean_wle = None if wle is None else float(np.mean(wle))
    return dict(u=u, v=v, V=np.ravel(vis), weights=np.ravel(wgt), wavelength=mean_wle,
                conversions=conversions)


def _dsharp_wavelength(path: Path, freq, n_rows: int, wavelength):
    if wavelength is not None:
        return wavelength
    if freq is None:
        return None
    if freq.size not in (1, n_rows):
        raise ValueError(f"{path}: {freq.size} frequencies for {n_rows} rows; expected 1 or one per row")
    wle = C_LIGHT / _check_wavelength(freq, f"{path} (frequencies)")
    return float(wle[0]) if freq.size == 1 else wle


def _dsharp_per_channel(path: Path, u, v, vis, wgt, freq, units, wavelength) -> dict:
    n_chan, n_rows = vis.shape
    if u.size != n_rows:
        raise ValueError(f"{path}: Vis has shape (n_chan, n_rows) = {vis.shape} but u has {u.size} rows")
    if units not in (None, "m"):
        raise ValueError(f"{path}: per-channel Vis of shape {vis.shape} needs u, v in metres (one per row, "
                         f"converted per channel); uv_units={units!r} cannot be applied")
    if wavelength is not None:
        wle = np.broadcast_to(_check_wavelength(wavelength, str(path)).reshape(-1, 1), (n_chan, 1))
    elif freq is not None and freq.size == n_chan:
        wle = (C_LIGHT / _check_wavelength(freq, f"{path} (freq)")).reshape(-1, 1)
    else:
        raise ValueError(f"{path}: Vis has {n_chan} channels but 'freq' has "
                         f"{0 if freq is None else freq.size} values; pass wavelength=<metres>")
    conversions = [f"u, v converted from metres per channel ({n_chan} channels, wavelength = c / freq)"]
    return dict(u=(u[None, :] / wle).ravel(), v=(v[None, :] / wle).ravel(), V=vis.ravel(),
                weights=wgt.ravel(), wavelength=float(np.mean(wle)), conversions=conversions)


def write_npz(vis: Visibilities, path) -> Path:
    """Write ``vis`` in frank's ``.npz`` layout (``u``, ``v`` [lambda], ``V`` [Jy], ``weights``).

    Also stores ``wavelength`` [m] (NaN when unknown), ``conjugated`` and ``provenance``
    (a JSON string); frank ignores the extra keys. Written atomically, without pickling.
    """
    path = Path(path)
    wle = np.nan if vis.wavelength is None else vis.wavelength
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez(fh, u=vis.u, v=vis.v, V=vis.V, weights=vis.weights, wavelength=np.float64(wle),
                 conjugated=np.bool_(vis.conjugated), provenance=np.str_(_json(vis.provenance)))
    log.info("wrote %d visibilities to %s", vis.n, path)
    return path


def _loads_provenance(text: str) -> Any:
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text


# ----------------------------------------------------------------------------------
# HDF5 (spiralbayes' own format)
# ----------------------------------------------------------------------------------
_H5_TYPE = "spiralbayes.Visibilities"
_H5_DATASETS = ("u", "v", "V", "weights")


def visibilities_to_hdf5_group(vis: Visibilities, group) -> None:
    """Store ``vis`` in an open ``h5py.Group`` (datasets u, v, V, weights; metadata as attributes).

    Attributes: ``spiralbayes_type``, ``format_version``, ``wavelength`` [m] (NaN when
    unknown), ``conjugated``, ``provenance`` (JSON), ``units``.
    """
    for name in _H5_DATASETS:
        group.create_dataset(name, data=getattr(vis, name))
    group.attrs["spiralbayes_type"] = _H5_TYPE
    group.attrs["format_version"] = FORMAT_VERSION
    group.attrs["wavelength"] = np.nan if vis.wavelength is None else vis.wavelength
    group.attrs["conjugated"] = bool(vis.conjugated)
    group.attrs["provenance"] = _json(vis.provenance)
    group.attrs["units"] = "u, v: lambda; V: Jy; weights: Jy^-2 (1/sigma^2 of Re and Im); wavelength: m"


def visibilities_from_hdf5_group(group, source: str = "") -> Visibilities:
    """Read a :class:`Visibilities` written by :func:`visibilities_to_hdf5_group`."""
    where = source or group.name
    missing = [name for name in _H5_DATASETS if name not in group]
    if missing:
        raise ValueError(f"{where}: missing dataset(s) {missing}; a spiralbayes visibility file holds "
                         f"datasets {list(_H5_DATASETS)} (write one with save_visibilities)")
    version = int(group.attrs.get("format_version", FORMAT_VERSION))
    if version > FORMAT_VERSION:
        raise ValueError(f"{where}: format_version {version} is newer than this spiralbayes understands "
                         f"({FORMAT_VERSION}); upgrade spiralbayes")
    wle = float(group.attrs.get("wavelength", np.nan))
    prov = _loads_provenance(_as_str(group.attrs.get("provenance", "{}")))
    return Visibilities(
        u=group["u"][()], v=group["v"][()], V=group["V"][()], weights=group["weights"][()],
        wavelength=wle if np.isfinite(wle) else None, conjugated=bool(group.attrs.get("conjugated", False)),
        provenance=prov if isinstance(prov, dict) else {"written_provenance": prov},
    )


def _as_str(x) -> str:
    return x.decode() if isinstance(x, bytes) else str(x)


def read_hdf5(path, *, group: str = "/") -> Visibilities:
    """Read visibilities from spiralbayes' HDF5 format (see :func:`write_hdf5`).

    Parameters
    ----------
    path : str or Path
    group : str
        HDF5 group holding the datasets (default the root).

    Returns
    -------
    Visibilities
        With the stored provenance, plus ``loaded_from`` (path, SHA-256 of the file).
    """
    import h5py

    path = _existing_file(path)
    try:
        fh = h5py.File(path, "r")
    except OSError as exc:
        raise ValueError(f"{path}: not a readable HDF5 file ({exc})") from None
    with fh:
        if group not in fh:
            raise ValueError(f"{path}: no group {group!r} in the file (groups: {list(fh.keys())})")
        try:
            vis = visibilities_from_hdf5_group(fh[group], source=str(path))
        except ValueError as exc:
            msg = str(exc)
            raise ValueError(msg if msg.startswith(str(path)) else f"{path}: {msg}") from None
    loaded = _source_record(path, "read_hdf5", format="spiralbayes hdf5")
    return replace(vis, provenance={**vis.provenance, "loaded_from": loaded})


def write_hdf5(vis: Visibilities, path) -> Path:
    """Write ``vis`` to an HDF5 file (datasets u, v [lambda], V [Jy], weights [Jy^-2]).

    Root attributes: ``wavelength`` [m] (NaN if unknown), ``conjugated``, ``provenance``
    (JSON string), ``format_version`` (``spiralbayes._provenance.FORMAT_VERSION``).
    Written to a temporary file and renamed into place.
    """
    import h5py

    path = Path(path)
    with atomic_path(path) as tmp:
        with h5py.File(tmp, "w") as fh:
            visibilities_to_hdf5_group(vis, fh)
    log.info("wrote %d visibilities to %s", vis.n, path)
    return path


# ----------------------------------------------------------------------------------
# dispatch by extension
# ----------------------------------------------------------------------------------
def _format_of(path: Path) -> str:
    suffixes = [s.lower() for s in path.suffixes]
    suffix = suffixes[-2] if suffixes and suffixes[-1] == ".gz" and len(suffixes) > 1 else path.suffix.lower()
    if path.is_dir() or suffix in MS_SUFFIXES:
        if suffix in MS_SUFFIXES or (path / "table.dat").exists():
            return "ms"
    if suffix in UVTABLE_SUFFIXES:
        return "uvtable"
    if suffix in NPZ_SUFFIXES:
        return "npz"
    if suffix in HDF5_SUFFIXES:
        return "hdf5"
    supported = UVTABLE_SUFFIXES + NPZ_SUFFIXES + HDF5_SUFFIXES + MS_SUFFIXES
    raise ValueError(f"{path}: unknown visibility format {suffix!r}; supported: {', '.join(supported)} "
                     "(or call read_uvtable/read_npz/read_hdf5/read_ms directly)")


def load_visibilities(path, **kwargs) -> Visibilities:
    """Read visibilities from any supported file, chosen by extension.

    ``.txt/.dat/.csv`` (optionally ``.gz``) → :func:`read_uvtable`; ``.npz`` →
    :func:`read_npz`; ``.h5/.hdf5`` → :func:`read_hdf5`; a directory ending in ``.ms``
    (or any casacore table directory) → :func:`spiralbayes.measurement_set.read_ms`.
    Keyword arguments go to that reader. The file is never modified.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"visibility file {path} does not exist")
    fmt = _format_of(path)
    if fmt == "ms":
        from .measurement_set import read_ms

        return read_ms(path, **kwargs)
    reader = {"uvtable": read_uvtable, "npz": read_npz, "hdf5": read_hdf5}[fmt]
    return reader(path, **kwargs)


def save_visibilities(vis: Visibilities, path, **kwargs) -> Path:
    """Write ``vis`` in the format given by the extension of ``path`` (see :func:`load_visibilities`).

    Existing files are replaced atomically. Keyword arguments go to the writer.
    """
    path = Path(path)
    fmt = _format_of(path)
    if fmt == "ms":
        from .measurement_set import write_ms

        return write_ms(vis, path, **kwargs)
    writer = {"uvtable": write_uvtable, "npz": write_npz, "hdf5": write_hdf5}[fmt]
    return writer(vis, path, **kwargs)


# ----------------------------------------------------------------------------------
# deprojected radial binning
# ----------------------------------------------------------------------------------
@dataclass
class BinnedVisibilities:
    """Visibilities averaged in annuli of deprojected baseline length.

    Only bins holding at least one visibility are kept.

    Attributes
    ----------
    q : ndarray
        Bin centres [lambda] (deprojected baseline length ``hypot(u', v')``).
    q_low, q_high : ndarray
        Bin edges [lambda].
    re, im : ndarray
        Weighted means of Re V' and Im V' [Jy] (V' re-centred on the disc, not rescaled by cos i).
    re_err, im_err : ndarray
        Their standard errors from the weights, ``1 / sqrt(sum w)`` [Jy].
    counts : ndarray of int
        Number of visibilities in each bin.
    weight_sum : ndarray
        Sum of the weights in each bin [Jy^-2].
    geometry : DiscGeometry
        The geometry used to deproject.
    """

    q: np.ndarray
    q_low: np.ndarray
    q_high: np.ndarray
    re: np.ndarray
    im: np.ndarray
    re_err: np.ndarray
    im_err: np.ndarray
    counts: np.ndarray
    weight_sum: np.ndarray
    geometry: "DiscGeometry"

    @property
    def V(self) -> np.ndarray:
        """Binned complex visibilities [Jy]."""
        return self.re + 1j * self.im

    def __len__(self) -> int:
        return self.q.size


def _bin_edges(qmax: float, bin_width: float | None, bins) -> np.ndarray:
    if bin_width is not None and bins is not None:
        raise ValueError("give either bin_width or bins, not both")
    if bins is not None and np.ndim(bins) == 0:
        n = int(bins)
        if n < 1:
            raise ValueError(f"bins must be a positive number of bins, got {bins!r}")
        return np.linspace(0.0, qmax * (1 + 1e-12), n + 1)
    if bins is not None:
        edges = np.asarray(bins, dtype=float)
        if edges.ndim != 1 or edges.size < 2 or np.any(np.diff(edges) <= 0) or not np.isfinite(edges).all():
            raise ValueError("bins must be an increasing 1-D array of at least two finite edges [lambda]")
        return edges
    width = qmax / 100.0 if bin_width is None else float(bin_width)
    if not (np.isfinite(width) and width > 0):
        raise ValueError(f"bin_width must be a positive number of wavelengths, got {bin_width!r}")
    return np.arange(0.0, qmax + width, width)


def bin_deprojected(
    vis: Visibilities,
    geometry: "DiscGeometry | None" = None,
    *,
    bin_width: float | None = None,
    bins: int | Sequence[float] | None = None,
) -> BinnedVisibilities:
    """Average visibilities in annuli of deprojected baseline length (a "uvplot").

    The visibilities are re-centred and deprojected with
    :meth:`DiscGeometry.apply_correction` (no ``cos i`` flux rescaling), then binned in
    ``q = hypot(u', v')`` with inverse-variance weights.

    Parameters
    ----------
    vis : Visibilities
        Data; used in the frank/galario convention (:meth:`Visibilities.standardised`).
    geometry : DiscGeometry, optional
        Disc geometry; default face on and centred (no deprojection).
    bin_width : float, optional
        Bin width [lambda]; bins then start at q = 0.
    bins : int or sequence of float, optional
        Number of equal bins from 0 to the longest baseline, or the bin edges [lambda].
        Default (neither given): 100 equal bins.

    Returns
    -------
    BinnedVisibilities
    """
    from .geometry import DiscGeometry

    geometry = DiscGeometry() if geometry is None else geometry
    vis = vis.standardised()
    up, vp, Vp = geometry.apply_correction(vis.u, vis.v, vis.V)
    q = np.hypot(up, vp)
    edges = _bin_edges(float(q.max()), bin_width, bins)
    idx = np.digitize(q, edges) - 1
    inside = (idx >= 0) & (idx < edges.size - 1)
    if not inside.all():
        log.info("bin_deprojected: %d visibilities outside the bin edges ignored", int((~inside).sum()))
    nb = edges.size - 1
    w = vis.weights[inside]
    counts = np.bincount(idx[inside], minlength=nb)
    wsum = np.bincount(idx[inside], weights=w, minlength=nb)
    re = np.bincount(idx[inside], weights=w * Vp.real[inside], minlength=nb)
    im = np.bincount(idx[inside], weights=w * Vp.imag[inside], minlength=nb)
    keep = counts > 0
    err = 1.0 / np.sqrt(wsum[keep])
    return BinnedVisibilities(
        q=0.5 * (edges[:-1] + edges[1:])[keep], q_low=edges[:-1][keep], q_high=edges[1:][keep],
        re=re[keep] / wsum[keep], im=im[keep] / wsum[keep], re_err=err, im_err=err.copy(),
        counts=counts[keep], weight_sum=wsum[keep], geometry=geometry,
    )


# ----------------------------------------------------------------------------------
# weight re-estimation from the scatter in uv cells
# ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class WeightRescaling:
    """Result of :func:`estimate_weight_factor`.

    Attributes
    ----------
    factor : float
        Multiply the weights by this to make them match the scatter of the data.
    factor_error : float
        1-sigma statistical error of ``factor`` (``factor * sqrt(2 / dof)``).
    dof : int
        Degrees of freedom in the estimate, ``2 * sum(n_cell - 1)`` over cells (Re and Im).
    n_cells : int
        Number of cells holding two or more visibilities.
    bin_width : float
        Cell size [lambda].
    binning : str
        ``'deprojected annuli'`` (with a geometry) or ``'uv cells'`` (without).
    """

    factor: float
    factor_error: float
    dof: int
    n_cells: int
    bin_width: float
    binning: str

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def _cell_index(vis: Visibilities, geometry, bin_width: float | None) -> tuple[np.ndarray, np.ndarray, float, str]:
    """Cell of each visibility, the visibilities to use (re-centred/folded) and the cell size."""
    V = vis.standardised().V
    if geometry is not None:
        up, vp, V = geometry.apply_correction(vis.u, vis.v, V)
        q = np.hypot(up, vp)
        width = bin_width or _default_width(q.max() - q.min(), vis.n, ndim=1)
        return np.floor((q - q.min()) / width).astype(np.int64), V, width, "deprojected annuli"
    # fold onto the half plane v >= 0 using V(-u, -v) = conj V(u, v), so that both halves share cells
    flip = (vis.v < 0) | ((vis.v == 0) & (vis.u < 0))
    u, v = np.where(flip, -vis.u, vis.u), np.where(flip, -vis.v, vis.v)
    V = np.where(flip, np.conj(V), V)
    width = bin_width or _default_width(float(np.hypot(u, v).max()), vis.n, ndim=2)
    iu, iv = np.floor(u / width).astype(np.int64), np.floor(v / width).astype(np.int64)
    _, cell = np.unique(np.stack([iu, iv]), axis=1, return_inverse=True)
    return cell.ravel(), V, width, "uv cells"


def _default_width(extent: float, n: int, ndim: int, per_cell: float = 10.0) -> float:
    """Cell size giving about ``per_cell`` points per cell for uniform coverage."""
    if ndim == 1:
        return max(extent, 1.0) * per_cell / n
    return float(np.sqrt(0.5 * np.pi * max(extent, 1.0) ** 2 * per_cell / n))


def estimate_weight_factor(
    vis: Visibilities,
    geometry: "DiscGeometry | None" = None,
    *,
    bin_width: float | None = None,
    min_dof: int = 20,
) -> WeightRescaling:
    """Estimate one factor ``f`` such that ``f * weights`` matches the scatter of the data.

    Within each cell, the weighted mean of Re V and Im V is subtracted and
    ``chi2 = sum w (dRe^2 + dIm^2)`` accumulated; for correct weights its expectation is
    ``dof = 2 sum (n_cell - 1)``, and if the true weights are ``f w`` it is ``dof / f``. So
    ``f = dof / chi2``, with relative error ``sqrt(2 / dof)``. Like frank's
    ``estimate_weights`` this assumes the signal is nearly constant within a cell:
    structure in the source adds scatter and biases ``f`` low, so keep cells small
    (many visibilities per cell help).

    Parameters
    ----------
    vis : Visibilities
    geometry : DiscGeometry, optional
        If given, cells are annuli of deprojected baseline length of the re-centred data
        (assumes an axisymmetric source, as frank does). Otherwise square cells in the
        (u, v) plane, with the two half planes folded together (no symmetry assumed).
    bin_width : float, optional
        Cell size [lambda]. Default: about 10 visibilities per cell for uniform coverage.
    min_dof : int
        Fewer degrees of freedom than this raise :class:`ValueError`.

    Returns
    -------
    WeightRescaling
    """
    if bin_width is not None and not (np.isfinite(bin_width) and bin_width > 0):
        raise ValueError(f"bin_width must be a positive number of wavelengths, got {bin_width!r}")
    cell, V, width, binning = _cell_index(vis, geometry, bin_width)
    w = vis.weights
    wsum = np.bincount(cell, weights=w)
    counts = np.bincount(cell)
    wV = np.bincount(cell, weights=w * V.real) + 1j * np.bincount(cell, weights=w * V.imag)
    mean = np.divide(wV, wsum, out=np.zeros_like(wV), where=wsum > 0)  # empty cells never indexed
    chi2 = float(np.sum(w * np.abs(V - mean[cell]) ** 2))
    dof = int(2 * np.sum(np.maximum(counts - 1, 0)))
    if dof < min_dof or chi2 <= 0:
        raise ValueError(
            f"estimate_weight_factor: only {dof} degrees of freedom with cells of {width:.4g} lambda "
            f"({int((counts > 1).sum())} cells with 2+ visibilities); increase bin_width"
        )
    factor = dof / chi2
    return WeightRescaling(factor=factor, factor_error=factor * np.sqrt(2.0 / dof), dof=dof,
                           n_cells=int((counts > 1).sum()), bin_width=float(width), binning=binning)


def estimate_weights(
    vis: Visibilities,
    geometry: "DiscGeometry | None" = None,
    *,
    bin_width: float | None = None,
    method: str = "scatter",
) -> Visibilities:
    """Rescale the weights by one factor estimated from the scatter of the data.

    An explicit option — spiralbayes never rescales weights on its own. CASA weights are
    often not statistical (and uvplot's export halves them): this measures by how much.
    See :func:`estimate_weight_factor` for the estimator and its assumptions.

    Parameters
    ----------
    vis : Visibilities
    geometry : DiscGeometry, optional
        Bin in deprojected annuli (axisymmetric source) instead of uv cells.
    bin_width : float, optional
        Cell size [lambda].
    method : {'scatter'}
        The estimator (only one so far).

    Returns
    -------
    Visibilities
        A copy with weights ``factor * weights``; the factor, its error and the binning are
        recorded in ``provenance['weight_rescaling']`` and logged.
    """
    if method != "scatter":
        raise ValueError(f"method={method!r} is not known: use 'scatter'")
    result = estimate_weight_factor(vis, geometry, bin_width=bin_width)
    log.info(
        "weights rescaled by %.4g +/- %.2g (scatter in %d %s of %.4g lambda, %d dof)",
        result.factor, result.factor_error, result.n_cells, result.binning, result.bin_width, result.dof,
    )
    note = f"rescaled by {result.factor:.6g} (scatter within {result.binning})"
    record = {**result.to_dict(), "method": method,
              "geometry": None if geometry is None else geometry.to_dict()}
    new = vis.with_weights(vis.weights * result.factor, note)
    new.provenance["weight_rescaling"] = record
    return new
