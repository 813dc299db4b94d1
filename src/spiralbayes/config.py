"""One configuration schema for every command (``scan``, ``sample``, ``limits``, ``compare``) and for
notebooks (TOML files).

Every option has a default (from Stevenson et al. 2024 where the paper sets one) and a
description with units; unknown sections or keys are rejected with the list of valid ones, and
the configuration actually used is saved beside every output. ``spiralbayes scan
--print-config`` (or ``sample --print-config``) writes the documented default file. The same file
drives every command: ``scan`` reads ``[data]`` to ``[alternatives]`` (with ``[calibration] solve``
set, it solves antenna gains after the frank fit and searches the corrected data), ``sample`` adds ``[sample]``
and ``[priors]``, ``limits`` adds ``[limits]`` (the last two reuse the scan's outputs when they
are in ``[output] dir``); ``compare`` runs
the scan and the image-plane comparisons of ``[compare]`` (needs CASA). Relative paths — inputs and
``[output] dir`` alike — are taken relative to the configuration file, so a configuration means
the same wherever it is run from.

Values are checked when the file is read (the settings dataclasses of :data:`SECTION_SETTINGS` and,
for the other sections, :data:`CHECKS`): a wrong type, a value out of range or an unknown choice
raises :class:`~spiralbayes.exceptions.ConfigError` naming the option (``section.key``) and what it
accepts, before any data is read or any fit is run.
"""

from __future__ import annotations

import copy
import math
import re
import warnings
from collections.abc import Callable
from dataclasses import fields
from pathlib import Path
from typing import Any, TypeVar

from ._compat import tomllib

from .axisymmetric.settings import FrankSettings
from .calibration.settings import CalibrationSettings
from .exceptions import ConfigError, MissingFileError
from .inference.detection.settings import AlternativesSettings
from .inference.limits.settings import LimitSettings
from .averaging import AVERAGING_MODES, DEFAULT_MAX_SMEARING
from .inference.posterior.settings import PriorSettings, SamplingSettings
from .inference.scan.settings import GRID_FIELDS, ScanSettings, field_error
from .settings import DEFAULT_DISTANCE_PC, MAX_DISTANCE_PC, MIN_DISTANCE_PC, config_options, from_config

__all__ = ["CHECKS", "PATH_KEYS", "RENAMED", "SCHEMA", "SECTION_SETTINGS", "default_config", "describe_config",
           "geometry_given", "load_config", "merge_config", "merge_section", "read_toml", "resolve_paths"]

