"""The learned model's training data: isothermal gas runs read from reduced FARGO3D files.

:func:`read_training_runs` reads every usable run of the reduced reference files
(``tests/data/references/...``, layout in tools/README.md, "File layout") as a :class:`TrainingRun`:
its physics point (planet mass, ``H/r``, surface-density slope, viscosity, age) and its
surface-density maps. :func:`row_weight` is the per-radius weight the visibilities give a map,
with which the model's bases are fitted.

Masses are in thermal masses ``M_th = h_p³ M_*``; ``α`` is the Shakura–Sunyaev parameter at
``r_p`` (``ν = α h_p² r_p² Ω_p``); ages in orbits of the planet.
"""

from __future__ import annotations

import json
import logging
import math
import re
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..._hdf5 import open_reference
from ...exceptions import DataFileError, InputError

__all__ = ["DISC_EXTENT", "FLARING", "MAX_CHANGE", "NUMERICAL_CHECKS", "OUTSIDE_WEIGHT", "PARAMETERS",
           "REFERENCE_FILES", "WEIGHT_TAU0", "TrainingRun", "parameter_vector", "read_training_runs",
           "reference_files", "row_weight"]

log = logging.getLogger(__name__)

PARAMETERS = ("ln_mass", "h_p", "slope", "log10_alpha", "ln_orbits")
"""The regression's inputs, in order: ``ln(M_p/M_th)``, ``H/r`` at r_p, surface-density slope ``p``
(Σ ∝ r^-p), ``log10 α`` at r_p, ``ln`` of the age in orbits."""

FLARING = 0.25
"""Flaring index of the training runs (``H/r ∝ r^0.25``: FARGO3D's ``FLARINGINDEX``; ``c_s ∝ r^-1/4``)."""

NUMERICAL_CHECKS = ("soft", "res")
"""Prefixes of the library's ``variant`` attribute that mark checks of one numerical setting
(softening ``soft0.35``, resolution ``res14``): the same physics as another run, left out."""

MAX_CHANGE = 0.5
"""Largest RMS change of δΣ/Σ over a run's last 5 orbits for it to be trained on (the references'
rule, ``tests/templates/fidelity.py``: above it, vortices at the gap edges dominate the map)."""

WEIGHT_TAU0 = 1.0
"""Optical depth of the brightness in :func:`row_weight` (between the bank's 0.3 and 3)."""

DISC_EXTENT = (0.2, 2.2)
"""The fiducial disc in ``x = r/r_p`` (10–110 au around a planet at 50 au); rows outside it are
weighted :data:`OUTSIDE_WEIGHT` times less."""

OUTSIDE_WEIGHT = 0.3
"""Relative weight of the rows outside :data:`DISC_EXTENT` (:func:`row_weight`)."""

REFERENCE_FILES = ("continuum/fargo3d_continuum.h5", "fargo3d_library.h5", "physics/fargo3d_library.h5",
                   "fargo3d_isothermal.h5")
"""The reduced FARGO3D files the model is trained on, relative to a checkout's ``tests/data/references``:
the continuum design, the library, the disc physics set and the two older isothermal runs."""


def reference_files(root=None) -> list[Path]:
    """The training files :data:`REFERENCE_FILES` in ``root`` (default: the ``tests/data/references``
    folder of the repository checkout this package is installed from).

    Raises
    ------
    InputError
        A file is missing (e.g. a package installed from a wheel, which carries no reference files):
        the message says to pass the files, or ``root``, explicitly.
    """
    base = Path(root) if root is not None else Path(__file__).resolve().parents[4] / "tests" / "data" / "references"
    paths = [base / name for name in REFERENCE_FILES]
    missing = [str(p) for p in paths if not p.exists()]
    if missing:
        raise InputError(f"the learned model's training files {missing} are not there: run from a clone of the "
                         "spiralbayes repository (pip install -e .) or give the reduced FARGO3D files explicitly")
    return paths


