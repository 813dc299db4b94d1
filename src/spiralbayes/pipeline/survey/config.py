"""The survey file (TOML): shared settings, the ``[survey]`` and ``[bank]`` sections and one ``[[disc]]`` per disc.

A survey file holds

* ``[survey]`` (:data:`SURVEY_SCHEMA`): the output folder, the Dask engine, the posterior policy;
* optionally ``[bank]``: a template bank the survey builds once (both hands of every mass, tau0,
  beta and h_p listed, at ``wavelength``) into ``OUTPUT/bank.h5`` and uses for every disc;
* any section of the single-disc schema (:data:`spiralbayes.config.SCHEMA`), shared by all discs;
* optionally ``[cluster]``: dask-jobqueue options when ``scheduler = "slurm"`` or ``"pbs"``
  (``jobs``, ``cores``, ``memory``, ``walltime``, ``queue``, ``account``, ...);
* ``[[disc]]`` tables: ``name``, ``path`` (uvtable, .npz, .h5 or Measurement Set), ``distance``
  [pc], ``inc``, ``PA`` [deg], ``dRA``, ``dDec`` [arcsec], ``fit_geometry`` (fit the geometry
  with frank), optionally ``simulate`` (write a synthetic observation at ``path`` when it is
  missing: ``preset``, ``flux`` [Jy, observed], ``r_eff`` [arcsec, 95 % flux radius], ``seed``),
  and per-disc overrides of any schema section (``[disc.limits]``, ``[disc.frank]``, ...).

Each disc becomes one merged single-disc configuration (checked exactly like a ``scan`` config,
by :func:`spiralbayes.config.merge_config`) whose ``[output] dir`` is ``OUTPUT/discs/<name>``, so
every disc's folder is what ``spiralbayes scan`` and ``limits`` would have written for it. A disc's
name needs a letter or digit (``"."`` or ``".."`` would name the output folder itself) and its
distance, as every configuration's, must lie between
:data:`~spiralbayes.settings.MIN_DISTANCE_PC` and :data:`~spiralbayes.settings.MAX_DISTANCE_PC`. The file is read,
its values coerced and its paths resolved (relative to the survey file) by the single-disc loader's
functions
(:func:`~spiralbayes.config.read_toml`, :func:`~spiralbayes.config.merge_section`,
:func:`~spiralbayes.config.resolve_paths`).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from pathlib import Path

from ..._provenance import content_hash
from ...cluster import check_scheduler
from ...config import SCHEMA, merge_config, merge_section, read_toml, resolve_paths
from ...exceptions import ConfigError, InputError
from ...templates.variants import DEFAULT_VARIANTS, VARIANTS

__all__ = ["BANK_SCHEMA", "DISC_KEYS", "SURVEY_SCHEMA", "DiscJob", "SurveySpec", "load_survey",
           "parse_survey", "slugify"]

SURVEY_SCHEMA: dict[str, tuple[object, str]] = {
    "name": ("survey", "name of the survey (table captions, provenance)"),
    "output": ("spiralbayes-survey", "output folder: the survey table, figures, provenance and discs/<name>/"),
    "scheduler": ("", "'local' (also empty): a dask.distributed LocalCluster sized to the machine; 'serial': no "
                      "Dask, in this process; 'slurm' or 'pbs': a dask-jobqueue cluster from [cluster]; else the "
                      "address of a running scheduler (tcp://host:8786)"),
    "n_workers": (0, "LocalCluster worker processes, one thread each (0: one per core)"),
    "connect_timeout": (10.0, "seconds to wait for a scheduler at the given address before giving up"),
    "posterior": ("candidates", "'candidates': the posterior for discs with a detection or a candidate; "
                                "'none'; 'all'"),
    "posterior_steps": (2000, "emcee steps per walker of the survey's posteriors (0: until converged)"),
    "chunk_templates": (2, "templates per scan task (the scan of one disc is split into such chunks)"),
    "retries": (1, "times a failed task is retried before its disc is reported as failed"),
    "figures": (True, "write the figure set (mass-radius grid, heatmap pairs of candidates)"),
}
"""``[survey]`` option -> (default, description)."""

BANK_SCHEMA: dict[str, tuple[object, str]] = {
    "mass": ([0.3, 1.0, 3.0], "planet masses M_p/M_th"),
    "tau0": ([0.3], "optical depths at r_p"),
    "beta": ([10.0], "cooling times t_c Omega"),
    "h_p": ([0.07], "aspect ratios H/r at r_p"),
    "wavelength": (1.33e-3, "observing wavelength of the templates [m]"),
    "morphologies": (list(DEFAULT_VARIANTS), "spiral morphologies (template variants) of every template: the "
                     "default set makes the limits robust to the spiral's shape; ['compromise'] alone is the "
                     "single-morphology bank of the paper's comparison"),
}
"""``[bank]`` option -> (default, description): a bank built by the survey (both hands)."""

DISC_KEYS = ("name", "path", "distance", "inc", "PA", "dRA", "dDec", "fit_geometry", "simulate")
SIMULATE_KEYS = {"preset": "taurus", "flux": 0.1, "r_eff": 0.4, "seed": 0}

_SURVEY_CHECKS = {
    "n_workers": lambda v: None if v >= 0 else "must be 0 (one per core) or a positive integer",
    "connect_timeout": lambda v: None if math.isfinite(v) and v > 0 else "must be a positive number of seconds",
    "posterior": lambda v: None if v in ("candidates", "none", "all") else "must be 'candidates', 'none' or 'all'",
    "posterior_steps": lambda v: None if v >= 0 else "must be an integer >= 0",
    "chunk_templates": lambda v: None if v >= 1 else "must be an integer >= 1",
    "retries": lambda v: None if v >= 0 else "must be an integer >= 0",
}


@dataclass
class DiscJob:
    """One disc of a survey: its merged single-disc configuration and how to make its data."""

    name: str
    slug: str
    config: dict
    simulate: dict | None = None
    bank_key: str = ""  # hash of the survey's [bank] (its templates are not in the config, only its path)

    @property
    def out_dir(self) -> Path:
        return Path(self.config["output"]["dir"])

    def key(self, *sections: str, extra=None, bank: bool = True) -> str:
        """Hash of the named configuration sections (and ``extra``, and the survey's bank): a stage's resume key."""
        return content_hash({s: self.config[s] for s in sections}, extra, self.bank_key if bank else "")


@dataclass
class SurveySpec:
    """A parsed survey file: ``[survey]`` settings, the optional bank, the discs."""

    settings: dict
    discs: list
    bank: dict | None = None
    source: str = ""
    text_hash: str = ""
    shared: dict = field(default_factory=dict)
    cluster: dict = field(default_factory=dict)

    @property
    def out_dir(self) -> Path:
        return Path(self.settings["output"])


def slugify(name: str) -> str:
    """A folder name for a disc: letters, digits, '.', '-' kept, the rest '_'.

    Raises ConfigError for a name with no letter or digit (``"."``, ``".."``, ``"_"``): its folder
    would be the survey's output or ``discs/`` itself, or escape it.
    """
    slug = "".join(c if c.isalnum() or c in ".-" else "_" for c in name).strip("_")
    if not any(c.isalnum() for c in slug):
        raise ConfigError(f"disc.name = {name!r} has no letter or digit, so it names no folder of its own under "
                          "discs/: give the disc a name such as \"DS Tau\"")
    return slug


def _deep_merge(base: dict, over: dict) -> dict:
    out = copy.deepcopy(base)
    for section, values in over.items():
        out.setdefault(section, {}).update(copy.deepcopy(values))
    return out


def _disc_job(entry: dict, shared: dict, out_dir: Path, root: Path, index: int) -> DiscJob:
    if not isinstance(entry, dict):
        raise ConfigError(f"disc {index + 1} must be a table ([[disc]])")
    name = entry.get("name")
    if not isinstance(name, str) or not name.strip():
        raise ConfigError(f"disc {index + 1} needs a name (disc.name = \"BP Tau\")")
    label = f"disc {name!r}"
    unknown = [k for k in entry if k not in DISC_KEYS and k not in SCHEMA]
    if unknown:
        raise ConfigError(f"{label}: unknown key(s) {unknown}; valid keys: {list(DISC_KEYS)} and the sections "
                          f"{sorted(SCHEMA)}")
    if not isinstance(entry.get("path", ""), str) or not entry.get("path"):
        raise ConfigError(f"{label} needs path = the visibility file (uvtable, .npz, .h5 or a Measurement Set)")
    overrides = {s: v for s, v in entry.items() if s in SCHEMA}
    disc = {"data": {"path": entry["path"]}, "geometry": {}, "output": {"dir": ""}, "limits": {}}
    for key in ("distance", "inc", "PA", "dRA", "dDec"):
        if key in entry:
            disc["geometry"][key] = entry[key]
    if "fit_geometry" in entry:
        disc["geometry"]["fit"] = entry["fit_geometry"]
    user = _deep_merge(_deep_merge(shared, overrides), disc)
    slug = slugify(name)
    user["output"]["dir"] = str(out_dir / "discs" / slug)
    if Path(user["output"]["dir"]).resolve().parent != (out_dir / "discs").resolve():
        raise ConfigError(f"disc.name = {name!r} names a folder outside discs/: give the disc a plain name")
    if not user["limits"].get("name"):
        user["limits"]["name"] = name
    try:
        config = merge_config(user)
    except ConfigError as exc:
        raise ConfigError(f"{label}: {exc}") from None
    simulate = entry.get("simulate")
    if simulate is not None:
        simulate = merge_section(f"{label}.simulate", simulate, {k: (v, "") for k, v in SIMULATE_KEYS.items()})
    return DiscJob(name, slug, resolve_paths(config, root), simulate)


def parse_survey(user: dict, root: Path = Path("."), *, source: str = "") -> SurveySpec:
    """A :class:`SurveySpec` from the survey file's parsed TOML ``user`` (paths relative to ``root``)."""
    user = dict(user)
    settings = merge_section("survey", user.pop("survey", {}), SURVEY_SCHEMA)
    for key, check in _SURVEY_CHECKS.items():
        error = check(settings[key])
        if error:
            raise ConfigError(f"survey.{key} = {settings[key]!r} {error}")
    try:
        check_scheduler(settings["scheduler"], "survey.scheduler")
    except InputError as exc:
        raise ConfigError(str(exc)) from None
    bank = merge_section("bank", user.pop("bank"), BANK_SCHEMA) if "bank" in user else None
    if bank is not None:
        unknown_variants = [v for v in bank.get("morphologies", []) if v not in VARIANTS]
        if unknown_variants or not bank["morphologies"]:
            raise ConfigError(f"bank.morphologies = {bank['morphologies']!r}: give one or more of {sorted(VARIANTS)} "
                              f"(default {list(DEFAULT_VARIANTS)})")
    cluster = user.pop("cluster", {})
    if not isinstance(cluster, dict):
        raise ConfigError("[cluster] must be a table of dask-jobqueue options (cores, memory, walltime, jobs, ...)")
    discs = user.pop("disc", [])
    if isinstance(discs, dict):
        discs = [discs]
    unknown = [s for s in user if s not in SCHEMA]
    if unknown:
        raise ConfigError(f"unknown section(s) {unknown} in the survey file; valid: [survey], [bank], [[disc]] and "
                          f"the single-disc sections {sorted(SCHEMA)}")
    if not discs:
        raise ConfigError("the survey lists no disc: add [[disc]] tables (name, path, distance, inc, PA)")
    out = Path(settings["output"]).expanduser()
    settings["output"] = str(out if out.is_absolute() else (root / out).resolve())
    shared = {s: dict(v) for s, v in user.items()}
    if bank is not None:
        shared.setdefault("templates", {})["bank"] = str(Path(settings["output"]) / "bank.h5")
    jobs = [_disc_job(entry, shared, Path(settings["output"]), root, i) for i, entry in enumerate(discs)]
    if bank is not None:
        for job in jobs:
            job.bank_key = content_hash(bank)
    seen: dict[str, str] = {}  # folder name -> disc name
    for job in jobs:
        if job.slug in seen:
            raise ConfigError(f"discs {seen[job.slug]!r} and {job.name!r} share the folder name {job.slug!r}: "
                              "give them distinct names")
        seen[job.slug] = job.name
    return SurveySpec(settings, jobs, bank, source, content_hash(user, settings, bank), shared, cluster)


def load_survey(path, **overrides) -> SurveySpec:
    """Read a survey file (relative paths from its folder); ``overrides`` replace ``[survey]`` options.

    Raises
    ------
    MissingFileError
        No file at ``path``.
    ConfigError
        Invalid TOML or not a text file, an unknown section, option or disc key, or a bad value (named).
    """
    path = Path(path)
    user = read_toml(path, what="survey file", hint="see examples/taurus_survey.toml")
    survey = dict(user.get("survey", {}))
    survey.update({k: v for k, v in overrides.items() if v is not None})
    user["survey"] = survey
    try:
        return parse_survey(user, path.parent.resolve(), source=str(path.resolve()))
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None
