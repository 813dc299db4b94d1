"""NumPy ``.npz`` archives: frank's keys, or the DSHARP ``ExportMS`` keys (u, v in metres)."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from .._provenance import atomic_path
from ..exceptions import InputError
from ..units import C_LIGHT
from ..visibilities import Visibilities
from ._common import (
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

__all__ = ["read_npz", "write_npz"]

log = logging.getLogger(__name__)

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
        raise InputError(f"{path}: cannot read as .npz without unpickling objects ({exc}); "
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
            raise InputError(
                f"{path}: keys {sorted(keys)} match no known layout; expected frank's "
                f"{list(_FRANK_KEYS)} or DSHARP ExportMS's {list(_DSHARP_KEYS)} (+ 'freq')"
            )
        raise InputError(f"{path}: holds both frank and DSHARP keys; pass layout='frank' or 'dsharp'")
    if layout not in complete:
        raise InputError(f"layout={layout!r} is not known: use 'frank' or 'dsharp'")
    if not complete[layout]:
        needed = _FRANK_KEYS if layout == "frank" else _DSHARP_KEYS
        missing = [k for k in needed if k not in keys]
        raise InputError(f"{path}: layout {layout!r} needs keys {list(needed)}; missing {missing}")
    return layout


def _npz_frank(path: Path, a: dict, units: str | None, wavelength) -> dict:
    explicit = units is not None
    units = units or "lambda"
    wle = wavelength
    if wle is None and "wavelength" in a and np.isfinite(a["wavelength"]).all():
        wle = float(a["wavelength"])
    u, v, conversions = _uv_to_lambda(a["u"], a["v"], units, wle, path)
    if units != "m":
        _guard_uv_units(u, v, path, wle, explicit)
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
            raise InputError(f"{path}: Wgt shape {wgt.shape} does not match Vis shape {vis.shape}") from None
    if vis.ndim == 2:
        return _dsharp_per_channel(path, u, v, vis, wgt, freq, units, wavelength)
    if units is None:
        if freq is None or freq.size != 1:
            raise InputError(
                f"{path}: DSHARP-style keys without one frequency per channel: the units of u, v "
                "are ambiguous (the DSHARP script wrote wavelengths, later variants metres); pass "
                "uv_units='lambda', or uv_units='m' with wavelength=<metres>"
            )
        units = "m"
    wle = _dsharp_wavelength(path, freq, u.size, wavelength)
    u, v, conversions = _uv_to_lambda(u, v, units, wle, path)
    if units != "m":
        _guard_uv_units(u, v, path, wle, explicit=True)
    mean_wle = None if wle is None else float(np.mean(wle))
    return dict(u=u, v=v, V=np.ravel(vis), weights=np.ravel(wgt), wavelength=mean_wle,
                conversions=conversions)


def _dsharp_wavelength(path: Path, freq, n_rows: int, wavelength):
    if wavelength is not None:
        return wavelength
    if freq is None:
        return None
    if freq.size not in (1, n_rows):
        raise InputError(f"{path}: {freq.size} frequencies for {n_rows} rows; expected 1 or one per row")
    wle = C_LIGHT / _check_wavelength(freq, f"{path} (frequencies)")
    return float(wle[0]) if freq.size == 1 else wle


def _dsharp_per_channel(path: Path, u, v, vis, wgt, freq, units, wavelength) -> dict:
    n_chan, n_rows = vis.shape
    if u.size != n_rows:
        raise InputError(f"{path}: Vis has shape (n_chan, n_rows) = {vis.shape} but u has {u.size} rows")
    if units not in (None, "m"):
        raise InputError(f"{path}: per-channel Vis of shape {vis.shape} needs u, v in metres (one per row, "
                         f"converted per channel); uv_units={units!r} cannot be applied")
    if wavelength is not None:
        wle = np.broadcast_to(_check_wavelength(wavelength, str(path)).reshape(-1, 1), (n_chan, 1))
    elif freq is not None and freq.size == n_chan:
        wle = (C_LIGHT / _check_wavelength(freq, f"{path} (freq)")).reshape(-1, 1)
    else:
        raise InputError(f"{path}: Vis has {n_chan} channels but 'freq' has "
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
