"""One configuration schema for every command (``scan``, ``sample``) and for notebooks (TOML files).

Every option has a default (from Stevenson et al. 2024 where the paper sets one) and a
description with units; unknown sections or keys are rejected with the list of valid ones, and
the configuration actually used is saved beside every output. ``spiralbayes scan
--print-config`` (or ``sample --print-config``) writes the documented default file. The same file
drives both commands: ``scan`` reads ``[data]`` to ``[scan]``, ``sample`` adds ``[sample]`` and
``[priors]`` and reuses the scan's outputs when they are in ``[output] dir``. Relative input
paths are taken relative to the configuration file.
"""

from __future__ import annotations

import copy
from pathlib import Path

import tomllib

from .exceptions import InputError, MissingFileError

__all__ = ["PATH_KEYS", "SCHEMA", "default_config", "describe_config", "load_config", "merge_config"]

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
        "model": ("", "a saved AxisymmetricModel (.h5) to use instead of fitting frank (empty: fit)"),
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
    "sample": {
        "run_name": ("posterior", "chains go to OUTPUT/chains/<run_name>.h5"),
        "scan": ("", "a saved ScanResult (.h5) to start walkers from and prune templates (empty: OUTPUT/scan.h5 if present)"),
        "n_walkers": (32, "emcee walkers per template (>= 12)"),
        "n_steps": (0, "total steps per walker (0: run until converged, up to max_steps)"),
        "max_steps": (20000, "cap on the steps per walker when running until converged"),
        "check_every": (500, "steps between convergence checks"),
        "convergence": ("warn", "'raise', 'warn' or 'ignore' when a chain is shorter than 50 autocorrelation times"),
        "min_ess": (400.0, "smallest effective sample size per parameter for convergence"),
        "processes": (1, "worker processes for the walkers"),
        "seed": (0, "random seed of the sampler"),
        "prune_delta_lnL": (25.0, "templates whose scan peak is this far below the best (in ln L) get a Laplace evidence only"),
        "evidence_draws": (2000, "draws of the importance-sampled evidence"),
        "mcmc_templates": ([], "names of the templates that get a chain (empty: chosen by prune_delta_lnL)"),
        "flush_every": (100, "steps between atomic writes of the chain file (a kill loses at most these)"),
        "planet_prior": (0.5, "prior probability that the disc hosts a planet (against the no-planet hypothesis)"),
    },
    "priors": {
        "r_p_min": (0.0, "smallest planet radius [arcsec] (0: R_eff / 25 of the frank profile)"),
        "r_p_max": (0.0, "largest planet radius [arcsec] (0: R_eff, at most Rmax / 2.2)"),
        "inc_sigma": (5.0, "width of the Gaussian prior on the inclination [deg], centred on [geometry]"),
        "PA_sigma": (5.0, "width of the Gaussian prior on the position angle [deg]"),
        "dRA_sigma": (0.05, "width of the Gaussian prior on the RA offset [arcsec]"),
        "dDec_sigma": (0.05, "width of the Gaussian prior on the Dec offset [arcsec]"),
        "amplitude_max": (2.0, "spiral amplitude A uniform on [0, amplitude_max] (A = 1: the template as simulated; 0: fix A = 1)"),
    },
    "output": {
        "dir": ("spiralbayes-output", "directory for results and plots"),
        "plots": (True, "write heatmap PNGs"),
    },
}


PATH_KEYS = (("data", "path"), ("frank", "model"), ("templates", "bank"), ("sample", "scan"))
"""Input paths; relative ones are resolved against the configuration file's folder (``[output] dir``, an
output, is relative to the working directory)."""


def default_config() -> dict:
    """The default configuration as a nested dict."""
    return {section: {k: copy.deepcopy(v[0]) for k, v in keys.items()} for section, keys in SCHEMA.items()}


def merge_config(user: dict, schema: dict = SCHEMA) -> dict:
    """Defaults overlaid with ``user``; unknown sections/keys and wrong types raise ValueError."""
    config = default_config() if schema is SCHEMA else {s: {k: v[0] for k, v in ks.items()} for s, ks in schema.items()}
    for section, values in user.items():
        if section not in schema:
            raise InputError(f"unknown config section [{section}]; valid sections: {sorted(schema)}")
        if not isinstance(values, dict):
            raise InputError(f"[{section}] must be a table of options")
        for key, value in values.items():
            if key not in schema[section]:
                raise InputError(f"unknown option {section}.{key}; valid options of [{section}]: {sorted(schema[section])}")
            config[section][key] = _coerce(section, key, value, schema[section][key][0])
    return config


def _coerce(section: str, key: str, value, default):
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise InputError(f"{section}.{key} must be true or false, got {value!r}")
        return value
    if isinstance(default, (int, float)) and not isinstance(default, bool):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InputError(f"{section}.{key} must be a number, got {value!r}")
        return type(default)(value) if isinstance(default, float) else value
    if isinstance(default, list) and not isinstance(value, list):
        return [value]
    if isinstance(default, str) and not isinstance(value, str):
        raise InputError(f"{section}.{key} must be a string, got {value!r}")
    return value


def load_config(path, schema: dict = SCHEMA) -> dict:
    """Read a TOML configuration file and merge it with the defaults.

    Relative data paths are taken relative to the configuration file.
    """
    path = Path(path)
    if not path.exists():
        raise MissingFileError(f"configuration file {path} not found (write one with --print-config)")
    try:
        user = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path} is not valid TOML: {exc}") from None
    config = merge_config(user, schema)
    for section, key in PATH_KEYS:
        value = config.get(section, {}).get(key)
        if value and value != "default" and not Path(value).expanduser().is_absolute():
            config[section][key] = str((path.parent / value).resolve())
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