# section -> key -> (default, description). The [frank], [calibration], [grid], [scan], [alternatives], [sample],
# [priors] and [limits] options are the fields of their settings dataclasses: each default is written once,
# where the code uses it.
SCHEMA: dict[str, dict[str, tuple[object, str]]] = {
    "data": {
        "path": ("", "visibility file: uvtable .txt/.npz, spiralbayes .h5, or a Measurement Set directory"),
        "uv_units": ("", "units of u, v in a uvtable: 'lambda' or 'm' (empty: from the file header, else lambda)"),
        "wavelength": (0.0, "observing wavelength [m] for u, v in metres (0: from the file)"),
        "conjugated": (False, "true if V is the complex conjugate of the CASA/frank convention (visread exports)"),
        "estimate_weights": (False, "rescale the weights from the scatter of the visibilities (CASA weights are often "
                                    "not statistical)"),
        "average": ("none", "average the visibilities before fitting: 'time' (per baseline, keeps antennas and times; "
                            "needs data that record them), 'uv' (in uv cells) or 'none'"),
        "max_smearing": (DEFAULT_MAX_SMEARING, "largest smearing of any averaged visibility, as a fraction of the "
                                               "model's L1 norm within [frank] Rmax (docs/performance.md)"),
        "time_bin": (0.0, "with average = 'time': longest average [s] (0: the smearing bound alone; with [calibration] "
                          "solve, the solution interval)"),
    },
    "geometry": {
        "inc": (0.0, "inclination [deg]"),
        "PA": (0.0, "position angle of the major axis, east of north [deg]"),
        "dRA": (0.0, "disc centre offset to the east [arcsec]"),
        "dDec": (0.0, "disc centre offset to the north [arcsec]"),
        "fit": (False, "fit the geometry with frank's nonparametric fitter (started from its Gaussian fit and the "
                       "values above)"),
        "distance": (DEFAULT_DISTANCE_PC, "distance [pc], for au axes and planet masses"),
    },
    "frank": {
        **config_options(FrankSettings),
        "model": ("", "a saved AxisymmetricModel (.h5) to use instead of fitting frank (empty: fit)"),
    },
    "calibration": config_options(CalibrationSettings),
    "templates": {
        "bank": ("default", "'default' (the built-in bank robust to the spiral's morphology: the paper's 64 templates "
                            "for H/r = 0.05, 0.07, 0.10 in the compromise, hydro and wakeflow morphologies, 576 "
                            "templates, cached; limits hold for every morphology; 'variants' is the same bank), "
                            "'compromise' (the same grid in the compromise morphology alone, 192 templates: the "
                            "paper's comparison, limits not robust to the spiral's shape; docs/limits.md), "
                            "'learned' (templates predicted by a model continuous in disc physics, learned_model, at "
                            "every mass, h_p, slope, alpha, orbits and tau0 given; isothermal, beta 0; cached; "
                            "docs/templates.md) or the path of a TemplateBank HDF5 file"),
        "learned_model": ("", "a saved LearnedTemplateModel (.h5: spiralbayes templates --fit-learned FILE) for "
                              "bank = 'learned'"),
        "slope": ([], "surface-density slopes p, Sigma ~ r^-p, of bank = 'learned' (empty: 0.5, 1, 1.5)"),
        "alpha": ([], "viscosities alpha at r_p of bank = 'learned' (empty: 2e-4, 1e-3, 1e-2)"),
        "orbits": ([], "planet ages [orbits] of bank = 'learned' (empty: 200)"),
        "maps": ([], "TemplateBank HDF5 files of maps from your own simulations (read_fargo3d, "
                     "read_fits_template, then TemplateBank(...).save) scanned beside the bank, filtered by mass, "
                     "tau0, beta and hand; test 3 then also tries the best template of the other kind at the "
                     "detection's position (docs/verdict.md)"),
        "mass": ([], "planet masses M_p/M_th to keep (empty: all)"),
        "tau0": ([], "initial optical depths at r_p to keep (empty: all)"),
        "beta": ([], "cooling times t_c Omega to keep (empty: all)"),
        "hand": ([], "'R' and/or 'L' (empty: both)"),
        "h_p": ([], "disc aspect ratios H/r at r_p (empty: all the bank has; the built-in banks have 0.05, 0.07, "
                    "0.10 and are made at any others given, e.g. a disc's measured H/r: at tau0 > 1 the limits hold "
                    "for the templates' H/r only, docs/limits.md 4d; with a bank file, the ones to keep)"),
    },
    "grid": config_options(ScanSettings, GRID_FIELDS),
    "scan": {
        **config_options(ScanSettings, [f.name for f in fields(ScanSettings)
                                        if f.metadata["config"] and f.name not in GRID_FIELDS]),
        "scheduler": ("", "Dask engine of the scan: empty or 'serial': in this process; 'local': a LocalCluster on "
                          "this machine; else a scheduler address (tcp://host:8786)"),
    },
    "alternatives": {
        "fit": (True, "fit the competing asymmetry models (geometry error, arc/vortex, lopsided, eccentric ring, "
                      "eccentric bright ring, m = 2) and apply test 3"),
        **config_options(AlternativesSettings),
        "refit_geometry": (True, "if no spiral is detected and the geometry alternative has Delta BIC > 10: refit "
                                 "frank at its geometry, rescan and decide again (OUTPUT/refit_geometry/)"),
    },
    "sample": {
        **config_options(SamplingSettings, ["run_name"]),
        "scan": ("", "a saved ScanResult (.h5) to start walkers from and prune templates (empty: OUTPUT/scan.h5 if "
                     "present)"),
        **config_options(SamplingSettings, [f.name for f in fields(SamplingSettings)
                                            if f.metadata["config"] and f.name != "run_name"]),
    },
    "priors": config_options(PriorSettings),
    "compare": {
        "residuals": ("visibilities", "'visibilities': CLEAN image of the residual visibilities (data - frank model); "
                                      "'difference': CLEAN image of the data minus that of the frank model at the "
                                      "same baselines (carries CLEAN artefacts)"),
        "weighting": ("briggs", "tclean weighting: 'natural', 'briggs' or 'uniform'"),
        "robust": (0.5, "Briggs robust parameter"),
        "deconvolver": ("hogbom", "tclean deconvolver: 'hogbom' or 'multiscale' (scales 0, 5, 15 pixels)"),
        "niter": (20000, "CLEAN iteration limit"),
        "threshold_sigma": (2.0, "CLEAN down to this many natural-weighted image noises 1/sqrt(sum w)"),
        "imsize": (0, "image size [pixels] (0: at least 6 r_out and 4 arcsec across)"),
        "cell": (0.0, "pixel [arcsec] (0: 1/(3 u_max))"),
        "r_out": (0.0, "outer disc radius [arcsec] for the residual statistic and the profile (0: 1.1 R_99 of the "
                       "frank profile)"),
        "keep_casa_files": (True, "keep the Measurement Sets, CASA images and CASA log in OUTPUT/casa"),
    },
    "limits": config_options(LimitSettings),
    "output": {
        "dir": ("spiralbayes-output", "directory for results and plots"),
        "plots": (True, "write heatmap PNGs"),
    },
}
"""section -> option -> ``(default, description)`` of every configuration option; the options of the
sections in :data:`SECTION_SETTINGS` (``[frank]``, ``[calibration]``, ``[alternatives]``, ``[sample]``,
``[priors]``, ``[limits]``) come from the fields of their settings dataclasses, the ``[grid]``
and ``[scan]`` options (but ``scheduler``) from :class:`~spiralbayes.inference.scan.settings.ScanSettings`."""