def row_weight(x) -> np.ndarray:
    """Per-row weight of the maps in the basis fit, ``w(x) ∝ x I_axi(x)``, maximum 1.

    ``I_axi ∝ x^-1/2 (1 − e^{−τ/x})`` (T ∝ r^-1/2, Σ ∝ r^-1, τ = :data:`WEIGHT_TAU0` at the planet):
    the squared weighted map ``w² δ²`` is ``δ² I² x² dln x``, the disc-area integral of the
    brightness perturbation the visibilities see on a log-spaced grid. Rows outside
    :data:`DISC_EXTENT` count :data:`OUTSIDE_WEIGHT` times less.

    Parameters
    ----------
    x : array
        ``r / r_p``, positive.

    Returns
    -------
    array
        Weights, the shape of ``x``.
    """
    x = np.asarray(x, dtype=float)
    w = x * x**-0.5 * -np.expm1(-WEIGHT_TAU0 / x)
    w = w * np.where((x >= DISC_EXTENT[0]) & (x <= DISC_EXTENT[1]), 1.0, OUTSIDE_WEIGHT)
    return w / w.max()


def parameter_vector(mass: float, h_p: float, slope: float, alpha: float, orbits: float) -> np.ndarray:
    """The regression inputs (:data:`PARAMETERS`) of one physics point.

    Parameters
    ----------
    mass, h_p, slope, alpha, orbits : float
        ``M_p/M_th``, ``H/r`` at r_p, Σ slope ``p``, ``α`` at r_p, age [orbits].

    Returns
    -------
    (5,) array
        ``(ln M_p, h_p, p, log10 α, ln orbits)``.
    """
    return np.array([math.log(mass), h_p, slope, math.log10(alpha), math.log(orbits)], dtype=float)


@dataclass(frozen=True, eq=False)
class TrainingRun:
    """One reduced hydrodynamic run (tools/README.md, "File layout").

    Attributes
    ----------
    name : str
        ``<source>:<group>``, e.g. ``library:h0.07_mu1`` (source: the file's folder, or its stem for
        files in ``tests/data/references``).
    mass : float
        Planet mass ``M_p/M_th``.
    h_p : float
        ``H/r`` at r_p.
    slope : float
        Surface-density slope ``p`` (initial Σ ∝ r^-p).
    alpha : float
        Viscosity ``α`` at r_p (``ν / h_p²``).
    orbits : float
        Age of the map [planet orbits].
    x : (n_x,) array
        ``r / r_p``.
    phi : (n_phi,) array
        Azimuths [rad], uniform, planet at 0.
    dsigma : (n_x, n_phi) array
        ``δΣ/Σ = Σ/⟨Σ⟩_φ − 1`` (hand R).
    gap : (n_x,) array
        ``⟨Σ⟩_φ / Σ_init`` (the planet's gap); NaN where ``valid`` is False.
    valid : (n_x,) bool array
        Rows inside the run's undamped domain.
    file : str
        The reduced file it was read from (its group is the name after the colon).
    """

    name: str
    mass: float
    h_p: float
    slope: float
    alpha: float
    orbits: float
    x: np.ndarray
    phi: np.ndarray
    dsigma: np.ndarray
    gap: np.ndarray
    valid: np.ndarray
    file: str = ""

    @property
    def group(self) -> str:
        """The run's group in ``file``."""
        return self.name.split(":", 1)[1]

    @property
    def inputs(self) -> np.ndarray:
        """The regression inputs (:data:`PARAMETERS`)."""
        return parameter_vector(self.mass, self.h_p, self.slope, self.alpha, self.orbits)

    @property
    def parameters(self) -> dict:
        """``{mass, h_p, slope, alpha, orbits}``: the arguments of
        :meth:`~spiralbayes.templates.learned.model.LearnedTemplateModel.predict`."""
        return {"mass": self.mass, "h_p": self.h_p, "slope": self.slope, "alpha": self.alpha,
                "orbits": self.orbits}


