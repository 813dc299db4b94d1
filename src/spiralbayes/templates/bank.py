"""The :class:`TemplateBank`: many spiral templates in one HDF5 file, and the cached built-in banks.

* :func:`~spiralbayes.templates.variants.default_bank` — the morphology-robust bank (the paper's grid
  in the compromise, hydro and wakeflow morphologies, 576 templates; :mod:`.variants`), the bank of
  every stage and command unless told otherwise;
* :func:`compromise_bank` — the paper's grid in the single compromise morphology (192 templates),
  for comparisons with the paper; limits from it are not robust to the spiral's shape.

HDF5 layout (``format_version`` 1)::

    /                      attrs: kind = "spiralbayes.TemplateBank", format_version,
                                  provenance (JSON), order (JSON list of names), generator_key
    /templates/<name>/     datasets: delta (float32, n_x × n_phi), x (float64), phi (float64)
                           attrs: mass, tau0, beta, h_p, flaring, wavelength, hand, name,
                                  provenance (JSON)

δ is stored as float32 (7 significant digits, far below the physics' accuracy), which keeps the
paper's 64-template grid at 320 × 720 cells to 59 MB in memory and on disk (177 MB for the
compromise bank's three aspect ratios, three times that for the default bank's three morphologies).
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import time
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path

import numpy as np

from .._hdf5 import open_file, write_file
from .._provenance import FORMAT_VERSION, provenance_record, to_json
from ..exceptions import DataFileError, InputError
from .generator import paper_grid
from .template import SpiralTemplate, repeated_names, validate_hand
from .wake import WakeSettings

__all__ = ["DEFAULT_H_PS", "TemplateBank", "cached_bank", "compromise_bank", "default_cache_dir"]

log = logging.getLogger(__name__)

BANK_KIND = "spiralbayes.TemplateBank"


class TemplateBank(Sequence):
    """An ordered collection of :class:`SpiralTemplate` with unique names.

    Parameters
    ----------
    templates : iterable of SpiralTemplate
        The templates; names must be unique.
    provenance : dict, optional
        How the bank was made (JSON-serialisable).

    Notes
    -----
    ``bank[i]`` and ``bank["name"]`` both work; iteration yields templates in order.
    """

    def __init__(self, templates: Iterable[SpiralTemplate] = (), provenance: dict | None = None):
        self._templates: list[SpiralTemplate] = list(templates)
        for t in self._templates:
            if not isinstance(t, SpiralTemplate):
                raise TypeError(f"TemplateBank holds SpiralTemplate objects, got {type(t).__name__}")
        names = [t.name for t in self._templates]
        dupes = repeated_names(self._templates)
        if dupes:
            raise InputError(f"template names must be unique in a bank; duplicated: {dupes}")
        self._index = {n: i for i, n in enumerate(names)}
        self.provenance = dict(provenance or {})

    # ----------------------------------------------------------------- container protocol
    def __len__(self) -> int:
        return len(self._templates)

    def __iter__(self) -> Iterator[SpiralTemplate]:
        return iter(self._templates)

    def __getitem__(self, key):
        if isinstance(key, str):
            try:
                return self._templates[self._index[key]]
            except KeyError:
                raise KeyError(f"no template named {key!r} in the bank; see TemplateBank.names") from None
        if isinstance(key, slice):
            return TemplateBank(self._templates[key], self.provenance)
        return self._templates[key]

    def __contains__(self, key) -> bool:
        if isinstance(key, str):
            return key in self._index
        return any(t is key for t in self._templates)

    def __repr__(self) -> str:  # pragma: no cover - cosmetic
        return f"TemplateBank({len(self)} templates)"

    @property
    def names(self) -> list[str]:
        """Template names, in order."""
        return [t.name for t in self._templates]

    @property
    def parameters(self) -> np.ndarray:
        """Structured array with fields ``name, mass, tau0, beta, hand, h_p, flaring, wavelength``
        (one row per template, in order)."""
        dtype = [("name", "U64"), ("mass", "f8"), ("tau0", "f8"), ("beta", "f8"), ("hand", "U1"),
                 ("h_p", "f8"), ("flaring", "f8"), ("wavelength", "f8")]
        rows = [(t.name, t.mass, t.tau0, t.beta, t.hand, t.h_p, t.flaring, t.wavelength)
                for t in self._templates]
        return np.array(rows, dtype=dtype)

    def nbytes(self) -> int:
        """Memory held by the δ maps [bytes]."""
        return int(sum(t.delta.nbytes for t in self._templates))

    # ----------------------------------------------------------------- selection
    def select(self, *, mass=None, tau0=None, beta=None, hand=None, h_p=None, rtol: float = 1e-6) -> TemplateBank:
        """Sub-bank of templates matching every given criterion.

        Each criterion is a scalar or a list of accepted values; floats compare with relative
        tolerance ``rtol``; ``hand`` is 'R'/'L' (case-insensitive). ``None`` means any.
        """
        def accepted(value, wanted):
            if wanted is None:
                return True
            vals = np.atleast_1d(np.asarray(wanted, dtype=float))
            return bool(np.any(np.isclose(value, vals, rtol=rtol, atol=0.0)))

        hands = None
        if hand is not None:
            hands = {validate_hand(h) for h in ([hand] if isinstance(hand, str) else hand)}
        out = [
            t for t in self._templates
            if accepted(t.mass, mass) and accepted(t.tau0, tau0) and accepted(t.beta, beta)
            and accepted(t.h_p, h_p) and (hands is None or t.hand in hands)
        ]
        return TemplateBank(out, self.provenance)

    def get(self, mass: float, tau0: float, beta: float, hand: str = "R", h_p: float | None = None) -> SpiralTemplate:
        """The single template with these parameters (``LookupError`` if none or several; give
        ``h_p`` when the bank holds several aspect ratios)."""
        sub = self.select(mass=mass, tau0=tau0, beta=beta, hand=hand, h_p=h_p)
        if len(sub) != 1:
            p = self.parameters
            raise LookupError(
                f"{len(sub)} templates match mass={mass}, tau0={tau0}, beta={beta}, hand={hand!r}, h_p={h_p}; "
                f"available (mass, tau0, h_p): {sorted(set(zip(p['mass'], p['tau0'], p['h_p'])))}"
            )
        return sub[0]

    # ----------------------------------------------------------------- I/O
    def save(self, path, *, compression: str | None = None) -> Path:
        """Write the bank to HDF5 atomically (temporary file, then rename).

        Parameters
        ----------
        path : str or Path
            Output file (conventionally ``.h5``).
        compression : {None, 'lzf', 'gzip'}
            Dataset compression (default none: fastest to load).
        """
        prov = provenance_record(**{k: v for k, v in self.provenance.items() if k != "created"})
        with write_file(path, BANK_KIND) as f:
            f.attrs["provenance"] = to_json(prov, sort_keys=True)
            f.attrs["order"] = json.dumps(self.names)
            if "generator_key" in self.provenance:
                f.attrs["generator_key"] = str(self.provenance["generator_key"])
            grp = f.create_group("templates")
            for t in self._templates:
                t.to_hdf5_group(grp.create_group(t.name), compression=compression)
        log.info("wrote %d templates to %s", len(self), path)
        return Path(path)

    @classmethod
    def load(cls, path) -> TemplateBank:
        """Read a bank written by :meth:`save`.

        A missing, truncated or corrupt file raises :class:`~spiralbayes.exceptions.MissingFileError`
        or :class:`~spiralbayes.exceptions.DataFileError` naming it.
        """
        with open_file(path, BANK_KIND, "template bank") as f:
            version = int(f.attrs.get("format_version", -1))
            if version > FORMAT_VERSION:
                raise DataFileError(f"{path} has format_version {version}, newer than this spiralbayes "
                                    f"({FORMAT_VERSION}); upgrade spiralbayes")
            if "templates" not in f:
                raise DataFileError(f"{path} holds no templates group; rebuild or re-download it")
            order = json.loads(f.attrs["order"]) if "order" in f.attrs else sorted(f["templates"])
            prov = json.loads(f.attrs.get("provenance", "{}"))
            templates = [SpiralTemplate.from_hdf5_group(f["templates"][name]) for name in order]
        return cls(templates, prov)


def default_cache_dir() -> Path:
    """The user's cache directory for spiralbayes: ``$SPIRALBAYES_CACHE`` if set, else
    ``$XDG_CACHE_HOME/spiralbayes``, else ``~/.cache/spiralbayes``."""
    env = os.environ.get("SPIRALBAYES_CACHE")
    if env:
        return Path(env).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg).expanduser() if xdg else Path.home() / ".cache"
    return base / "spiralbayes"


def cached_bank(path: Path, key_field: str, key: str, n_expected: int, rebuild: bool = False) -> TemplateBank | None:
    """The bank cached at ``path`` if it was built from the same inputs (its provenance's ``key_field``
    is ``key`` and it holds ``n_expected`` templates); None when it is missing, stale, unreadable or
    ``rebuild`` is asked for (the caller then builds and saves it)."""
    if rebuild or not path.exists():
        return None
    try:
        bank = TemplateBank.load(path)
    except (ValueError, OSError, KeyError) as exc:
        log.warning("cached bank %s unreadable (%s); rebuilding", path, exc)
        return None
    if bank.provenance.get(key_field) == key and len(bank) == n_expected:
        log.debug("loaded cached template bank %s", path)
        return bank
    log.warning("cached bank %s does not match its inputs; rebuilding", path)
    return None


DEFAULT_H_PS = (0.05, 0.07, 0.10)
"""Disc aspect ratios ``H/r`` at r_p of the default bank (the paper fixes 0.07; 0.05 and 0.10
bracket the discs surveyed, and planets in discs thinner or thicker than the template are missed
or mis-located: see docs/templates.md)."""


def compromise_bank(cache_dir: str | os.PathLike | None = None, rebuild: bool = False,
                    progress: bool = False, h_ps: Sequence[float] = DEFAULT_H_PS, **options) -> TemplateBank:
    """The single-morphology bank: the paper's 64-template grid for each ``H/r`` in ``h_ps``
    (default {0.05, 0.07, 0.10}: 192 templates), from the built-in generator (the compromise
    morphology), cached on disk. Limits from it assume that one shape and are not robust to the
    spiral's morphology; :func:`~spiralbayes.templates.variants.default_bank` is.

    Built on first use with :func:`~spiralbayes.templates.generator.paper_grid` (seconds) and
    stored as ``bank-<key>.h5`` in ``cache_dir`` (default :func:`.default_cache_dir`), where ``key`` hashes
    the generator settings, version and ``h_ps``, so a changed generator rebuilds. Loading a cached
    bank takes well under a second. Select one aspect ratio with ``bank.select(h_p=0.07)``.

    Parameters
    ----------
    cache_dir : path, optional
        Where to cache the bank.
    rebuild : bool
        Rebuild even if a cached copy exists.
    progress : bool
        Show a progress bar while building.
    h_ps : sequence of float
        Disc aspect ratios ``H/r`` at r_p.
    **options
        Other :class:`~spiralbayes.templates.wake.WakeSettings` fields (e.g. ``n_phi``, ``wavelength``).

    Returns
    -------
    TemplateBank
        The paper's 64 templates for each H/r of ``h_ps`` (192 with the default three), one morphology.
    """
    if "h_p" in options:
        h_ps = (options.pop("h_p"),)
    h_ps = tuple(float(h) for h in np.atleast_1d(h_ps))
    settings = WakeSettings(h_p=h_ps[0], **options)
    key = _bank_key(settings, h_ps)
    n_expected = 64 * len(h_ps)
    folder = Path(cache_dir).expanduser() if cache_dir is not None else default_cache_dir()
    path = folder / f"bank-{key}.h5"
    cached = cached_bank(path, "generator_key", key, n_expected, rebuild)
    if cached is not None:
        return cached
    t0 = time.perf_counter()
    templates = paper_grid(h_ps=h_ps, progress=progress, **options)
    bank = TemplateBank(templates, {"generator_key": key, "generator_settings": settings.to_dict(),
                                    "h_ps": list(h_ps),
                                    "generator": "spiralbayes.templates.generator.paper_grid"})
    log.info("built the compromise template bank (%d templates) in %.1f s", len(bank), time.perf_counter() - t0)
    try:
        bank.save(path)
    except OSError as exc:  # read-only cache: still return the bank
        log.warning("could not cache the template bank at %s (%s)", path, exc)
    return bank


def _bank_key(settings: WakeSettings, h_ps: tuple) -> str:
    """Cache key: the generator settings' key (with the first H/r) and every H/r of the bank."""
    if len(h_ps) == 1:
        return settings.key()
    blob = settings.key() + json.dumps([round(h, 12) for h in h_ps])
    return hashlib.sha256(blob.encode()).hexdigest()[:16]