SECTION_SETTINGS: dict[str, type] = {
    "frank": FrankSettings,
    "calibration": CalibrationSettings,
    "alternatives": AlternativesSettings,
    "sample": SamplingSettings,
    "priors": PriorSettings,
    "limits": LimitSettings,
}
"""section -> the settings dataclass its options make; :func:`merge_config` builds each one, so that the
dataclass's own checks run when the file is read, before any data."""


BUILT_IN_BANKS = ("default", "variants", "compromise", "learned")
"""``[templates] bank`` values that name a built-in bank rather than a file: ``"default"`` and
``"variants"`` the morphology-robust bank, ``"compromise"`` the single-morphology bank, ``"learned"``
the bank a learned model (``[templates] learned_model``) predicts."""
LEARNED_OPTIONS = ("learned_model", "slope", "alpha", "orbits")
"""``[templates]`` options read only with ``bank = "learned"``."""
PATH_KEYS = (("data", "path"), ("frank", "model"), ("templates", "bank"), ("templates", "learned_model"),
             ("sample", "scan"), ("output", "dir"))
"""Every path option; relative ones are resolved against the configuration file's folder (``~`` is
expanded). ``templates.bank = "default"`` names the built-in bank, not a file."""
PATH_LIST_KEYS = (("templates", "maps"),)
"""Options holding a list of paths, resolved as :data:`PATH_KEYS`."""


# --- value checks: each returns an error text (what the option accepts) or None ---------------------
def _finite(v):
    return None if math.isfinite(v) else "must be a finite number"


def _positive(v):
    return None if math.isfinite(v) and v > 0 else "must be a positive, finite number"


def _non_negative(v):
    return None if math.isfinite(v) and v >= 0 else "must be a finite number >= 0"


def _int_at_least(low):
    return lambda v: None if v >= low else f"must be an integer >= {low}"