def _source_label(path: Path) -> str:
    stem = path.stem.removeprefix("fargo3d_")
    return stem if path.parent.name == "references" else path.parent.name


def _last_change(attrs) -> float:
    steady = attrs.get("steadiness")
    if steady is None:
        return 0.0
    steady = json.loads(steady) if isinstance(steady, (str, bytes)) else dict(steady)
    orbits = float(attrs.get("orbits", 0.0))
    return float(steady.get(f"rms_rel_diff_vs_orbit_{orbits - 5:g}", 0.0))


def _text(attrs, key: str, default: str = "") -> str:
    """A string attribute (h5py may return bytes); ``default`` where it is missing or None."""
    v = attrs.get(key)
    return default if v is None else (v.decode() if isinstance(v, bytes) else str(v))


def _physics_key(attrs) -> tuple:
    """What makes two groups one disc and planet at different ages (a run and its continuation)."""
    visc = float(attrs["alpha_at_rp"]) if "alpha_at_rp" in attrs else float(attrs.get("nu", 0.0))
    # a continuation's variant is its run's with the age appended ("slope1_alpha2.0e-03_orbits200")
    variant = re.sub(r"_?orbits[0-9.e+]+$", "", _text(attrs, "variant"))
    numbers = [round(float(attrs.get(k, 0.0) or 0.0), 10) for k in ("stokes", "beta", "h_p", "mu_Mth", "p_sigma")]
    return (_text(attrs, "fluid", "gas"), variant, *numbers, round(visc, 12))


def _later_changes(groups) -> dict:
    """``{physics key: [(orbits, change over the last 5 orbits), ...]}`` over a file's finished groups."""
    out: dict = {}
    for attrs in groups:
        if "orbits" in attrs and not str(attrs.get("run_state", "finished")).startswith("running"):
            out.setdefault(_physics_key(attrs), []).append((float(attrs["orbits"]), _last_change(attrs)))
    return out


def _skip_reason(attrs, max_change: float, ages: dict | None = None) -> str | None:
    """Why a group is not a training run of the isothermal gas model (None: it is one).

    ``ages`` (:func:`_later_changes` of the group's file) adds the transient rule: a map is not trained
    on when a later age of the same disc and planet is not quasi-steady, since the map is then a stage
    on the way to vortices, not a state the planet keeps."""
    fluid = _text(attrs, "fluid", "gas")
    if fluid != "gas" or float(attrs.get("stokes", 0.0) or 0.0) > 0:
        return f"fluid {fluid!r} (the model is of the gas)"
    if float(attrs.get("beta", 0.0) or 0.0) > 0:
        return f"beta = {float(attrs['beta']):g} (the model is locally isothermal)"
    variant = _text(attrs, "variant")
    if variant.startswith(NUMERICAL_CHECKS):
        return f"a check of one numerical setting ({variant})"
    if str(attrs.get("run_state", "finished")).startswith("running"):
        return "still running"
    change = _last_change(attrs)
    if change > max_change:
        return f"not quasi-steady (δΣ/Σ changes by {change:.0%} in 5 orbits > {max_change:.0%})"
    for key in ("h_p", "mu_Mth", "orbits"):
        if key not in attrs:
            return f"no {key!r} attribute"
    unsteady = [(o, c) for o, c in (ages or {}).get(_physics_key(attrs), [])
                if o > float(attrs["orbits"]) and c > max_change]
    if unsteady:
        o, c = min(unsteady)
        return (f"a transient (the same run at {o:g} orbits is not quasi-steady: δΣ/Σ changes by {c:.0%} "
                f"in 5 orbits > {max_change:.0%})")
    return None


