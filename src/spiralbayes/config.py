"""One configuration schema for the command line and notebooks (TOML files).

Every option has a default (from Stevenson et al. 2024 where the paper sets one) and a
description with units; unknown sections or keys are rejected with the list of valid ones, and
the configuration actually used is saved beside every output. ``spiralbayes scan
--print-config`` writes the documented default file.
"""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path

__all__ = ["SCHEMA", "default_config", "describe_config", "load_config", "merge_config"]

# section -> key -> (default, description)
SCHEMA: dict[str, dict[str, tuple[object, str]]] = {
    "data": {
        "path": ("", "visibility file: uvtable .txt/.npz, spiralbayes .h5, or a Measurement Set directory"),
        "uv_units": ("", "units of u, v in a uvtable: 'lambda' or 'm' (empty: from the file header, else lambda)"),
        "wavelength": (0.0, "observing wavelength [m] for u, v in metres (0: from the file)"),
        "conjugated": (False, "true if V is the complex conjugate of the CASA/frank convention (visread exports)"),
        "estimate_weights": (False, "rescale the weights from the scatter of the visibilities (CASA weights are often not statistical)"),
    },
    "geometry": {
        "inc": (0.0, "inclination [deg]"),
        "PA": (0.0, "position angle of the major axis, east of north [deg]"),
        "dRA": (0.0, "disc centre offset to the east [arcsec]"),
        "dDec": (0.0, "disc centre offset to the north [arcsec]"),
        "fit": (False, "fit the geometry with frank's nonparametric fitter (started from its Gaussian fit and the values above)"),
        "distance": (140.0, "distance [pc], for au axes and planet masses"),
    },
    "frank": {
        "N": (200, "number of radial collocation points"),
        "Rmax": (1.2, "outer radius of the fit [arcsec]"),
        "alpha": (1.05, "order parameter of the power-spectrum prior"),
        "p0": (1e-15, "scale parameter of the power-spectrum prior [Jy^2]"),
        "weights_smooth": (0.1, "strength of the power-spectrum smoothing"),
        "nonnegative": (False, "use frank's non-negative profile"),
    },
    "templates": {
        "bank": ("default", "'default' (the built-in 64-template wake bank, cached) or the path of a TemplateBank HDF5 file"),
        "mass": ([], "planet masses M_p/M_th to keep (empty: all)"),
        "tau0": ([], "initial optical depths at r_p to keep (empty: all)"),
        "beta": ([], "cooling times t_c Omega to keep (empty: all)"),
        "hand": ([], "'R' and/or 'L' (empty: both)"),
    },
    "grid": {
        "r_p_min": (0.02, "smallest planet radius [arcsec] (paper: 0.02)"),
        "r_p_max": (0.5, "largest planet radius [arcsec] (paper: 0.5)"),
        "n_r_p": (25, "number of planet radii (paper: 25)"),
        "n_phi_p": (90, "number of planet azimuths over 360 deg (paper: 90, i.e. 4 deg)"),
    },
    "scan": {
        "amplitude": ("fixed", "'fixed' (the paper's A = 1) or 'free' (best linear spiral amplitude per instance, +1 BIC parameter)"),
        "dask": ("", "empty: serial; 'local': a Dask LocalCluster; else a scheduler address (tcp://host:8786)"),
        "nthreads": (1, "threads per template for the NUFFTs"),
        "cell_factor": (20.0, "quadrature cells are at most 1/(cell_factor u_max) across"),
        "checkpoint": (True, "checkpoint after each template and resume an interrupted scan"),
    },
    "output": {
        "dir": ("spiralbayes-output", "directory for results and plots"),
        "plots": (True, "write heatmap PNGs"),
    },
}


def default_config() -> dict:
    """The default configuration as a nested dict."""
    return {section: {k: copy.deepcopy(v[0]) for k, v in keys.items()} for section, keys in SCHEMA.items()}


def merge_config(user: dict, schema: dict = SCHEMA) -> dict:
    """Defaults overlaid with ``user``; unknown sections/keys and wrong types raise ValueError."""
    config = default_config() if schema is SCHEMA else {s: {k: v[0] for k, v in ks.items()} for s, ks in schema.items()}
    for section, values in user.items():
        if section not in schema:
            raise ValueError(f"unknown config section [{section}]; valid sections: {sorted(schema)}")
        if not isinstance(values, dict):
            raise ValueError(f"[{section}] must be a table of options")
        for key, value in values.items():
            if key not in schema[section]:
                raise ValueError(f"unknown option {section}.{key}; valid options of [{section}]: {sorted(schema[section])}")
            config[section][key] = _coerce(section, key, value, schema[section][key][0])
    return config


def _coerce(section: str, key: str, value, default):
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise ValueError(f"{section}.{key} must be true or false, got {value!r}")
        return value
    if isinstance(default, (int, float)) and not isinstance(default, bool):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"{section}.{key} must be a number, got {value!r}")
        return type(default)(value) if isinstance(default, float) else value
    if isinstance(default, list) and not isinstance(value, list):
        return [value]
    if isinstance(default, str) and not isinstance(value, str):
        raise ValueError(f"{section}.{key} must be a string, got {value!r}")
    return value


def load_config(path, schema: dict = SCHEMA) -> dict:
    """Read a TOML configuration file and merge it with the defaults.

    Relative data paths are taken relative to the configuration file.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"configuration file {path} not found (write one with --print-config)")
    try:
        user = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{path} is not valid TOML: {exc}") from None
    config = merge_config(user, schema)
    data_path = config.get("data", {}).get("path")
    if data_path and not Path(data_path).is_absolute():
        config["data"]["path"] = str((path.parent / data_path).resolve())
    return config


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