def _scan_check(key):
    # ScanSettings' own rule, so that TOML and Python accept the same values; 0 spells "automatic"
    return lambda v: field_error(key, None if key in ("r_p_min", "r_p_max") and v == 0 else v)


def _distance(v):
    return None if math.isfinite(v) and MIN_DISTANCE_PC <= v <= MAX_DISTANCE_PC else \
        f"must be a distance in pc between {MIN_DISTANCE_PC:g} and {MAX_DISTANCE_PC:g} " \
        f"(e.g. {DEFAULT_DISTANCE_PC:g} for Taurus)"


def _inclination(v):
    return None if math.isfinite(v) and 0 <= v < 90 else "must be an inclination in degrees in [0, 90)"


def _choice(*allowed, case=True):
    def check(v):
        value = v if case else v.upper()
        return None if value in allowed else f"must be one of {', '.join(repr(a) for a in allowed)}"
    return check


def _each(check):
    def each(values):
        for v in values:
            if isinstance(v, bool) or not isinstance(v, (int, float, str)):
                return f"must be a list of values, got element {v!r}"
            error = check(v)
            if error:
                return f"has element {v!r} that {error}"
        return None
    return each


def _number(check):
    def number(v):
        if isinstance(v, (str, bool)):
            return "must be a list of numbers"
        return check(v)
    return number


def _string(check):
    def string(v):
        return check(v) if isinstance(v, str) else "must be a list of strings"
    return string


_UV_UNITS = ("", "lambda", "klambda", "m", "λ", "kλ", "wavelengths", "wle", "kilolambda", "metre", "metres",
             "meter", "meters")

CHECKS: dict[str, dict[str, Callable[[Any], str | None]]] = {
    "data": {"uv_units": _choice(*_UV_UNITS), "wavelength": _non_negative, "average": _choice(*AVERAGING_MODES),
             "max_smearing": lambda v: None if math.isfinite(v) and 0 < v <= 0.1 else "must lie in (0, 0.1]",
             "time_bin": _non_negative},
    "geometry": {"inc": _inclination, "PA": _finite, "dRA": _finite, "dDec": _finite, "distance": _distance},
    "templates": {"mass": _each(_number(_positive)), "tau0": _each(_number(_positive)),
                  "beta": _each(_number(_non_negative)), "hand": _each(_string(_choice("R", "L", case=False))),
                  "h_p": _each(_number(_positive)), "slope": _each(_number(_non_negative)),
                  "alpha": _each(_number(_positive)), "orbits": _each(_number(_positive)),
                  "maps": _each(_string(lambda v: None if v.strip() else "must name a file"))},
    "grid": {key: _scan_check(key) for key in GRID_FIELDS},
    "scan": {key: _scan_check(key) for key in ScanSettings.field_names() if key not in GRID_FIELDS},
    "compare": {"residuals": _choice("visibilities", "difference"),
                "weighting": _choice("natural", "briggs", "uniform"),
                "robust": _finite, "deconvolver": _choice("hogbom", "multiscale"), "niter": _int_at_least(0),
                "threshold_sigma": _positive, "imsize": _int_at_least(0), "cell": _non_negative,
                "r_out": _non_negative},
    "output": {"dir": lambda v: None if v.strip() else "must name a directory"},
}
"""section -> option -> check of its (already type-coerced) value, for the sections without a settings
dataclass (:data:`SECTION_SETTINGS` sections are checked by their dataclass); options without one take any
value of their type. Sections added to :data:`.SCHEMA` may add their checks here."""