def _read_file(path: Path, max_change: float, drop_transients: bool) -> list[TrainingRun]:
    """The training runs of one reduced file."""
    import h5py

    source = _source_label(path)
    runs = []
    with open_reference(path, "reduced reference file") as f:
        if "x" not in f or "phi" not in f:
            raise DataFileError(f"{path} has no root 'x' and 'phi' datasets: not a reduced reference file "
                                "(tools/README.md, 'File layout')")
        x, phi = f["x"][()].astype(float), f["phi"][()].astype(float)
        skipped: list[str] = []
        ages = _later_changes(f[n].attrs for n in f if isinstance(f[n], h5py.Group)) if drop_transients else None
        for name in sorted(f):
            g = f[name]
            if not isinstance(g, h5py.Group):
                continue
            a = g.attrs
            reason = _skip_reason(a, max_change, ages)
            if reason is None and not {"dsigma", "sigma_axisym"} <= set(g):
                reason = "no dsigma or sigma_axisym dataset"
            if reason is not None:
                log.debug("%s:%s not trained on: %s", path.name, name, reason)
                skipped.append(reason.split(" (")[0])
                continue
            h_p = float(a["h_p"])
            slope = float(a.get("p_sigma", 1.0))
            alpha = float(a["alpha_at_rp"]) if "alpha_at_rp" in a else float(a["nu"]) / h_p**2
            valid = g["valid"][()].astype(bool) if "valid" in g else np.ones(x.size, bool)
            gap = np.where(valid, g["sigma_axisym"][()].astype(float) * x**slope, np.nan)
            runs.append(TrainingRun(f"{source}:{name}", float(a["mu_Mth"]), h_p, slope, alpha, float(a["orbits"]),
                                    x, phi, g["dsigma"][()].astype(float), gap, valid, str(path)))
    if skipped:
        counts = ", ".join(f"{n} {why}" for why, n in sorted(Counter(skipped).items()))
        log.info("%s: %d runs read, %d not trained on (%s; -v names them)", path.name,
                 len(runs), len(skipped), counts)
    return runs


def read_training_runs(paths: Iterable, *, max_change: float = MAX_CHANGE,
                       drop_transients: bool = False) -> list[TrainingRun]:
    """The isothermal gas runs of reduced reference files (tools/README.md, "File layout").

    Every group of each file is read except dust (``fluid`` not gas, ``stokes > 0``), β-cooled runs
    (``beta > 0``), checks of one numerical setting (``variant`` starting with
    :data:`NUMERICAL_CHECKS`), runs still going and maps that are not quasi-steady (RMS change of
    δΣ/Σ over the last 5 orbits above ``max_change``); with ``drop_transients`` also maps of a run whose
    later age, reduced into the same file (its continuation: same disc and planet), is not quasi-steady.
    Each skip is logged. Files that gain groups
    (runs reduced later) give more runs on the next call.

    Parameters
    ----------
    paths : iterable of path
        Reduced HDF5 files (``fargo3d_library.h5`` layout: root ``x``, ``phi``; one group per run with
        ``dsigma``, ``sigma_axisym``, ``valid`` and the attributes ``h_p``, ``mu_Mth``, ``p_sigma``,
        ``nu`` or ``alpha_at_rp``, ``orbits``).
    max_change : float
        Largest relative change over the last 5 orbits (default :data:`MAX_CHANGE`).
    drop_transients : bool
        Leave out transients, the maps on the way to a later map that is not quasi-steady (default
        False: they are trained on; docs/templates.md, "Runs still changing at 20 orbits").

    Returns
    -------
    list of TrainingRun
        Sorted by name.

    Raises
    ------
    InputError
        A file does not exist, or two files hold runs of one name.
    DataFileError
        A file is not a reduced reference file (no root ``x`` and ``phi``), or is corrupt.
    """
    runs = []
    for path in paths:
        path = Path(path)
        if not path.exists():
            raise InputError(f"reference file {path} does not exist: give reduced FARGO3D files "
                             "(tests/data/references/...; tools/README.md, 'File layout')")
        runs += _read_file(path, max_change, drop_transients)
    names = [r.name for r in runs]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise InputError(f"training runs {twice} come from more than one file: give each file once")
    return sorted(runs, key=lambda r: r.name)