def _check_values(config: dict) -> None:
    for section, checks in CHECKS.items():
        for key, check in checks.items():
            if key in config.get(section, {}):
                value = config[section][key]
                if key in SCHEMA.get(section, {}) and value == SCHEMA[section][key][0]:
                    continue  # defaults are valid by construction (and may be sentinels such as 0)
                error = check(value)
                if error:
                    raise ConfigError(f"{section}.{key} = {value!r} {error}")
    templates = config.get("templates", {})
    if "bank" in templates:
        learned = templates["bank"] == "learned"
        stray = [k for k in LEARNED_OPTIONS if templates.get(k) and templates[k] != SCHEMA["templates"][k][0]]
        if stray and not learned:
            raise ConfigError(f"templates.{stray[0]} = {templates[stray[0]]!r} is read only with bank = 'learned' "
                              f"(bank = {templates['bank']!r}): set [templates] bank = \"learned\" or remove it")
        if learned and not templates.get("learned_model"):
            raise ConfigError("templates.bank = 'learned' needs [templates] learned_model = \"model.h5\", a saved "
                              "LearnedTemplateModel (fit one with: spiralbayes templates --fit-learned model.h5)")
    grid = config.get("grid", {})
    if grid.get("r_p_min") and grid.get("r_p_max") and grid["r_p_min"] >= grid["r_p_max"]:
        raise ConfigError(f"grid.r_p_min = {grid['r_p_min']!r} must be smaller than grid.r_p_max = "
                          f"{grid['r_p_max']!r} [arcsec] (or 0: automatic)")


def _check_settings(config: dict) -> None:
    """Build each section's settings dataclass, so that its own checks run; its error names ``section.key``."""
    for section, cls in SECTION_SETTINGS.items():
        if section not in config:
            continue
        try:
            from_config(cls, config[section])
        except (ValueError, TypeError) as exc:
            raise ConfigError(_settings_message(section, cls, str(exc))) from None


def _settings_message(section: str, cls, message: str) -> str:
    # the dataclasses' messages start with "<field> = <value>", which becomes "<section>.<field> = <value>"
    match = re.match(r"(\w+) ", message)
    if match and match.group(1) in {f.name for f in fields(cls)}:
        return f"{section}.{message}"
    return f"[{section}] {message}"


def default_config() -> dict:
    """The default configuration as a nested dict."""
    return {section: {k: copy.deepcopy(v[0]) for k, v in keys.items()} for section, keys in SCHEMA.items()}


def merge_config(user: dict, schema: dict = SCHEMA) -> dict:
    """Defaults overlaid with ``user``; unknown sections/keys, wrong types and bad values raise ConfigError."""
    config = default_config() if schema is SCHEMA else {s: {k: copy.deepcopy(v[0]) for k, v in ks.items()}
                                                         for s, ks in schema.items()}
    for section, values in user.items():
        if section not in schema:
            raise ConfigError(f"unknown config section [{section}]; valid sections: {sorted(schema)}")
        if isinstance(values, dict):
            values = {_current_name(section, key, values): value for key, value in values.items()}
        config[section].update(merge_section(section, values, schema[section], defaults=False))
    _check_values(config)
    _check_settings(config)
    return config


RENAMED = {("scan", "dask"): "scheduler"}
"""(section, old option name) -> new name: old names are still read, as the new one, with a FutureWarning."""


def _current_name(section: str, key: str, values: dict) -> str:
    new = RENAMED.get((section, key))
    if new is None:
        return key
    if new in values:
        raise ConfigError(f"{section}.{key} is the old name of {section}.{new}: give {new} only")
    warnings.warn(f"{section}.{key} is renamed {section}.{new}: write '{new} = ...' (the old name will be removed)",
                  FutureWarning, stacklevel=4)
    return new


def merge_section(section: str, values, options: dict, *, defaults: bool = True) -> dict:
    """One section's ``values`` type-checked against ``options`` (option -> ``(default, description)``).

    Unknown options and values of the wrong type raise ConfigError naming ``section.option``; integers
    given for float options become floats, a single value for a list option a one-element list.
    With ``defaults`` the options not in ``values`` are filled with their defaults.
    """
    if not isinstance(values, dict):
        raise ConfigError(f"[{section}] must be a table of options")
    out = {k: copy.deepcopy(v[0]) for k, v in options.items()} if defaults else {}
    for key, value in values.items():
        if key not in options:
            raise ConfigError(f"unknown option {section}.{key}; valid options of [{section}]: {sorted(options)}")
        out[key] = _coerce(section, key, value, options[key][0])
    return out


def _coerce(section: str, key: str, value, default):
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise ConfigError(f"{section}.{key} must be true or false, got {value!r}")
        return value
    if isinstance(default, (int, float)) and not isinstance(default, bool):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{section}.{key} must be a number, got {value!r}")
        if isinstance(default, float):
            return float(value)
        if isinstance(value, float) and not (math.isfinite(value) and value.is_integer()):
            raise ConfigError(f"{section}.{key} must be an integer, got {value!r}")
        return int(value)
    if isinstance(default, list) and not isinstance(value, list):
        return [value]
    if isinstance(default, str) and not isinstance(value, str):
        raise ConfigError(f"{section}.{key} must be a string, got {value!r}")
    return value


def load_config(path, schema: dict = SCHEMA) -> LoadedConfig:
    """Read a TOML configuration file, merge it with the defaults and check every value.

    Relative paths (:data:`PATH_KEYS`) are taken relative to the configuration file.

    Raises
    ------
    MissingFileError
        No file at ``path``.
    ConfigError
        Not valid TOML, an unknown section or option, or a bad value (the message names it).
    """
    path = Path(path)
    user = read_toml(path)
    try:
        config = merge_config(user, schema)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None
    config = LoadedConfig(config)
    config.given = {section: sorted(values) for section, values in user.items() if isinstance(values, dict)}
    config.source = str(path)
    return resolve_paths(config, path.parent)


def read_toml(path, *, what: str = "configuration file", hint: str = "write one with --print-config") -> dict:
    """The parsed TOML of the file at ``path``.

    Raises
    ------
    MissingFileError
        No file at ``path`` (the message names the ``what`` and the ``hint``).
    ConfigError
        Not valid TOML, or not a text file.
    """
    path = Path(path)
    if not path.exists():
        raise MissingFileError(f"{what} {path} not found ({hint})")
    try:
        return tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path} is not valid TOML: {exc}") from None
    except UnicodeDecodeError:
        raise ConfigError(f"{path} is not a text (TOML) file") from None
    except IsADirectoryError:
        raise ConfigError(f"{path} is a folder, not a {what}") from None


_ConfigT = TypeVar("_ConfigT", bound=dict)


def resolve_paths(config: _ConfigT, root) -> _ConfigT:
    """``config`` with its relative path options (:data:`PATH_KEYS`) taken relative to ``root`` (``~`` expanded)."""
    for section, key in PATH_KEYS:
        value = config.get(section, {}).get(key)
        if not value or (section, key) == ("templates", "bank") and value in BUILT_IN_BANKS:
            continue
        config[section][key] = _resolve(value, root)
    for section, key in PATH_LIST_KEYS:
        values = config.get(section, {}).get(key)
        if values:
            config[section][key] = [_resolve(v, root) for v in values]
    return config


def _resolve(value: str, root) -> str:
    resolved = Path(value).expanduser()
    return str(resolved if resolved.is_absolute() else (Path(root) / resolved).resolve())


class LoadedConfig(dict):
    """A merged configuration read from a file: a plain dict that also knows the file (``source``) and
    which options the file stated (``given``: section -> option names), so that a missing
    ``[geometry]`` can be refused rather than replaced by the defaults silently."""

    given: dict | None = None
    source: str = ""


def geometry_given(config: dict) -> bool:
    """Whether the configuration file stated the disc geometry (``[geometry] inc`` or ``PA``).

    Configurations built in code (no record of what the file held) count as stated.
    """
    given = getattr(config, "given", None)
    return given is None or bool({"inc", "PA"} & set(given.get("geometry", ())))


def describe_config(config: dict | None = None, schema: dict = SCHEMA) -> str:
    """TOML text of ``config`` (default: the defaults) with each option's description."""
    config = default_config() if config is None else config
    lines = ["# spiralbayes configuration (TOML); every option is shown with its default", ""]
    for section, keys in schema.items():
        lines.append(f"[{section}]")
        for key, (_, description) in keys.items():
            lines.append(f"# {description}")
            lines.append(f"{key} = {_toml_value(config[section][key])}")
        lines.append("")
    return "\n".join(lines)


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return repr(value)
